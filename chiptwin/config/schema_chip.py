"""The ``[chip]`` sections of the scenario schema: ``[chip.pixel]``, ``[chip.adc]``,
``[chip.memory]``, ``[chip.dsp]``, ``[chip.timing]``, ``[chip.cost]``
(:mod:`chiptwin.config.schema_cost`) and ``[chip]`` itself, one frozen dataclass
each, units in the field names; every default with its source or marked as a choice (the rest of
the schema: :mod:`chiptwin.config.schema`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from chiptwin.config.fields import param
from chiptwin.config.schema_cost import Cost
from chiptwin.config.schema_ranges import (
    CLOCK_MAX_HZ,
    CLOCK_MIN_HZ,
    CLOCKS,
    LENGTH_MAX_UM,
    LENGTH_MIN_UM,
    LENGTHS,
    T_MAX,
    T_MIN,
    TEMP_MAX_C,
    TEMP_MIN_C,
    TEMPS,
    TIMES,
    VOLT_MAX,
    VOLTS,
)
from chiptwin.dsp.fmt import OVERFLOW_MODES, ROUNDING_MODES


@dataclass(frozen=True)
class Pixel:
    """``[chip.pixel]``: photodiode and readout (Eltoukhy et al. 2006; El Gamal & Eltoukhy 2005;
    most defaults are choices). What moves with what: the node capacitance follows the diode,
    junction_fF_per_um2 × diode_w_um × diode_h_um + sidewall_fF_per_um × 2 (diode_w_um +
    diode_h_um) + readout_fF (1000 fF for the 100 µm diode), unless capacitance_fF is given,
    which then wins; the conversion gain q/C and the kTC noise follow the capacitance; full_well_e
    is in electrons and does not follow; chip.pitch_um must hold the diode and is not moved by
    it.

    The capacitance is resolved once, when the scenario is loaded
    (:func:`chiptwin.config.load.scenario_from_dict`), so every stage reads one number.
    """

    diode_w_um: float = param(100.0, lo=LENGTH_MIN_UM, hi=LENGTH_MAX_UM,
                              doc="µm; paper's 100 µm diode; " + LENGTHS)
    diode_h_um: float = param(100.0, lo=LENGTH_MIN_UM, hi=LENGTH_MAX_UM,
                              doc="µm; paper's 100 µm diode; " + LENGTHS)
    qe: float = param(0.4, lo=0.0, hi=1.0, lo_open=True, doc="at 560 nm; typically 0.3–0.6")
    dark_current_nA_per_cm2: float = param(
        0.05, lo=0.0, hi=1.0e4,
        doc="at ref_temp_C; low-dark-current diodes: tens of pA/cm² (choice); ≤ 10 µA/cm², a "
            "thousand times a plain n-well's 0.1–10 nA/cm² (sources.md P8)"
    )
    ref_temp_C: float = param(25.0, lo=TEMP_MIN_C, hi=TEMP_MAX_C, doc=TEMPS)
    temperature_C: float = param(25.0, lo=TEMP_MIN_C, hi=TEMP_MAX_C,
                                 doc="room temperature by default; " + TEMPS)
    dark_doubling_C: float = param(
        7.0, lo=1.0, hi=50.0,
        doc="°C per doubling; 5–8 measured (Theuwissen, Harvest Imaging); 1 … 50 covers "
            "any silicon diode")
    capacitance_fF: float = param(
        0.0, lo=0.1, hi=1.0e7, zero="derived from the diode",
        doc="fF, the whole node; 0 = junction_fF_per_um2 × area + sidewall_fF_per_um × "
            "perimeter + readout_fF (1000 fF for the 100 µm diode); a value given wins over "
            "that (a datasheet's, a measured one); 0.1 fF (below the ≈1 fF node of the smallest "
            "pixels) … 10 nF (a 1 cm² n-well diode at ≈0.1 fF/µm²)")
    junction_fF_per_um2: float = param(
        0.08, lo=0.01, hi=2.0,
        doc="fF/µm², the diode's bottom (area) junction capacitance; n-well/p-substrate of a "
            "0.18 µm process: 0.07–0.13 fF/µm² (MOSIS wafer acceptance tests of TSMC SCN018, "
            "N-well area to substrate 69–130 aF/µm²); 0.01 (a deep, lightly doped well at high "
            "reverse bias) … 2 fF/µm², above the n+/p-substrate junction's ≈ 1 fF/µm² (same "
            "tests), the most heavily doped diode a CMOS pixel uses")
    sidewall_fF_per_um: float = param(
        0.25, lo=0.0, hi=2.0,
        doc="fF/µm of diode perimeter, the sidewall junction; 0.25 (choice: the n+ diffusion's "
            "fringe to substrate in the same MOSIS tests is 0.21–0.25 fF/µm); 0 … 2 fF/µm, "
            "eight times that fringe")
    readout_fF: float = param(
        100.0, lo=0.0, hi=1.0e4,
        doc="fF on the node besides the diode: reset and source-follower transistors, the "
            "converter's input, wiring (choice: 100 fF makes the 100 µm diode's node 1 pF with "
            "the two keys above); 0 … 10 pF")
    read_noise_e: float = param(
        100.0, lo=0.0, hi=1.0e6,
        doc="e⁻ rms per sample (choice); ≤ 1e6, above the kTC noise of the largest diode (10 nF: "
            "4e4 e⁻)")
    full_well_e: float = param(
        6.0e6, lo=1.0, hi=1.0e12,
        doc="e⁻; ≈1 V swing at 1 pF; ≤ 1e12 (10 nF over 10 V holds 6e11)")
    prnu_frac: float = param(0.01, lo=0.0, hi=0.5, doc="gain non-uniformity, rms fraction")
    dsnu_frac: float = param(0.1, lo=0.0, hi=2.0, doc="dark non-uniformity, rms fraction")
    true_cds: bool = param(True, kind=bool, doc="reset sampled right after reset: kTC cancels")
    pedestal_V: float = param(0.02, lo=0.0, hi=VOLT_MAX,
                              doc="V; output at zero charge, keeps noise in range; " + VOLTS)

    @property
    def derived_capacitance_fF(self) -> float:
        """The node capacitance the diode gives: junction × area + sidewall × perimeter +
        readout (the junction capacitance of a rectangular diode, bottom plus sidewall: Sze &
        Ng, Physics of Semiconductor Devices, 3rd ed., ch. 2). Unit: fF."""
        w, h = self.diode_w_um, self.diode_h_um
        return (self.junction_fF_per_um2 * (w * h) + self.sidewall_fF_per_um * (2.0 * (w + h))
                + self.readout_fF)


#: ``[chip.adc]`` keys of the converter as built, each 0 / off for the ideal ADC.
ADC_EFFECTS = ("comparator_noise_lsb", "comparator_noise_uV", "inl_max_lsb", "inl_shape",
               "inl_table", "dnl_rms_lsb", "offset_sigma_lsb", "gain_sigma")


@dataclass(frozen=True)
class Adc:
    """``[chip.adc]``: the per-pixel ADC (JSSC 2006: 13 bits, one channel per pixel)."""

    bits: int = param(13, kind=int, lo=1, hi=24, doc="JSSC 2006: 13")
    v_min_V: float = param(0.0, lo=-VOLT_MAX, hi=VOLT_MAX, doc="V; " + VOLTS)
    v_max_V: float = param(1.0, lo=-VOLT_MAX, hi=VOLT_MAX, doc="V; " + VOLTS)
    offset_error_lsb: float = param(0.0, lo=-2.0**24, hi=2.0**24,
                                    doc="LSB; at most the widest ADC's scale (24 bits)")
    gain_error: float = param(0.0, lo=-0.5, hi=0.5, doc="fractional")
    clock_hz: float = param(20e6, lo=CLOCK_MIN_HZ, hi=CLOCK_MAX_HZ,
                            doc="Hz; single-slope counter clock; " + CLOCKS)
    cycles_per_conversion: int = param(
        0, kind=int, lo=0, hi=2**32,
        doc="0 = 2^bits (single slope); ≤ 2^32, 256 times a 24-bit ramp")
    range_below_full_well_ok: bool = param(
        False, kind=bool, doc="true when the ADC range is meant to clip before the full well"
    )
    # the converter as built (chiptwin.pixel.converter); every effect 0 = the ideal converter
    comparator_noise_lsb: float = param(
        0.0, lo=0.0, hi=256.0,
        doc="LSB rms, input-referred comparator/ramp noise, a fresh draw per conversion; "
            "typical a few tenths to 1 LSB; ≤ 256 LSB: beyond, 8 of the bits are "
            "noise and the converter is a noise source, not an ADC")
    inl_max_lsb: float = param(
        0.0, lo=-1024.0, hi=1024.0,
        doc="LSB, signed peak of the ramp's bow (end-point INL), shared by the converters on a "
            "ramp; single-slope ramps: a few LSB (textbook); ±1024 LSB, an eighth of a "
            "13-bit range (a steeper bow reverses transitions and is refused for the bits)")
    inl_shape: str = param("quadratic", choices=("quadratic", "cubic", "table"),
                           doc="the bow 4u(1−u), the S-curve u(1−u)(1−2u), or inl_table")
    inl_table: str = param(
        "", kind=str,
        doc="file of the ramp's 2^bits − 1 transition levels (LSB of the ideal converter; "
            "text or .npy), non-decreasing; only with inl_shape = 'table'; '' = none")
    dnl_rms_lsb: float = param(
        0.0, lo=0.0, hi=1.0,
        doc="LSB rms spread of the code widths, fixed per chip, widths clipped at 0 (missing "
            "codes); ≤ 1 LSB: beyond, a sixth of the codes are missing and the bits mean little")
    offset_sigma_lsb: float = param(
        0.0, lo=0.0, hi=1024.0,
        doc="LSB rms per-converter offset mismatch, fixed per chip; ≤ 1024 LSB, an eighth of a "
            "13-bit range")
    gain_sigma: float = param(
        0.0, lo=0.0, hi=0.1,
        doc="fractional rms per-converter gain mismatch, fixed per chip; ≤ 0.1 so 1 + σz stays "
            "> 0 over any chip's draws (z > −10)")
    ramp: str = param("chip", choices=("chip", "column", "pixel"),
                      doc="converters sharing a ramp (its INL and DNL): all, a column's, none")
    comparator_noise_uV: float = param(
        0.0, lo=0.0, hi=1e5,
        doc="µV rms, the comparator noise as a voltage (instead of comparator_noise_lsb: stays "
            "physical when the bits change; one of the two may be set); ≤ 0.1 V")
    fom_schreier_db: float = param(
        165.7, lo=130.0, hi=190.0,
        doc="dB, Schreier figure of merit SNDR + 10 log10(f_s / 2 / P) for the converter's "
            "power and energy (Murmann, ADC Performance Survey 1997–2025: median of the "
            "ENOB 12–14 designs 165.7 dB, best of all 189.2 dB); 130–190 dB spans the survey")

    @property
    def conversion_time_s(self) -> float:
        """One conversion: ``cycles_per_conversion`` (single slope: 2^bits) cycles. Unit: s."""
        cycles = self.cycles_per_conversion or 2**self.bits
        return cycles / self.clock_hz

    @property
    def as_built_keys(self) -> dict[str, Any]:
        """The as-built effects that are set, key → value (empty: the ideal converter)."""
        keys = {k: getattr(self, k) for k in ADC_EFFECTS}
        keys["inl_shape"] = None if self.inl_shape != "table" else "table"
        return {k: v for k, v in keys.items() if v}

    @property
    def comparator_noise_total_lsb(self) -> float:
        """The comparator noise in LSB of this converter, from whichever key gives it."""
        lsb_uV = (self.v_max_V - self.v_min_V) / 2**self.bits * 1e6
        return self.comparator_noise_lsb + self.comparator_noise_uV / lsb_uV

    @property
    def energy_per_conversion_J(self) -> float:
        """Energy of one conversion from the Schreier figure of merit at the ideal SNDR of the
        bits, 6.02 N + 1.76 dB: FOM_S = SNDR + 10 log10(f_s / 2 / P) gives
        P / f_s = 1 / (2 · 10^((FOM_S − SNDR)/10)). Unit: J (Murmann's ADC survey; sources.md
        D5)."""
        sndr_db = 6.02 * self.bits + 1.76
        return 0.5 * 10.0 ** (-(self.fom_schreier_db - sndr_db) / 10.0)


@dataclass(frozen=True)
class Memory:
    """``[chip.memory]``: on-chip frame memory; capacity in bits (word × pixels × frames)."""

    word_bits: int = param(16, kind=int, lo=1, hi=64)
    capacity_bits: int = param(
        1_048_576, kind=int, lo=1, hi=2**40,
        doc="bits; 128 KiB (choice); ≤ 2^40 (128 GiB), beyond any on-chip memory")


@dataclass(frozen=True)
class Dsp:
    """``[chip.dsp]``: the on-chip DSP (background subtraction, CMS, N-frame averaging, and the
    program's further stages: kinetics-weighted accumulation, line binning, 8-tap FIR, Wiener)."""

    mode: str = param("float", choices=("float", "fixed", "rtl"))
    n_dark_frames: int = param(16, kind=int, lo=1, hi=65536, doc="frames in the dark ref")
    cms_samples: int = param(4, kind=int, lo=1, hi=256, doc="M reset + M signal samples")
    average_frames: int = param(4, kind=int, lo=1, hi=65536, doc="N frames per output")
    clock_hz: float = param(50e6, lo=CLOCK_MIN_HZ, hi=CLOCK_MAX_HZ,
                            doc="Hz (choice); " + CLOCKS)
    cycles_per_sample: float = param(
        2.0, lo=1e-3, hi=1e6,
        doc="DSP cycles per stored word; 1e-3 (a 1000-lane SIMD) … 1e6 (a slow soft core)")
    # fixed point (mode "fixed"): formats derive from the ADC bits and M, K, N (chiptwin.dsp.chain)
    rounding: str = param("RND_CONV", choices=ROUNDING_MODES, doc="every output register")
    overflow: str = param("SAT", choices=OVERFLOW_MODES, doc="every output register")
    acc_bits: int = param(0, kind=int, lo=0, hi=64, doc="N-frame accumulator; 0 = exact width")
    acc_overflow: str = param("WRAP", choices=("WRAP", "SAT"), doc="N-frame accumulator")
    report_error: bool = param(False, kind=bool, doc="run the float reference beside fixed")
    # the DSP program (chiptwin.dsp.program): ordered stages; the default is the fixed chain
    program: list = param(
        ["cms", "dark", "background", "average"], kind=list,
        doc="ordered stages from cms, dark, background, average, kinetics, bin_rows, fir8, "
            "wiener (chiptwin.dsp.program); default: the chain CMS → dark → background → "
            "N-frame average")
    bin_factor: int = param(
        0, kind=int, lo=0, hi=4096,
        doc="rows summed by bin_rows; 0 = every row (one column profile, as the paper's Fig. 12); "
            "must divide chip.rows")
    fir_cutoff: float = param(
        0.25, lo=0.01, hi=0.99,
        doc="fir8 cut-off as a fraction of the spatial Nyquist frequency (1 / 2 pitch); 0.25 "
            "(choice) keeps structure wider than ≈ 4 pixels; 0.01 … 0.99: any narrower band "
            "needs more than 8 taps, any wider passes everything")
    wiener_noise_to_signal: float = param(
        0.01, lo=0.0, hi=1.0e6,
        doc="λ = σ_n²/σ_s² of the wiener equalizer (Salama et al. 2004, Sec. 3.3); 0 = zero "
            "forcing; 0.01 "
            "(choice) for a site SNR of 20 dB; ≤ 1e6, where the equalizer passes nothing")
    wiener_coef_bits: int = param(
        18, kind=int, lo=4, hi=32,
        doc="width of the wiener coefficient words (choice 18, an FPGA/ASIC multiplier input); "
            "4 … 32")
    kinetics_acc_bits: int = param(
        44, kind=int, lo=8, hi=46,
        doc="kinetics accumulator width, one word per pixel held in frame memory (choice 44: "
            "the 13-bit chip's 37-bit products summed over 128 frames); 8 … 46, so that the "
            "accumulator times the 18-bit normalisation fits 64 bits")


@dataclass(frozen=True)
class Timing:
    """``[chip.timing]``: the frame schedule."""

    frame_period_s: float = param(1.0, lo=T_MIN, hi=T_MAX, doc="s; " + TIMES)
    t_int_s: float = param(0.99, lo=T_MIN, hi=T_MAX,
                           doc="s of integration per frame; " + TIMES)
    t_reset_s: float = param(1e-5, lo=T_MIN, hi=T_MAX, doc="s; " + TIMES)


@dataclass(frozen=True)
class Chip:
    """``[chip]``: the array and its blocks (JSSC 2006: 8 × 16 pixels)."""

    rows: int = param(8, kind=int, lo=1, hi=4096, doc="JSSC 2006: 8; ≤ 4096 (a 16 Mpixel array)")
    cols: int = param(16, kind=int, lo=1, hi=4096, doc="JSSC 2006: 16; ≤ 4096")
    pitch_um: float = param(125.0, lo=LENGTH_MIN_UM, hi=LENGTH_MAX_UM,
                            doc="µm (choice: diode + 25 µm); " + LENGTHS)
    fixed_pattern_seed: int = param(
        -1, kind=int, lo=-1, hi=2**63 - 1,
        doc="seed of this chip's PRNU/DSNU maps; -1 = from scenario.seed (one chip per seed)")
    pixel: Pixel = field(default_factory=Pixel)
    adc: Adc = field(default_factory=Adc)
    memory: Memory = field(default_factory=Memory)
    dsp: Dsp = field(default_factory=Dsp)
    timing: Timing = field(default_factory=Timing)
    cost: Cost = field(default_factory=Cost)

    @property
    def n_pixels(self) -> int:
        """Pixels in the array."""
        return self.rows * self.cols

    @property
    def samples_per_frame(self) -> int:
        """ADC samples per pixel per frame: M reset + M signal (correlated multiple sampling)."""
        return 2 * self.dsp.cms_samples

    @property
    def frame_bits(self) -> int:
        """Bits one raw frame takes in memory: word × pixels × samples. Unit: bit."""
        return self.memory.word_bits * self.n_pixels * self.samples_per_frame

    @property
    def readout_time_s(self) -> float:
        """Reset plus all conversions of one frame (all pixel ADCs in parallel). Unit: s."""
        return self.timing.t_reset_s + self.samples_per_frame * self.adc.conversion_time_s


