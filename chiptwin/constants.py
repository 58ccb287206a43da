"""Physical constants (CODATA 2018 exact values) and the chip's time unit.

Simulation time in the chip model is an integer count of nanosecond ticks (:data:`TICKS_PER_S`);
convert only at the edges with :func:`s_to_ticks` and :func:`ticks_to_s`.
"""

from __future__ import annotations

Q_E: float = 1.602176634e-19
"""Elementary charge. Unit: C (exact, SI 2019)."""

K_B: float = 1.380649e-23
"""Boltzmann constant. Unit: J/K (exact, SI 2019)."""

N_A: float = 6.02214076e23
"""Avogadro constant. Unit: 1/mol (exact, SI 2019)."""

H_PLANCK: float = 6.62607015e-34
"""Planck constant. Unit: J·s (exact, SI 2019)."""

C_LIGHT: float = 299_792_458.0
"""Speed of light in vacuum. Unit: m/s (exact)."""

T_ROOM_K: float = 300.0
"""Room temperature at which the kTC noise figures are quoted (sources.md P5). Unit: K."""

ZERO_C_K: float = 273.15
"""0 °C in kelvin (the scenario's temperatures are in °C). Unit: K."""

TICKS_PER_S: int = 1_000_000_000
"""The chip model's clock: one tick is one nanosecond."""

TICK_S: float = 1.0 / TICKS_PER_S
"""One tick, the shortest time the chip model resolves. Unit: s."""

MAX_TIME_S: float = 1.0e7
"""The longest time a scenario may give (≈ 116 days). Unit: s.

Longer than any luminescence experiment: glow assays last minutes to hours, the longest are
bioluminescence reporter recordings of circadian rhythms over days to a few weeks. In ticks it is
1e16, far below the int64 range (9.2e18) the chip model's event times are stored in, and a float64
of that size is exact to 0.93 ns, so :func:`s_to_ticks` neither overflows nor is off by more than
one tick anywhere between :data:`TICK_S` and here.
"""


def s_to_ticks(t_s: float) -> int:
    """Seconds to integer nanosecond ticks, rounded to the nearest tick.

    Scenario times are validated to lie in [:data:`TICK_S`, :data:`MAX_TIME_S`] (or be 0), so
    they give at least one tick and at most 1e16.
    """
    return int(round(t_s * TICKS_PER_S))


def ticks_to_s(ticks: int) -> float:
    """Integer nanosecond ticks to seconds."""
    return ticks / TICKS_PER_S
