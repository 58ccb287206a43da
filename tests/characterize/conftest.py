"""The three chips of the round trip, each characterised once per test session.

* ``reference``: the bundled ``pyro_1fmol`` chip with its converters made ideal (8 × 16 pixels,
  13-bit ADC per pixel over 1 V, 1 pF diode, 100 e⁻ read noise per sample = 0.13 LSB, CMS of
  M = 4): deep in the quantisation regime; the linear camera model the round trips check.
* ``as_built``: the same chip as configured, its converters as built (comparator noise, INL,
  mismatch: chiptwin.config.reference_chip): the bundled datasheet's chip.
* ``adc10``: a 64 × 64 chip with a 10-bit ADC and 2 DN read noise per sample (10 fF node,
  61 e⁻/DN), M = 1.
* ``ccd``: a cooled CCD-like chip, 64 × 64 pixels of 24 µm, −40 °C, 16-bit ADC, 10 e⁻ read noise,
  3e5 e⁻ full well, M = 1 (the cooled camera of the paper's CCD experiment, sources.md
  P15).
* ``dark``: the bundled ``snr10_requirement`` chip: 0.36 nA/cm² of dark current over 10 s
  exposures (a third of the well is dark charge), no PRNU or DSNU, M = 2.
"""

from __future__ import annotations

import copy

import pytest

from chiptwin.characterize import characterize
from chiptwin.config import load_scenario
from chiptwin.config.load import scenario_from_dict
from tests.conftest import IDEAL_ADC, SCENARIOS

#: A flux scene (light given at the sensor plane) on a chip to be characterised: the bench
#: replaces the light anyway, the sections only need to be a valid scenario.
FLUX = {
    "scenario": {"name": "chip", "seed": 12},
    "assay": {"kind": "flux", "photons_per_s_per_um2": 1.0, "start_s": 16.0},
    "sites": {"at_pixels": "centre"},
    "run": {"duration_s": 20.0},
}

CHIPS = {
    "adc10": {
        "rows": 64, "cols": 64, "pitch_um": 12.0,
        "pixel": {"diode_w_um": 10.0, "diode_h_um": 10.0, "qe": 0.6, "capacitance_fF": 10.0,
                  "read_noise_e": 122.0, "full_well_e": 40_000.0, "pedestal_V": 0.05,
                  "dark_current_nA_per_cm2": 1.0, "prnu_frac": 0.01, "dsnu_frac": 0.1},
        "adc": {"bits": 10, "v_min_V": 0.0, "v_max_V": 1.0},
        "memory": {"capacity_bits": 1 << 23},
        "dsp": {"cms_samples": 1, "n_dark_frames": 16, "average_frames": 4},
    },
    "ccd": {
        "rows": 64, "cols": 64, "pitch_um": 24.0,
        "pixel": {"diode_w_um": 24.0, "diode_h_um": 24.0, "qe": 0.5, "capacitance_fF": 50.0,
                  "read_noise_e": 10.0, "full_well_e": 3.0e5, "temperature_C": -40.0,
                  "dark_current_nA_per_cm2": 0.05, "prnu_frac": 0.01, "dsnu_frac": 0.1},
        "adc": {"bits": 16, "v_min_V": 0.0, "v_max_V": 1.0, "clock_hz": 100.0e6},
        "memory": {"capacity_bits": 1 << 23},
        "dsp": {"cms_samples": 1, "n_dark_frames": 16, "average_frames": 4},
    },
}


def chip_scenario(name: str, **adc):
    """The Scenario of one of the three chips; ``adc``: ``[chip.adc]`` keys set besides (a
    converter as built), with the chip's fixed pattern pinned (seed 5) for those."""
    bundled = {"reference": ("pyro_1fmol", IDEAL_ADC), "as_built": ("pyro_1fmol", []),
               "dark": ("snr10_requirement", [])}
    if name in bundled and not adc:
        file, sets = bundled[name]
        return load_scenario(SCENARIOS / f"{file}.toml", sets)
    raw = copy.deepcopy(FLUX)
    raw["scenario"]["name"] = name
    raw["chip"] = copy.deepcopy(CHIPS[name])
    if adc:
        raw["chip"]["adc"].update(adc)
        raw["chip"]["fixed_pattern_seed"] = 5
    return scenario_from_dict(raw, f"<{name}>")


@pytest.fixture(scope="session")
def characterized():
    """``characterized(name)``: the chip's Characterization (images kept), made once."""
    cache = {}

    def get(name: str):
        if name not in cache:
            cache[name] = characterize(chip_scenario(name), keep_images=True)
        return cache[name]

    return get
