"""The scenario schema: one frozen dataclass per TOML section, units in the field names.

Every default is documented with its source (docs/background/sources.md) or marked as a choice. The
rule of each field (type, range, choices) sits beside it (:func:`chiptwin.config.fields.param`);
cross-field rules live in :mod:`chiptwin.config.consistency`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

from chiptwin.config.fields import param
from chiptwin.config.schema_chip import ADC_EFFECTS, Adc, Chip, Dsp, Memory, Pixel, Timing
from chiptwin.config.schema_ranges import (
    AMOL_MAX,
    AMOL_MIN,
    AMOUNTS,
    CLOCK_MAX_HZ,
    CLOCK_MIN_HZ,
    CLOCKS,
    FMOL_MAX,
    FMOL_MIN,
    LENGTH_MAX_UM,
    LENGTH_MIN_UM,
    LENGTHS,
    RATE_MAX,
    RATE_MIN,
    RATES,
    T_MAX,
    T_MIN,
    TEMP_MAX_C,
    TEMP_MIN_C,
    TEMPS,
    TIMES,
    VOLT_MAX,
    VOLTS,
)

#: ``[assay] chemistry`` presets: "" (none: the scene's own keys) and the fitted ones
#: (chiptwin.kinetics.chemistry_presets.PRESET_NAMES, kept equal by a test).
CHEMISTRIES = ("", "454_flx", "454_titanium", "ion_pgm")

#: The flow-value model's keys of ``[assay]`` (chiptwin.kinetics.chemistry.FlowModel).
CHEMISTRY_KEYS = ("chemistry", "flow_yield_cv", "flow_noise_sd", "flow_background",
                  "well_noise_cv", "homopolymer_yield_loss", "empty_flow_law", "empty_flow_mean",
                  "empty_flow_sd")

ASSAY_KINDS = ("pyrosequencing", "atp", "luciferase_label", "substrate", "catalyst", "flux")

#: Keys of ``[assay]`` that each kind uses; any other non-common key is an error for that kind.
ASSAY_KIND_KEYS: dict[str, frozenset[str]] = {
    "pyrosequencing": frozenset(
        {"dna_fmol", "template", "key", "flow_order", "n_flows", "flow_period_s", "k_t_per_s",
         "k_a_per_s", "quantum_yield", "photons_per_incorporation", "template_length",
         "template_gc", "template_homopolymer_p", "template_homopolymer_max", "template_seed",
         "incomplete_extension", "carry_forward", "droop_per_flow", "dna_cv", "caller",
         *CHEMISTRY_KEYS}
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
    """``[assay]``: the chemistry that makes light (Salama et al. 2004, eqs. 2–19; sources.md
    Kinetics)."""

    kind: str = param(choices=ASSAY_KINDS)
    start_s: float = param(0.0, lo=0.0, hi=T_MAX,
                           doc="s; reagent added / first flow / light on; 0 or " + TIMES)
    quantum_yield: float = param(
        0.88, lo=0.0, hi=1.0, lo_open=True,
        doc="photons per luciferase turnover; 0.88 Seliger & McElroy (paper), 0.41 Ando 2008",
    )
    # pyrosequencing (eqs. 18–19)
    dna_fmol: float = param(1.0, lo=FMOL_MIN, hi=FMOL_MAX,
                            doc="fmol of template DNA " + AMOUNTS)
    template: str = param("", kind=str, doc="bases A C G T, read 5'→3' from the primer")
    key: str = param("TCAG", kind=str, doc="known prefix of the template; its 1-mers normalise")
    flow_order: str = param("TACG", kind=str, doc="nucleotide dispensation cycle")
    n_flows: int = param(16, kind=int, lo=1, hi=10_000,
                         doc="dispensations; 454 runs ≈ 800 flows")
    flow_period_s: float = param(60.0, lo=T_MIN, hi=T_MAX,
                                 doc="s between dispensations; " + TIMES)
    k_t_per_s: float = param(1.0, lo=RATE_MIN, hi=RATE_MAX,
                             doc="1/s luciferase turnover (eq. 18; paper 1); " + RATES)
    k_a_per_s: float = param(0.05, lo=RATE_MIN, hi=RATE_MAX,
                             doc="1/s apyrase removal (eq. 18; paper 0.05); " + RATES)
    photons_per_incorporation: float = param(
        0.0, lo=0.0, hi=1.0e6,
        doc="measured yield; 0 = derive α·k_t/k_a = 17.6 (eq. 19); Ronaghi ≈ 0.01; ≤ 1e6, "
            "five orders above eq. 19"
    )
    # long reads: a drawn template, the per-flow losses that end reads, the per-site DNA spread
    template_length: int = param(
        0, kind=int, lo=0, hi=5000,
        doc="bases of a drawn insert after the key (template = key + insert); 0 = use "
            "`template`; ≤ 5,000, beyond the longest pyrosequencing reads (454 GS FLX+ ≈ 1,000)")
    template_gc: float = param(
        0.5, lo=0.0, hi=1.0, doc="G+C share of the drawn insert (choice 0.5); 0 … 1")
    template_homopolymer_p: float = param(
        0.25, lo=0.0, hi=0.9,
        doc="geometric continuation probability of a drawn homopolymer; 0.25 = a uniformly "
            "random sequence; ≤ 0.9 (mean run 10 bases)")
    template_homopolymer_max: int = param(
        8, kind=int, lo=1, hi=12,
        doc="longest drawn homopolymer, bases; 1 … 12, the caller's limit (454 reads resolve "
            "≈ 8: Balzer et al., Bioinformatics 26:i420, 2010)")
    template_seed: int = param(
        0, kind=int, lo=0, hi=2**63 - 1,
        doc="seed of the drawn template (its own stream, so replicates share the template)")
    incomplete_extension: float = param(
        0.0, lo=0.0, hi=0.05,
        doc="ε, share of strands not extended per flow; 0 = none; 454: 0.001–0.003 (Margulies "
            "et al., Nature 437:376, 2005); ≤ 0.05, where no read passes 100 flows")
    carry_forward: float = param(
        0.0, lo=0.0, hi=0.05,
        doc="λ, share of strands extended one homopolymer ahead per flow (the previous "
            "nucleotide not yet removed); 0 = none; 454: 0.01–0.02 (Margulies 2005); ≤ 0.05")
    droop_per_flow: float = param(
        0.0, lo=0.0, hi=0.02,
        doc="share of the active template (or polymerase) lost per flow, signal droop; 0 = "
            "none; choice 0.001 in the long-read scene (454 reads lose about half their light "
            "over 400–800 flows); ≤ 0.02 (the signal halves within 35 flows)")
    dna_cv: float = param(
        0.0, lo=0.0, hi=1.0,
        doc="coefficient of variation of the DNA copies per site, drawn per site and per chip "
            "(gamma law); 0 = every site holds dna_fmol; ≤ 1 (exponential spread)")
    caller: str = param(
        "round", choices=("round", "dephase"),
        doc="base caller: round (each flow value rounded) or dephase (phase-correcting, "
            "Eltoukhy & El Gamal, ICASSP 2006), both with phred qualities")
    # the flow-value model (chiptwin.kinetics.chemistry): what a phase-corrected flow reads
    chemistry: str = param(
        "", kind=str, choices=CHEMISTRIES,
        doc="named chemistry fitted to real runs (454 GS FLX, GS FLX Titanium flow-value "
            "profiles; Ion PGM reads against their reference): sets the flow_* , well_*, "
            "homopolymer_* and empty_flow_* keys below; keys the scene gives override it; "
            "\"\" = none, the scene's own keys")
    flow_yield_cv: float = param(
        0.0, lo=0.0, hi=0.5,
        doc="CV of each flow's light per well (reagent delivery, enzyme turnover flow by "
            "flow): a flow-value spread growing with the homopolymer; 0 = none; 454 FLX "
            "0.06; ≤ 0.5, where a 2-mer reads as a 1-mer one flow in three")
    flow_noise_sd: float = param(
        0.0, lo=0.0, hi=0.5,
        doc="sd of additive light in every flow, 1-mer units; 0 = none; 454 FLX 0.059, Ion "
            "0.13; ≤ 0.5, half a base (no call survives it)")
    flow_background: float = param(
        0.0, lo=-0.2, hi=0.2,
        doc="mean of that additive light, 1-mer units (light is clipped at 0); 454 FLX "
            "+0.015 (its 1-mers read 1.013); within ±0.2, a fifth of a base")
    well_noise_cv: float = param(
        0.0, lo=0.0, hi=3.0,
        doc="CV of each well's noise level (gamma law, drawn per site): peaked values with "
            "long tails; 0 = every well alike; 454 ≈ 0.9–1.0; ≤ 3, beyond any fitted run")
    homopolymer_yield_loss: float = param(
        0.0, lo=0.0, hi=0.2,
        doc="light lost per base past the first of a homopolymer (h-mer reads "
            "h·(1 − κ)^(h−1)); 0 = linear; Ion 0.004; ≤ 0.2, an 8-mer reading 1.7 bases low")
    empty_flow_law: str = param(
        "lognormal", kind=str, choices=("lognormal", "normal"),
        doc="law of the light of a flow that extends nothing: lognormal (454: Balzer et al., "
            "Bioinformatics 26:i420, 2010) or normal")
    empty_flow_mean: float = param(
        0.0, lo=-0.5, hi=0.5,
        doc="mean of that empty-flow light, 1-mer units; 0 = none; 454 FLX 0.070, Titanium "
            "0.10; within ±0.5 (a 0-mer beyond reads as a 1-mer); ≥ 0 for the lognormal")
    empty_flow_sd: float = param(
        0.0, lo=0.0, hi=0.5,
        doc="sd of the empty-flow light, 1-mer units; 0 = a constant; 454 FLX 0.015, Ion 0.5 "
            "(a light near 0 in most flows, bright in a few); ≤ 0.5, half a base")
    # ATP assay (eq. 12) and luciferase label (eq. 13)
    atp_fmol: float = param(1.0, lo=FMOL_MIN, hi=FMOL_MAX,
                            doc="fmol ATP, V·[ATP0], " + AMOUNTS)
    luciferase_amol: float = param(1.0, lo=AMOL_MIN, hi=AMOL_MAX,
                                   doc="amol luciferase " + AMOUNTS)
    turnover_per_s: float = param(0.1, lo=RATE_MIN, hi=RATE_MAX,
                                  doc="1/s; 0.1 glow … 1 flash; " + RATES)
    # substrate detection (eqs. 5–6) and catalyst detection (eqs. 7–8), mass action (eq. 2)
    substrate_amol: float = param(1.0, lo=AMOL_MIN, hi=AMOL_MAX,
                                  doc="amol substrate V·[S0] " + AMOUNTS)
    enzyme_amol: float = param(1.0, lo=AMOL_MIN, hi=AMOL_MAX, doc="amol enzyme V·[E] " + AMOUNTS)
    k_f_per_M_per_s: float = param(
        1.0e5, lo=1e-9, hi=1e10,
        doc="1/(M·s), forward rate; ≤ 1e10, the diffusion limit (Smoluchowski, ≈ 1e9–1e10)")
    enzyme_M: float = param(1.0e-6, lo=1e-18, hi=1.0,
                            doc="M; enzyme in excess; 1 aM … 1 M (proteins dissolve to mM)")
    substrate_max_M: float = param(1.0e-6, lo=1e-18, hi=1.0,
                                   doc="M; substrate in excess; 1 aM … 1 M")
    # flux: light given directly at the sensor plane
    photons_per_s_per_um2: float = param(
        0.5, lo=0.0, hi=1.0e12,
        doc="photons/s/µm² on the diode; ≤ 1e12, above direct sunlight (≈ 3e9 at 560 nm)")


@dataclass(frozen=True)
class Sites:
    """``[sites]``: where the assay sites sit, above pixel centres (contact imaging)."""

    at_pixels: list = param(
        "all", kind=(str, list), doc='"all", "centre", or a list of [row, col] pixel indices'
    )
    footprint_radius_um: float = param(
        0.0, lo=0.0, hi=LENGTH_MAX_UM, doc="µm; disc footprint of a site, 0 = point; ≤ the pitch")
    height_um: float = param(15.0, lo=LENGTH_MIN_UM, hi=LENGTH_MAX_UM,
                             doc="µm above the diode (paper: 15 µm); " + LENGTHS)
    amounts_fmol: list = param(
        [], kind=list,
        doc="fmol of the assay's analyte at each site, one per site in at_pixels order (a dose "
            "response); 0 = a blank site; [] = the [assay] amount at every site. Each in "
            "[0, the [assay] amount]: [assay] names the largest, which bounds the run's budget "
            "(chiptwin.config.budget), and 1e-9 fmol is below one molecule",
    )


EMITTER_LAWS = ("isotropic", "lambertian", "lambertian_na2")
"""The emitter's angular law: molecules in solution emit isotropically; a Lambertian
emitter faces the diodes; ``lambertian_na2`` is the paper's NA² convention (Salama et al. 2004,
Sec. 3.1), kept by name to reproduce its figures."""

INDEX_MIN, INDEX_MAX = 1.0, 4.5
INDICES = "vacuum 1 … 4.5, above silicon's ≈ 4.1–4.3 at 470–560 nm (textbook; sources.md O11)"


@dataclass(frozen=True)
class FaceplateSection:
    """``[optics.faceplate]``: a fibre-optic faceplate between the assay and the diodes (the JSSC
    2006 chip's assays sit on one, Eltoukhy et al. 2006). ``na = 0``: none."""

    na: float = param(
        0.0, lo=0.0, hi=2.0,
        doc="numerical aperture in air; 0 = no faceplate; makers' datasheets 0.35 … 1.0 "
            "(sources.md O16); ≤ 2, above any glass core's index")
    fiber_pitch_um: float = param(
        6.0, lo=LENGTH_MIN_UM, hi=1.0e3,
        doc="µm between fibre centres, the blur of the light carried down; imaging faceplates "
            "3 … 25 µm (choice 6); 0.1 µm … 1 mm and ≤ half the diode's smaller side (the psf "
            "level's blur quadrature, chiptwin.config.budget.FIBER_PER_DIODE_MAX)")
    thickness_um: float = param(
        1000.0, lo=1.0, hi=1.0e5,
        doc="µm; enters the site height (sites.height_um = layers + this); 1 µm … 10 cm")
    open_area_ratio: float = param(
        0.7, lo=0.0, hi=1.0, lo_open=True,
        doc="the cores' share of the face; the cladding and extramural absorber take the rest "
            "(choice 0.7)")
    core_n: float = param(
        0.0, lo=0.0, hi=INDEX_MAX,
        doc="index of the fibre cores for the Fresnel loss at the entry; 0 = no loss; else "
            + INDICES)

    @property
    def present(self) -> bool:
        """True when the scenario states a faceplate (``na > 0``)."""
        return self.na > 0.0


TOP_MEDIA = ("solution", "air", "glass")
"""What lies above the site's solution (chiptwin.optics.top): more of it, air, a glass lid."""

#: A glass lid's index when ``lid_n`` is not given: soda-lime and borosilicate glass 1.47–1.52
#: near 560 nm (crown glass ≈ 1.52, borosilicate ≈ 1.47; Hecht, *Optics*, ch. 3).
LID_N_DEFAULT = 1.5


@dataclass(frozen=True)
class TopSection:
    """``[optics.top]``: the site's top surface, what returns the light the site sends up.

    ``"solution"`` (default): the solution continues far above the site (a deep flow cell, an
    index-matched absorber): nothing returns, the twin as it was. ``"air"``: an open well, the
    solution's free surface ``solution_depth_um`` above the site plane, air above (total
    internal reflection beyond 48.75° from water). ``"glass"``: a lid of ``lid_n`` and
    ``lid_thickness_um`` on the solution, air above it. The solution's index is the first
    layer's (``optics.layers[0].n``, 1.33 without layers)."""

    medium: str = param(
        "solution", choices=TOP_MEDIA,
        doc='"solution" = nothing returns (a deep flow cell); "air" = an open well; "glass" = a '
            "lid with air above")
    solution_depth_um: float = param(
        0.0, lo=0.0, hi=1.0e4,
        doc="µm from the site plane up to the free surface or the lid; required with air or "
            "glass, in [0.1, 1e4]: 0.1 µm (a film of solution over the site) … 1 cm, deeper "
            "than any drop; an open drop is 100 µm – a few mm, a flow cell's channel 50–500 µm; "
            "0 = not given (with solution only)")
    lid_thickness_um: float = param(
        0.0, lo=0.0, hi=1.0e4,
        doc="µm; the glass lid's thickness, required with glass and only there, in [1, 1e4]: "
            "1 µm (a membrane) … 1 cm; coverslips 80–250 µm, slides 1 mm")
    lid_n: float = param(
        0.0, lo=0.0, hi=2.5,
        doc=f"the lid's index, with glass only; 0 = {LID_N_DEFAULT:g} (soda-lime or "
            "borosilicate glass, 1.47–1.52); else in [the solution's n, 2.5]: fused silica "
            "1.46, PDMS 1.41, sapphire 1.77; a lid of lower index than the solution is not "
            "modelled")

    @property
    def present(self) -> bool:
        """True when the top returns light (``medium`` is not ``"solution"``)."""
        return self.medium != "solution"

    @property
    def lid_index(self) -> float:
        """The lid's index in force: ``lid_n``, else :data:`LID_N_DEFAULT`."""
        return self.lid_n or LID_N_DEFAULT


@dataclass(frozen=True)
class Optics:
    """``[optics]``: how emitted light reaches the diodes (Salama et al. 2004, Sec. 3; sources.md
    Optics).

    ``emitter`` names the angular law; ``convention`` is its older name, kept as an alias (a file
    may set either; both, only if they agree). ``layers`` is the planar stack from the site down
    to the diodes (or to the faceplate's top), an array of tables ``{name, n, thickness_um,
    alpha_per_um | k}`` top to bottom; rule: the thicknesses (plus the faceplate's) sum to
    ``sites.height_um``, which stays the one site height every level reads; the first layer (the
    solution the site sits in) may leave out its thickness, and then fills the height.
    """

    coupling: str = param("contact", choices=("contact", "lens"))
    emitter: str = param(
        "", choices=("",) + EMITTER_LAWS,
        doc='"" = convention (its older name); isotropic for molecules in solution')
    convention: str = param("lambertian_na2", choices=("lambertian_na2", "isotropic"),
                            doc="the emitter's law under its older name (alias of emitter)")
    transmission: float = param(1.0, lo=0.0, hi=1.0, lo_open=True, doc="extra optical loss")
    aperture_diameter_um: float = param(
        0.0, lo=0.0, hi=1.0e6, doc="µm; lens aperture D (lens coupling only); ≤ 1 m"
    )
    object_distance_um: float = param(
        0.0, lo=0.0, hi=1.0e7, doc="µm; sample-to-lens U (lens only); ≤ 10 m")
    layers: list = param(
        [], kind=list,
        doc="the planar stack from the site down, top to bottom: tables {name, n, thickness_um, "
            "alpha_per_um or k}; [] = one medium of sites.height_um; thicknesses (plus a "
            "faceplate's) sum to sites.height_um, or the first leaves it out and fills it")
    wavelength_nm: float = param(
        562.0, lo=200.0, hi=1200.0,
        doc="nm; the emission's peak: turns a layer's k into alpha_per_um = 4πk/λ and centres "
            "the band thin films are averaged over; the paper's 562 nm; 200 … 1200 nm, "
            "silicon's band")
    band_fwhm_nm: float = param(
        70.0, lo=1.0, hi=300.0,
        doc="nm; the emission band's full width at half maximum (Gaussian), over which thin "
            "films' interference is averaged; 70 nm assumed for firefly luciferase (not "
            "published; a choice); 1 nm (a line) … 300 nm")
    thin_film_um: float = param(
        2.0, lo=0.0, hi=10.0,
        doc="µm; inner layers this thin or thinner are thin films: their multiple reflections "
            "add as amplitudes over the band (transfer matrices) at the psf and raytrace "
            "levels, in place (they move light ≤ d·tanθ sideways); 0 = every layer a ray "
            "layer; ≤ 10 µm, beyond which a round trip moves light ≥ 20 µm")
    silicon_n: float = param(
        0.0, lo=0.0, hi=INDEX_MAX,
        doc="0 = the diode plane absorbs what reaches it (the pixel's qe is then external, "
            "surface reflection included); else the silicon's index (≈ 4.3 at 470–560 nm): "
            "Fresnel into it, at the psf level single pass, traced at raytrace (use an internal "
            "qe)")
    raytrace_rel_error: float = param(
        0.01, lo=1e-3, hi=0.2,
        doc="relative standard error of each site's own-pixel entry at the raytrace level "
            "(sets its rays); 0.1 % (≈ 1e7 rays per site) … 20 %")
    raytrace_seed: int = param(
        0, kind=int, lo=0, hi=2**63 - 1,
        doc="seed of the raytrace level's rays: the matrix estimates the geometry, the same for "
            "every scenario.seed (a study's replicates share it; cached per geometry and seed)")
    walls: str = param(
        "none", choices=("none", "absorbing", "reflecting"),
        doc="well walls at the raytrace level (a square well of well_side_um around each site)")
    well_side_um: float = param(0.0, lo=0.0, hi=LENGTH_MAX_UM,
                                doc="µm; the well's side with walls; " + LENGTHS)
    faceplate: FaceplateSection = field(default_factory=FaceplateSection)
    top: TopSection = field(default_factory=TopSection)

    @property
    def law(self) -> str:
        """The emitter's angular law in force: ``emitter``, else ``convention``."""
        return self.emitter or self.convention

    @property
    def closed_form_convention(self) -> str:
        """The one-medium closed forms' convention of :attr:`law` (``chiptwin.optics``): a
        Lambertian emitter into a cone of half-angle θ is sin²θ = NA², the paper's convention."""
        return "isotropic" if self.law == "isotropic" else "lambertian_na2"

    @property
    def stated_stack(self) -> bool:
        """True when the scenario states more than one medium: layers, a faceplate, the
        silicon's index or a top that returns light (the psf level then goes through
        :func:`chiptwin.optics.coupling_stack`)."""
        return (bool(self.layers) or self.faceplate.present or self.silicon_n > 0.0
                or self.top.present)


@dataclass(frozen=True)
class Fidelity:
    """``[run.fidelity]``: the level of each stage (the fidelity ladder).

    ``"auto"`` picks the cheapest level whose error on the scene stays within ``[run]
    error_budget`` (:mod:`chiptwin.fidelity.auto`).
    """

    kinetics: str = param("closed_form", choices=("closed_form", "cascade", "auto"))
    photons: str = param("binned", choices=("expected", "binned", "events", "auto"))
    optics: str = param("psf", choices=("na2", "psf", "raytrace", "auto"))
    shot: str = param(
        "poisson", choices=("poisson", "gaussian", "auto"),
        doc="photon shot noise of the binned level: exact Poisson counts, or a normal of the "
            "same mean and variance (faster; wrong for dim pixels)")
    dsp: str = param("", choices=("", "float", "fixed", "rtl", "auto"),
                     doc='"" = [chip.dsp] mode')
    adc: str = param(
        "as_built", choices=("ideal", "as_built", "auto"),
        doc='the converter: "as_built" = [chip.adc] as configured (the ideal rounding ADC when '
            'no effect is set), "ideal" = every as-built effect zeroed')

    def auto_stages(self) -> tuple[str, ...]:
        """The stages set to ``"auto"``."""
        return tuple(f.name for f in fields(self) if getattr(self, f.name) == "auto")


#: What ``[run] error_budget`` may bound, each against the reference combination of levels.
BUDGET_FIGURES = {
    "snr_rel": "relative error of each site's power SNR S²/N² (eq. 22; the amplitude SNR's "
               "relative error is about half of it)",
    "snr_db": "error of each site's power SNR in dB",
    "signal_rel": "relative error of each site's signal",
    "noise_rel": "relative error of each site's noise",
    "flow_value_abs": "absolute error of each pyrosequencing flow value (bases)",
    "dsp_lsb": "error of the DSP's outputs in LSB",
}


@dataclass(frozen=True)
class ErrorBudget:
    """``[run] error_budget``: the error ``auto`` fidelity may spend, per headline figure.

    A figure not set is not budgeted. Errors are against the most faithful levels (the ladder's
    reference), as an upper estimate on this scene (the analytic bound, or a calibration run's
    measured error plus its uncertainty).
    """

    snr_rel: float | None = param(None, lo=0.0, hi=1.0, doc=BUDGET_FIGURES["snr_rel"])
    snr_db: float | None = param(None, lo=0.0, hi=20.0, doc=BUDGET_FIGURES["snr_db"])
    signal_rel: float | None = param(None, lo=0.0, hi=1.0, doc=BUDGET_FIGURES["signal_rel"])
    noise_rel: float | None = param(None, lo=0.0, hi=1.0, doc=BUDGET_FIGURES["noise_rel"])
    flow_value_abs: float | None = param(None, lo=0.0, hi=1.0,
                                         doc=BUDGET_FIGURES["flow_value_abs"])
    dsp_lsb: float | None = param(None, lo=0.0, hi=2.0**20, doc=BUDGET_FIGURES["dsp_lsb"])

    def items(self) -> dict[str, float]:
        """The budgeted figures and their tolerances."""
        return {f.name: getattr(self, f.name) for f in fields(self)
                if getattr(self, f.name) is not None}


@dataclass(frozen=True)
class Run:
    """``[run]``: how long to run and at which fidelity."""

    duration_s: float = param(lo=T_MIN, hi=T_MAX, doc="s of chip time; " + TIMES)
    detection_snr_power: float = param(
        10.0, lo=1e-6, hi=1e12,
        doc="power SNR (eq. 22) above which a site is detected (one-sided: a positive signal "
            "whose amplitude SNR reaches its square root); 1e-6 (−60 dB) … 1e12 (120 dB, "
            "beyond any sensor's dynamic range)"
    )
    light_estimator: str = param(
        "sum", choices=("sum", "matched"),
        doc="window total: plain sum of DSP outputs, or the matched filter for the assay's "
            "exponential decay (pyrosequencing k_a, ATP turnover)")
    save_frames: bool = param(
        False, kind=bool,
        doc="keep every frame as read: the variable frames of run.nc in the output folder "
            "(streamed to a temporary file during the run, never held)")
    beside_physical_law: bool = param(
        True, kind=bool,
        doc="under the paper's lambertian_na2 convention: also run the scene with isotropic "
            "emitters at the expected level and report the signal and power-SNR ratios "
            "(chiptwin.twin.physical_law; skipped when estimated above 5 s)")
    carry_dark_pixels: bool = param(
        False, kind=bool,
        doc="binned level: carry pixels that see no site light (≤ 0.1 of their noise) at the "
            "expected level instead of drawing them (chiptwin.twin.shortcuts; same law, other "
            "draws)")
    max_wall_s: float = param(
        3600.0, lo=1.0, hi=1e7,
        doc="s of wall time a run may be estimated at (chiptwin.config.cost) before it is "
            "refused; default 1 hour (CHOICE: an interactive run; a longer one is asked for)")
    tile: str | int = param(
        "off", kind=(str, int), lo=1, hi=4096,
        doc='"off"; "auto"; or a tile side in pixels, a multiple of the site pitch, 1 … 4096 '
            "(the largest array): a periodic site layout run as 9 tiles (4 corners, 4 edges, "
            "the interior) with every neighbour's light, its figures scaled to the array "
            '(chiptwin.twin.tile; "auto" runs the whole array where the layout is not '
            "periodic, a size refuses it)")
    fidelity: Fidelity = field(default_factory=Fidelity)
    error_budget: ErrorBudget = field(default_factory=ErrorBudget)


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


__all__ = [
    "ADC_EFFECTS",
    "AMOL_MAX",
    "AMOL_MIN",
    "AMOUNTS",
    "ASSAY_KIND_KEYS",
    "Adc",
    "Assay",
    "CLOCKS",
    "CLOCK_MAX_HZ",
    "CLOCK_MIN_HZ",
    "Chip",
    "Dsp",
    "ErrorBudget",
    "FMOL_MAX",
    "FMOL_MIN",
    "FaceplateSection",
    "Fidelity",
    "LENGTHS",
    "LENGTH_MAX_UM",
    "LENGTH_MIN_UM",
    "Memory",
    "Optics",
    "Pixel",
    "RATES",
    "RATE_MAX",
    "RATE_MIN",
    "Run",
    "Scenario",
    "ScenarioMeta",
    "Sites",
    "TEMPS",
    "TEMP_MAX_C",
    "TEMP_MIN_C",
    "TIMES",
    "T_MAX",
    "T_MIN",
    "Timing",
    "TopSection",
    "VOLTS",
    "VOLT_MAX",
]
