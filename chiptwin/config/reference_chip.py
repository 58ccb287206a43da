"""The reference chip as built: one named set of the parameters its papers do not publish.

The JSSC 2006 chip (Eltoukhy, Salama, El Gamal, "A 0.18-µm CMOS bioluminescence detection
lab-on-chip", IEEE JSSC 41(3):651, 2006) publishes its array (8 × 16), its converter's 13 bits
and its techniques (low-dark-current diodes, CMS, background subtraction, faceplate), not its
comparator noise, ramp linearity, pixel capacitance, dark current, read noise, QE or faceplate
NA. The twin needs a value for each; :data:`AS_BUILT` states the one the headline scenes use,
why, and the range it could plausibly take on a chip like it. The sensitivity studies
(``scenarios/studies/sensitivity_*.toml``) move each across that range and report which one
decides the answer.

This module is data: the scenes state the values themselves (so a scenario file reads whole),
and the tests check that every scene built on the reference chip states exactly these.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

NAME = "jssc2006_as_built"
"""The set's name, as scenes, studies and summaries cite it."""


@dataclass(frozen=True)
class Assumption:
    """One unpublished parameter: the scenario key, the value used, its plausible range."""

    key: str
    value: float
    lo: float
    hi: float
    unit: str
    why: str
    range_why: str

    def __post_init__(self) -> None:
        if not self.lo <= self.value <= self.hi:
            raise ValueError(f"{self.key}: value {self.value} outside its range "
                             f"[{self.lo}, {self.hi}]")


LSB13_UV = 1.0e6 / 2**13
"""One LSB of the reference chip's 13-bit converter over its 1 V range. Unit: µV."""

AS_BUILT: tuple[Assumption, ...] = (
    Assumption(
        "chip.adc.comparator_noise_uV", round(0.5 * LSB13_UV, 2), 0.0, round(LSB13_UV, 2), "µV",
        "half an LSB of the 13-bit converter: a converter sold as 13 bits keeps its comparator "
        "below 1 LSB (else the 13th bit is noise), and a single-slope comparator integrating "
        "over a 410 µs ramp is slow enough to reach the middle of that",
        "0 (a noiseless comparator, the paper's ideal) … 1 LSB₁₃ (122 µV), where the 13th bit "
        "stops carrying information"),
    Assumption(
        "chip.adc.inl_max_lsb", 1.0, 0.0, 2.0, "LSB",
        "a 1-LSB quadratic bow of the shared ramp: the end-point INL of 12–14-bit single-slope "
        "column converters in image sensors is typically quoted within ±1–2 LSB",
        "0 (a perfectly linear ramp) … 2 LSB"),
    Assumption(
        "chip.adc.dnl_rms_lsb", 0.0, 0.0, 0.3, "LSB",
        "0: a single-slope converter with a continuous analog ramp and a counter has code "
        "widths of one clock period each; only clock jitter (ps against the 50 ns period at "
        "20 MHz: < 1e-4 LSB) makes them differ",
        "0 … 0.3 LSB rms, the DNL of a ramp made by a DAC (a digital ramp) instead"),
    Assumption(
        "chip.adc.offset_sigma_lsb", 2.0, 0.0, 8.0, "LSB",
        "2 LSB (0.24 mV) per converter: the residual offset of a comparator auto-zeroed before "
        "each ramp, as single-slope column comparators are; CMS subtracts what remains",
        "0 … 8 LSB (1 mV, a comparator without auto-zero's pair mismatch at its low end)"),
    Assumption(
        "chip.adc.gain_sigma", 0.001, 0.0, 0.01, "",
        "0.1 % per converter: converters sharing one ramp differ in gain only by their "
        "comparators' delay and the ramp's distribution along the array",
        "0 … 1 %"),
    Assumption(
        "chip.pixel.capacitance_fF", 1000.0, 300.0, 3000.0, "fF",
        "≈ 1 pF for a 100 × 100 µm n-well diode at ≈ 0.1 fF/µm² (area and sidewall)",
        "0.3 pF (a shallower, lightly doped well) … 3 pF (a deep diode with its routing)"),
    Assumption(
        "chip.pixel.dark_current_nA_per_cm2", 0.05, 0.01, 1.0, "nA/cm²",
        "tens of pA/cm²: the 'very-low-dark-current photodiodes' the chip's paper names, "
        "against 0.1–10 nA/cm² for a plain n-well diode at 25 °C",
        "0.01 … 1 nA/cm²: the best such diodes to a plain one's lower end"),
    Assumption(
        "chip.pixel.read_noise_e", 100.0, 30.0, 300.0, "e⁻",
        "100 e⁻ rms per sample: a 1 pF node's source follower and column amplifier "
        "(0.16 µV/e⁻: 16 µV rms)",
        "30 e⁻ (a quiet, low-noise differential readout) … 300 e⁻ (a plain follower)"),
    Assumption(
        "chip.pixel.qe", 0.4, 0.3, 0.6, "",
        "0.4 at 560 nm: a front-side diode without microlens in a 0.18 µm image-sensor process",
        "0.3 … 0.6, the range such diodes reach at 560 nm"),
)
"""The reference chip as built, one assumption per unpublished parameter."""

FACEPLATE_NA = Assumption(
    "optics.faceplate.na", 1.0, 0.5, 1.0, "",
    "NA 1.0 in air: the common high-NA imaging faceplates of the makers' datasheets",
    "0.5 … 1.0, the numerical apertures faceplate makers offer")
"""The faceplate's numerical aperture, for the scenes that put the assay on one."""


def by_key() -> dict[str, Assumption]:
    """The set keyed by scenario key, the faceplate's NA included."""
    return {a.key: a for a in (*AS_BUILT, FACEPLATE_NA)}




def stated(s) -> dict:
    """``summary['assumptions']``: the run's value of each unpublished parameter against
    :data:`AS_BUILT` (the faceplate's NA when the scene has one). The converter's values are the
    ones that made the codes: all 0 when ``run.fidelity.adc`` is ``"ideal"``; the comparator noise
    in µV whichever key set it.

    Returns ``{"set": NAME, "n": parameters compared, "as_reference": bool, "differ": {key:
    {"value", "reference"}}}``.
    """
    ideal_adc = s.run.fidelity.adc == "ideal"
    wanted = AS_BUILT + ((FACEPLATE_NA,) if s.optics.faceplate.present else ())
    differ = {}
    for a in wanted:
        if a.key == "chip.adc.comparator_noise_uV":
            adc = s.chip.adc
            value = adc.comparator_noise_total_lsb * (adc.v_max_V - adc.v_min_V) / 2**adc.bits * 1e6
        else:
            value = s
            for part in a.key.split("."):
                value = getattr(value, part)
        if ideal_adc and a.key.startswith("chip.adc."):
            value = 0.0
        if not math.isclose(float(value), a.value, rel_tol=1e-3, abs_tol=1e-12):
            differ[a.key] = {"value": float(value), "reference": a.value}
    return {"set": NAME, "n": len(wanted), "as_reference": not differ, "differ": differ}


__all__ = ["AS_BUILT", "FACEPLATE_NA", "NAME", "Assumption", "by_key", "stated"]
