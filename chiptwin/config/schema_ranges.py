"""The ranges several scenario fields share, each with its reason: physical, not numerical (what a
CMOS sensor, a well or an experiment can be), so a value outside is a typo or a unit slip, never
a design choice. Combinations that are each in range but too large to run are refused by
:mod:`chiptwin.config.budget`."""

from __future__ import annotations

from chiptwin.constants import MAX_TIME_S, TICK_S

T_MIN, T_MAX = TICK_S, MAX_TIME_S
TIMES = "one tick (1 ns) … 1e7 s (116 days, longer than any luminescence experiment)"
RATE_MIN, RATE_MAX = 1e-9, 1e9
RATES = "1e-9 … 1e9 1/s: a time constant from 30 years to one tick"
FMOL_MIN, FMOL_MAX = 1e-9, 1e6
AMOUNTS = ("per site; 1e-9 fmol (0.6 molecule) … 1 nmol (1 µL of 1 mM, a thousand times what "
           "a 1 nL well holds at 1 mM)")
AMOL_MIN, AMOL_MAX = FMOL_MIN * 1e3, FMOL_MAX * 1e3
LENGTH_MIN_UM, LENGTH_MAX_UM = 0.1, 1.0e4
LENGTHS = "0.1 µm (below the smallest image-sensor pixel, ≈ 0.5 µm) … 1 cm (a whole die)"
CLOCK_MIN_HZ, CLOCK_MAX_HZ = 1.0, 1.0e10
CLOCKS = ("1 Hz (far below any real block: a DSP that cannot keep up is modelled so) … 10 GHz, "
          "above any CMOS counter or DSP clock (0.18 µm: hundreds of MHz)")
VOLT_MAX = 100.0
VOLTS = "±100 V: beyond what any CMOS process, high-voltage ones included, withstands; 0.18 µm " \
        "runs at 1.8–3.3 V"
TEMP_MIN_C, TEMP_MAX_C = -273.15, 200.0
TEMPS = ("°C; absolute zero (cryo-CMOS runs at 4 K) … 200 °C, above the 150–175 °C junction "
         "limit of automotive-grade CMOS")
