"""The scenario schema: one frozen dataclass per TOML section, units in the field names.

Every default is documented with its source (REFERENCE.md section) or marked as a choice. The rule
of each field (type, range, choices) sits beside it (:func:`chiptwin.config.fields.param`);
cross-field rules live in :mod:`chiptwin.config.consistency`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from chiptwin.config.fields import param
from chiptwin.dsp.fmt import OVERFLOW_MODES, ROUNDING_MODES

ASSAY_KINDS = ("pyrosequencing", "atp", "luciferase_label", "substrate", "catalyst", "flux")

#: Keys of ``[assay]`` that each kind uses; any other non-common key is an error for that kind.
ASSAY_KIND_KEYS: dict[str, frozenset[str]] = {
    "pyrosequencing": frozenset(
        {"dna_fmol", "template", "key", "flow_order", "n_flows", "flow_period_s", "k_t_per_s",
         "k_a_per_s", "quantum_yield", "photons_per_incorporation"}
    ),
    "atp": frozenset({"atp_fmol", "turnover_per_s", "quantum_yield"}),
    "luciferase_label": frozenset({"luciferase_amol", "turnover_per_s", "quantum_yield"}),
    "substrate": frozenset({"substrate_amol", "k_f_per_M_per_s", "enzyme_M", "quantum_yield"}),
    "catalyst": frozenset({"enzyme_amol", "k_f_per_M_per_s", "substrate_max_M",
                           "quantum_yield"}),
    "flux": frozenset({"photons_per_s_per_um2"}),
}
ASSAY_COMMON_KEYS = frozenset({"kind", "start_s"})


@dataclass(frozen=True)
class ScenarioMeta:
    """``[scenario]``: what the run is called and the seed of every random stream."""

    name: str = param(kind=str, doc="identifier used in outputs")
    seed: int = param(kind=int, lo=0, hi=2**63 - 1, doc="root of np.random.SeedSequence")
    description: str = param("", kind=str)


@dataclass(frozen=True)
class Assay:
    """``[assay]``: the chemistry that makes light (Salama et al. 2004, eqs. 2–19; REFERENCE §1)."""

    kind: str = param(choices=ASSAY_KINDS)
    start_s: float = param(0.0, lo=0.0, doc="s; reagent added / first flow / light on")
    quantum_yield: float = param(
        0.88, lo=0.0, hi=1.0, lo_open=True,
        doc="photons per luciferase turnover; 0.88 Seliger & McElroy (paper), 0.41 Ando 2008",
    )
    # pyrosequencing (eqs. 18–19)
    dna_fmol: float = param(1.0, lo=0.0, lo_open=True, doc="fmol of template DNA per site")
    template: str = param("", kind=str, doc="bases A C G T, read 5'→3' from the primer")
    key: str = param("TCAG", kind=str, doc="known prefix of the template; its 1-mers normalise")
    flow_order: str = param("TACG", kind=str, doc="nucleotide dispensation cycle")
    n_flows: int = param(16, kind=int, lo=1, hi=10_000)
    flow_period_s: float = param(60.0, lo=0.0, lo_open=True, doc="s between dispensations")
    k_t_per_s: float = param(1.0, lo=0.0, lo_open=True, doc="1/s luciferase turnover (eq. 18)")
    k_a_per_s: float = param(0.05, lo=0.0, lo_open=True, doc="1/s apyrase removal (eq. 18)")
    photons_per_incorporation: float = param(
        0.0, lo=0.0, doc="measured yield; 0 = derive α·k_t/k_a = 17.6 (eq. 19); Ronaghi ≈ 0.01"
    )
    # ATP assay (eq. 12) and luciferase label (eq. 13)
    atp_fmol: float = param(1.0, lo=0.0, lo_open=True, doc="fmol ATP per site, V·[ATP0]")
    luciferase_amol: float = param(1.0, lo=0.0, lo_open=True, doc="amol luciferase per site")
    turnover_per_s: float = param(0.1, lo=0.0, lo_open=True, doc="1/s; 0.1 glow … 1 flash")
    # substrate detection (eqs. 5–6) and catalyst detection (eqs. 7–8), mass action (eq. 2)
    substrate_amol: float = param(1.0, lo=0.0, lo_open=True, doc="amol substrate per site V·[S0]")
    enzyme_amol: float = param(1.0, lo=0.0, lo_open=True, doc="amol enzyme per site V·[E]")
    k_f_per_M_per_s: float = param(1.0e5, lo=0.0, lo_open=True, doc="1/(M·s), forward rate")
    enzyme_M: float = param(1.0e-6, lo=0.0, lo_open=True, doc="M; enzyme in excess")
    substrate_max_M: float = param(1.0e-6, lo=0.0, lo_open=True, doc="M; substrate in excess")
    # flux: light given directly at the sensor plane
    photons_per_s_per_um2: float = param(0.5, lo=0.0, doc="photons/s/µm² on the diode")


@dataclass(frozen=True)
class Sites:
    """``[sites]``: where the assay sites sit, above pixel centres (contact imaging)."""

    at_pixels: list = param(
        "all", kind=(str, list), doc='"all", "centre", or a list of [row, col] pixel indices'
    )
    footprint_radius_um: float = param(0.0, lo=0.0, doc="µm; disc footprint of a site, 0 = point")
    height_um: float = param(15.0, lo=0.0, lo_open=True, doc="µm above the diode (paper: 15 µm)")


@dataclass(frozen=True)
class Optics:
    """``[optics]``: how emitted light reaches the diodes (REFERENCE §2)."""

    coupling: str = param("contact", choices=("contact", "lens"))
    convention: str = param("lambertian_na2", choices=("lambertian_na2", "isotropic"))
    transmission: float = param(1.0, lo=0.0, hi=1.0, lo_open=True, doc="extra optical loss")
    aperture_diameter_um: float = param(
        0.0, lo=0.0, doc="µm; lens aperture D (lens coupling only)"
    )
    object_distance_um: float = param(0.0, lo=0.0, doc="µm; sample-to-lens U (lens only)")


@dataclass(frozen=True)
class Pixel:
    """``[chip.pixel]``: photodiode and readout (REFERENCE §3–4; most defaults are choices)."""

    diode_w_um: float = param(100.0, lo=0.0, lo_open=True, doc="µm; paper's 100 µm diode")
    diode_h_um: float = param(100.0, lo=0.0, lo_open=True, doc="µm; paper's 100 µm diode")
    qe: float = param(0.4, lo=0.0, hi=1.0, lo_open=True, doc="at 560 nm; REFERENCE §4: 0.3–0.6")
    dark_current_nA_per_cm2: float = param(
        0.05, lo=0.0, doc="at ref_temp_C; low-dark-current diodes: tens of pA/cm² (choice)"
    )
    ref_temp_C: float = param(25.0, lo=-273.15)
    temperature_C: float = param(25.0, lo=-273.15, doc="°C; room temperature")
    dark_doubling_C: float = param(7.0, lo=0.0, lo_open=True, doc="°C per doubling (5–8)")
    capacitance_fF: float = param(1000.0, lo=0.0, lo_open=True, doc="fF; ≈1 pF for 100 µm n-well")
    read_noise_e: float = param(100.0, lo=0.0, doc="e⁻ rms per sample (choice)")
    full_well_e: float = param(6.0e6, lo=0.0, lo_open=True, doc="e⁻; ≈1 V swing at 1 pF")
    prnu_frac: float = param(0.01, lo=0.0, hi=0.5, doc="gain non-uniformity, rms fraction")
    dsnu_frac: float = param(0.1, lo=0.0, hi=2.0, doc="dark non-uniformity, rms fraction")
    true_cds: bool = param(True, kind=bool, doc="reset sampled right after reset: kTC cancels")
    pedestal_V: float = param(0.02, lo=0.0, doc="V; output at zero charge, keeps noise in range")


@dataclass(frozen=True)
class Adc:
    """``[chip.adc]``: the per-pixel ADC (JSSC 2006: 13 bits, one channel per pixel)."""

    bits: int = param(13, kind=int, lo=1, hi=24, doc="JSSC 2006: 13")
    v_min_V: float = param(0.0)
    v_max_V: float = param(1.0)
    offset_error_lsb: float = param(0.0)
    gain_error: float = param(0.0, lo=-0.5, hi=0.5, doc="fractional")
    clock_hz: float = param(20e6, lo=0.0, lo_open=True, doc="Hz; single-slope counter clock")
    cycles_per_conversion: int = param(0, kind=int, lo=0, doc="0 = 2^bits (single slope)")
    range_below_full_well_ok: bool = param(
        False, kind=bool, doc="true when the ADC range is meant to clip before the full well"
    )

    @property
    def conversion_time_s(self) -> float:
        """One conversion: ``cycles_per_conversion`` (single slope: 2^bits) cycles. Unit: s."""
        cycles = self.cycles_per_conversion or 2**self.bits
        return cycles / self.clock_hz


@dataclass(frozen=True)
class Memory:
    """``[chip.memory]``: on-chip frame memory; capacity in bits (word × pixels × frames)."""

    word_bits: int = param(16, kind=int, lo=1, hi=64)
    capacity_bits: int = param(1_048_576, kind=int, lo=1, doc="bits; 128 KiB (choice)")


@dataclass(frozen=True)
class Dsp:
    """``[chip.dsp]``: the on-chip DSP (background subtraction, CMS, N-frame averaging)."""

    mode: str = param("float", choices=("float", "fixed", "rtl"))
    n_dark_frames: int = param(16, kind=int, lo=1, hi=65536, doc="frames in the dark ref")
    cms_samples: int = param(4, kind=int, lo=1, hi=256, doc="M reset + M signal samples")
    average_frames: int = param(4, kind=int, lo=1, hi=65536, doc="N frames per output")
    clock_hz: float = param(50e6, lo=0.0, lo_open=True, doc="Hz (choice)")
    cycles_per_sample: float = param(2.0, lo=0.0, lo_open=True, doc="DSP cycles per stored word")
    # fixed point (mode "fixed"): formats derive from the ADC bits and M, K, N (chiptwin.dsp.chain)
    rounding: str = param("RND_CONV", choices=ROUNDING_MODES, doc="every output register")
    overflow: str = param("SAT", choices=OVERFLOW_MODES, doc="every output register")
    acc_bits: int = param(0, kind=int, lo=0, hi=64, doc="N-frame accumulator; 0 = exact width")
    acc_overflow: str = param("WRAP", choices=("WRAP", "SAT"), doc="N-frame accumulator")
    report_error: bool = param(False, kind=bool, doc="run the float reference beside fixed")


@dataclass(frozen=True)
class Timing:
    """``[chip.timing]``: the frame schedule."""

    frame_period_s: float = param(1.0, lo=0.0, lo_open=True)
    t_int_s: float = param(0.99, lo=0.0, lo_open=True, doc="s of integration per frame")
    t_reset_s: float = param(1e-5, lo=0.0, lo_open=True)


@dataclass(frozen=True)
class Chip:
    """``[chip]``: the array and its blocks (JSSC 2006: 8 × 16 pixels)."""

    rows: int = param(8, kind=int, lo=1, hi=4096)
    cols: int = param(16, kind=int, lo=1, hi=4096)
    pitch_um: float = param(125.0, lo=0.0, lo_open=True, doc="µm (choice: diode + 25 µm)")
    fixed_pattern_seed: int = param(
        -1, kind=int, lo=-1, hi=2**63 - 1,
        doc="seed of this chip's PRNU/DSNU maps; -1 = from scenario.seed (one chip per seed)")
    pixel: Pixel = field(default_factory=Pixel)
    adc: Adc = field(default_factory=Adc)
    memory: Memory = field(default_factory=Memory)
    dsp: Dsp = field(default_factory=Dsp)
    timing: Timing = field(default_factory=Timing)

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


@dataclass(frozen=True)
class Fidelity:
    """``[run.fidelity]``: the level of each stage (SPEC: the fidelity ladder)."""

    kinetics: str = param("closed_form", choices=("closed_form", "cascade"))
    photons: str = param("binned", choices=("expected", "binned", "events"))
    optics: str = param("psf", choices=("na2", "psf", "raytrace"))
    dsp: str = param("", choices=("", "float", "fixed", "rtl"), doc='"" = [chip.dsp] mode')


@dataclass(frozen=True)
class Run:
    """``[run]``: how long to run and at which fidelity."""

    duration_s: float = param(lo=0.0, lo_open=True, doc="s of chip time")
    detection_snr_power: float = param(
        10.0, lo=0.0, lo_open=True, doc="power SNR (eq. 22) above which a site is detected"
    )
    light_estimator: str = param(
        "sum", choices=("sum", "matched"),
        doc="window total: plain sum of DSP outputs, or the matched filter for the assay's "
            "exponential decay (pyrosequencing k_a, ATP turnover)")
    fidelity: Fidelity = field(default_factory=Fidelity)


@dataclass(frozen=True)
class Scenario:
    """A whole scenario file, validated."""

    scenario: ScenarioMeta
    assay: Assay
    sites: Sites
    optics: Optics
    chip: Chip
    run: Run
    source: str = "<scenario>"

    @property
    def dsp_level(self) -> str:
        """The DSP level in force: ``run.fidelity.dsp`` if set, else ``chip.dsp.mode``."""
        return self.run.fidelity.dsp or self.chip.dsp.mode
