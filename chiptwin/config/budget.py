"""What a run would hold and draw, checked before it starts: values in range, too large together.

Three budgets, each refused with :class:`ScenarioError` naming the keys that make it too large and
the limit (exit 2 from the CLI, an ``invalid`` point in a study):

* **memory** — an estimate of the peak a run holds (:func:`memory_estimate`), term by term from
  what :mod:`chiptwin.twin.runner`, :mod:`chiptwin.twin.scene`, :mod:`chiptwin.chip.des` and
  :mod:`chiptwin.twin.results` keep, against :func:`memory_budget_bytes` (8 GiB by default, a third
  of the 24 GiB machine the twin is developed on, so two study workers fit beside the system;
  ``CHIPTWIN_MEMORY_BUDGET_GIB`` changes it);
* **counts** — the largest Poisson mean a sampler is handed, the expected charge of one pixel in
  one frame (:func:`max_pixel_charge_e`), against NumPy's :data:`POISSON_LAM_MAX` (≈ 9.2e18; its
  sampler refuses more, and the count would not fit an int64);
* **chip time** — the chip model's event times are integer nanosecond ticks stored as int64: the
  DSP's work over the run (it goes on after the last frame when the DSP is slow) must fit in
  :data:`~chiptwin.constants.MAX_TIME_S`, as any time a scenario gives does;
and beside them, in :mod:`chiptwin.config.cost` (over this module), the run's estimated wall
time against ``[run] max_wall_s``.

The per-unit byte counts are measured peaks of ``chiptwin run`` (RSS and ``tracemalloc``) with a
margin; ``tests/config/test_budget.py`` checks that the estimate stays above measured runs of
several shapes, so a change in what a run holds shows up there.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from chiptwin.config.fields import ScenarioError
from chiptwin.config.schema import Scenario
from chiptwin.constants import MAX_TIME_S, N_A, Q_E, ZERO_C_K, s_to_ticks
from chiptwin.limits import (
    COUPLING_DROP_RTOL,
    POISSON_LAM_MAX,
    coupling_is_dense,
    frames_per_block,
)
from chiptwin.pixel.frames import code_dtype

#: Peak of the stack psf (``chiptwin.optics.coupling_stack``'s tabulated radial profile, its disc
#: convolution and quadrature temporaries), per emitter law of ``summary['optics']``: measured
#: 35 MiB (tracemalloc) for pyro_1fmol's two-layer stack with its 20 µm disc, 18 MiB for
#: crosstalk_microarray and jssc2006_faceplate; one run makes them one after the other. Unit: B.
STACK_PSF_BYTES: int = 48 << 20
#: Bytes of per-frame pixel moments a scene keeps for its replicates: below this the expected charge
#: and CMS moments of every pixel in every frame (3 float64 arrays, n_frames × n_pixels) are
#: computed once and shared; above it (a large array, a long run) they are computed a block of
#: frames at a time as the chip model reaches them and then dropped, so memory stays flat in frames
#: (``chiptwin.twin.scene``; the wall-time estimate charges the kept ones to the scene).
MOMENTS_KEPT_BYTES: int = 48 << 20


def moments_kept(n_pixels: int, n_frames: int) -> bool:
    """Whether a scene keeps every frame's pixel moments for its replicates."""
    return 3 * 8 * n_pixels * n_frames <= MOMENTS_KEPT_BYTES


#: The converter-as-built's quadrature (a transition table, the range's ends, white
#: noise below the series' floor): its slices of ``QUAD_SLICE_VALUES`` node values
#: (chiptwin.pixel.expected_adc), float64, this many arrays at once: measured 83 MiB
#: (tracemalloc, pyro_1fmol with 0.2 LSB of DNL against without) = 10.4 arrays of 8 MiB.
QUADRATURE_ARRAYS: int = 12

#: Default memory budget of one run. Unit: GiB.
MEMORY_BUDGET_GIB: float = 8.0

#: Environment variable that replaces :data:`MEMORY_BUDGET_GIB` (a positive number of GiB).
MEMORY_BUDGET_ENV: str = "CHIPTWIN_MEMORY_BUDGET_GIB"


# Bytes per unit of a run, measured on chiptwin run (peak RSS, 2-core machine) and rounded up.
#: The interpreter with numpy, numba, simpy and matplotlib loaded (260 MB RSS for pyro_1fmol).
BASE_BYTES: int = 384 << 20
#: Per frame: ≈ 7 trace events and 2 memory-occupancy entries as Python tuples, the simpy events,
#: the trace's arrays in the run's dataset, the light-curve plot (measured 2.4 kB per frame on 1e5
#: frames).
FRAME_BYTES: int = 3072
#: Per site and frame: the light table (two window edges per frame, float64), the DSP outputs
#: kept at the site pixels (value, mean, variance per output frame), the summary's arrays
#: (measured: 16–20 B for the light table).
SITE_FRAME_BYTES: int = 48
#: Per pixel, besides held frames: PRNU/DSNU maps, dark reference, the brightest output frame,
#: block-moment temporaries (measured ≤ 450 B per pixel beyond the held frames).
PIXEL_BYTES: int = 1024
#: Per pixel of one frame held (waiting in the frame memory or in the block being made), plus
#: its 2M ADC codes (2 B each up to 16 bits, else 4: :func:`chiptwin.pixel.frames.code_dtype`):
#: its expected CMS mean and variance (float64). A DSP job
#: stacks its frames' codes besides, ``(3M + 1) · 8`` B per pixel-frame (twice at fixed point).
HELD_PIXEL_FRAME_BYTES: int = 32
#: Per entry of a dense coupling matrix made by the psf level (offsets, their deduplication and
#: the matrix: a 97 B per entry peak measured for 64 × 64 pixels × 4,096 sites).
DENSE_COUPLING_BYTES: int = 104
#: Per entry of a sparse coupling (its COO triplets, the mask and the CSR matrix).
SPARSE_COUPLING_BYTES: int = 64
#: Safety factor on the whole estimate.
MARGIN: float = 1.25

#: Largest footprint radius, in heights above the diode, the psf level's quadrature (≤ 256
#: nodes per dimension) is allowed: it converges to 1e-6 up to ≈ 35 heights for every diode size
#: tried (at 50 a 10 µm diode under a 125 µm footprint fails); 25 leaves a margin.
FOOTPRINT_PER_HEIGHT_MAX: float = 25.0

#: Largest faceplate fibre pitch, in the diode's smaller side, the psf level's box-blur quadrature
#: is allowed. Measured per coupling (NA 1.0, 10 µm of solution, a point or a 5–20 µm disc site,
#: 12, 30 and 100 µm diodes): at a quarter of the side ≤ 0.7 s, at half 3–4 s, at one side
#: 3–4 s (12 µm), at two sides 43 s, at 80–120 % of a 100 µm diode 30 s and at 1 mm beyond ten
#: minutes: the blurred diode edge needs nodes as the fibre widens.
FIBER_PER_DIODE_MAX: float = 0.5

GIB = float(1 << 30)


def check_budget(s: Scenario) -> None:
    """Refuse a scenario whose run cannot work: too much memory, too many counts, too long."""
    _counts(s)
    _memory(s)
    _chip_time(s)


def _fail(s: Scenario, key: str, value: object, allowed: str) -> None:
    raise ScenarioError(s.source, key, value, allowed)


# --- counts ---------------------------------------------------------------------------------------


def _lognormal_max(cv: float, n: int) -> float:
    """Largest of ``n`` unit-mean lognormal draws of CV ``cv`` (the PRNU/DSNU maps), bounded:
    never above ``n`` (the maps are divided by their mean) nor, in practice, 8σ above the mean."""
    sigma = math.sqrt(math.log1p(cv * cv))
    return min(float(n), 1.1 * math.exp(8.0 * sigma))


def amount_key(s: Scenario) -> str:
    """The ``[assay]`` key that scales the light of every site."""
    return {"pyrosequencing": "dna_fmol", "atp": "atp_fmol", "luciferase_label": "luciferase_amol",
            "substrate": "substrate_amol", "catalyst": "enzyme_amol",
            "flux": "photons_per_s_per_um2"}[s.assay.kind]


def max_site_photons(s: Scenario) -> float:
    """An upper bound on the photons one site emits (flux: falling on its diode) in one
    integration window, from the closed forms of Salama et al. 2004 (eqs. 5–19). Unit: photons.

    Every source is a sum of pulses ``A·e^{−k t}``; a window of ``t_int`` gets at most
    ``min(A·t_int, A/k)`` of each (the cascade level emits the same photons per incorporation).
    """
    a, t = s.assay, s.chip.timing.t_int_s
    fmol, amol, alpha = 1e-15 * N_A, 1e-18 * N_A, a.quantum_yield
    if a.kind == "pyrosequencing":
        y = a.photons_per_incorporation or alpha * a.k_t_per_s / a.k_a_per_s
        window = 1.0 if s.run.fidelity.kinetics == "cascade" else min(1.0, a.k_a_per_s * t)
        return a.dna_fmol * fmol * y * len(a.template) * window
    if a.kind == "atp":
        return a.atp_fmol * fmol * alpha * min(1.0, a.turnover_per_s * t)
    if a.kind == "luciferase_label":
        return a.luciferase_amol * amol * alpha * a.turnover_per_s * t
    if a.kind == "substrate":
        return a.substrate_amol * amol * alpha * min(1.0, a.k_f_per_M_per_s * a.enzyme_M * t)
    if a.kind == "catalyst":
        return a.enzyme_amol * amol * alpha * a.k_f_per_M_per_s * a.substrate_max_M * t
    return a.photons_per_s_per_um2 * s.chip.pixel.diode_w_um * s.chip.pixel.diode_h_um * t


def max_dark_e(s: Scenario) -> float:
    """An upper bound on the dark charge of one pixel in one frame (hottest pixel). Unit: e⁻."""
    px = s.chip.pixel
    amps = px.dark_current_nA_per_cm2 * 1e-9 * px.diode_w_um * px.diode_h_um * 1e-8
    per_s = amps / Q_E * 2.0 ** ((px.temperature_C - px.ref_temp_C) / px.dark_doubling_C)
    return per_s * _lognormal_max(px.dsnu_frac, s.chip.n_pixels) * s.chip.timing.t_int_s


def max_pixel_charge_e(s: Scenario) -> tuple[float, float]:
    """Upper bounds on the light and dark charge one pixel expects in one frame: the mean its
    Poisson draw gets. Unit: e⁻.

    Sites sit one per pixel centre, so the shares of all sites' light on one pixel add up to at
    most what one site puts on the whole (infinite) array: a pixel gets at most one site's
    photons times :func:`max_coupling`.
    """
    px = s.chip.pixel
    light = (px.qe * _lognormal_max(px.prnu_frac, s.chip.n_pixels) * max_site_photons(s)
             * max_coupling(s))
    return light, max_dark_e(s)


def max_coupling(s: Scenario) -> float:
    """The largest share of a site's photons one pixel gets: the transmission times what the
    optics deliver to a plane (contact) or collect (lens); 1 for light given at the diode."""
    from chiptwin import optics

    o = s.optics
    if s.assay.kind == "flux":
        return 1.0
    if o.coupling == "lens":
        eff = optics.collection_efficiency(o.aperture_diameter_um, o.object_distance_um,
                                           convention=o.closed_form_convention)
        return float(eff) * o.transmission
    return optics.plane_fraction(o.closed_form_convention) * o.transmission


def film_bound(s: Scenario) -> tuple[int, int]:
    """At most how many thin-film groups the scene's stack has, and the band's wavelength nodes
    they ask together (``chiptwin.optics.layers.Stack.ray_path``, ``Band.node_count``): every
    layer below the first of at most ``optics.thin_film_um`` counted as its own group, the last
    only where an interface lies below it (the silicon, ``optics.silicon_n > 0``, or a
    faceplate's cores, ``core_n``), as ``chiptwin.optics.stack_psf.receiving_stack`` makes it
    inner. ``(0, 0)`` without films."""
    o = s.optics
    if not o.layers or o.thin_film_um <= 0:
        return 0, 0
    from chiptwin.optics.layers import Band, Layer

    below = o.silicon_n > 0 or (o.faceplate.present and o.faceplate.core_n > 0)
    inner = o.layers[1:] if below else o.layers[1:-1]
    films = [Layer("film", float(t["n"]), float(t["thickness_um"]))
             for t in inner if float(t["thickness_um"]) <= o.thin_film_um]
    if not films:
        return 0, 0
    edge = Layer("edge", 1.0, 0.0)
    return len(films), Band(o.wavelength_nm, o.band_fwhm_nm).node_count((edge, *films, edge))


def _film_table_bytes(s: Scenario) -> int:
    """An upper bound of the raytrace level's film tables (``chiptwin.optics.raytrace``):
    :func:`film_bound`'s groups and nodes, 2 directions × 2 polarisations × R|T ×
    ``FILM_COS_NODES`` float64, plus the transfer matrices' ≈ 32 complex temporaries of
    ``thinfilm.CHUNK`` values. 0 below the raytrace level or without films. Measured: 12.7 MiB
    traced for 0.1 µm of nitride, 75 MiB for 10 µm of index 4.5 (874 wavelengths)."""
    groups, nodes = film_bound(s)
    if s.run.fidelity.optics != "raytrace" or not groups:
        return 0
    from chiptwin.optics.raytrace import FILM_COS_NODES
    from chiptwin.optics.thinfilm import CHUNK

    return groups * 8 * nodes * FILM_COS_NODES * 8 + 32 * CHUNK * 16


#: Time a traced ray takes under a top that returns light, against none: the returned rays go
#: down the stack again, and some bounce between the top and the stack. Measured on the
#: pyro_1fmol stack (2 M rays, a 50 µm top): 4.4 M rays/s without, 2.2 under air, 1.6 under a
#: 170 µm lid; over silicon (n 4.3) 3.4 against 1.5 and 1.4. The largest ratio, rounded up.
TOP_RAY_COST: dict[str, float] = {"solution": 1.0, "air": 2.5, "glass": 3.0}


def raytrace_rays_estimate(s: Scenario) -> float:
    """Rays the raytrace level traces for this scene (pilot included), from the one-medium
    closed form of the own pixel's share (times the faceplate's acceptance and open area): the
    rule ``N = (1 − p)/(p·rel²)`` of :func:`chiptwin.optics.raytrace.rays_for_error` per site."""
    from chiptwin import optics
    from chiptwin.optics.raytrace import PILOT_RAYS

    o, px = s.optics, s.chip.pixel
    hw, hh = 0.5 * px.diode_w_um, 0.5 * px.diode_h_um
    p = float(optics.point_rectangle_fraction(-hw, hw, -hh, hh, s.sites.height_um,
                                              convention=o.closed_form_convention))
    if o.faceplate.present:
        n_top = float(o.layers[0]["n"]) if o.layers else 1.33
        p *= o.faceplate.open_area_ratio * min(1.0, o.faceplate.na / n_top) ** 2
    p = min(max(p, 1e-12), 1.0)
    rel = o.raytrace_rel_error
    sites = 1 if not coupling_is_dense(s.chip.n_pixels, n_sites(s)) else n_sites(s)
    return sites * ((1.0 - p) / (p * rel * rel) + PILOT_RAYS)


def _counts(s: Scenario) -> None:
    light, dark = max_pixel_charge_e(s)
    if light + dark <= POISSON_LAM_MAX:
        return
    t_int = s.chip.timing.t_int_s
    if light >= dark:
        key = "assay." + amount_key(s)
        others = {"pyrosequencing": "assay.photons_per_incorporation (or k_t/k_a), the template's "
                                    "length, chip.pixel.qe",
                  "flux": "chip.pixel.diode_w_um/diode_h_um"}.get(
            s.assay.kind, "the assay's rate constants, chip.pixel.qe")
        why = f"light ≈ {light:.3g} e⁻ in one {t_int:g} s frame"
        fix = f"lower it, {others} or chip.timing.t_int_s"
    else:
        key = "chip.pixel.dark_current_nA_per_cm2"
        why = (f"dark charge ≈ {dark:.3g} e⁻ in one {t_int:g} s frame (hottest pixel, "
               f"temperature_C {s.chip.pixel.temperature_C:g})")
        fix = "lower it, chip.pixel.temperature_C, the diode area or chip.timing.t_int_s"
    _fail(s, key, getattr(s.assay, amount_key(s)) if light >= dark else
          s.chip.pixel.dark_current_nA_per_cm2,
          f"gives a pixel up to {why}: the Poisson sampler takes means ≤ {POISSON_LAM_MAX:.3g} "
          f"e⁻; {fix}")


# --- chip time ------------------------------------------------------------------------------------


def _chip_time(s: Scenario) -> None:
    """The DSP works through every stored frame: its work must fit in MAX_TIME_S."""
    c = s.chip
    dsp_s = c.n_pixels * c.samples_per_frame * c.dsp.cycles_per_sample / c.dsp.clock_hz
    frames = s_to_ticks(s.run.duration_s) // s_to_ticks(c.timing.frame_period_s)
    if frames * dsp_s > MAX_TIME_S:
        _fail(s, "chip.dsp.cycles_per_sample", c.dsp.cycles_per_sample,
              f"with chip.dsp.clock_hz = {c.dsp.clock_hz:g} Hz the DSP takes {dsp_s:.3g} s per "
              f"frame, {frames * dsp_s:.3g} s for the run's {frames} frames: must be ≤ "
              f"{MAX_TIME_S:g} s, the longest time the chip model runs; make the DSP faster or "
              "the run shorter")


# --- memory ---------------------------------------------------------------------------------------


@dataclass(frozen=True)
class MemoryTerm:
    """One term of the estimate: what it is, its bytes, and the keys that set its size."""

    what: str
    bytes: float
    keys: str


def memory_budget_bytes() -> float:
    """The budget one run may use: ``CHIPTWIN_MEMORY_BUDGET_GIB`` or :data:`MEMORY_BUDGET_GIB`.

    Unit: bytes.
    """
    text = os.environ.get(MEMORY_BUDGET_ENV, "")
    try:
        gib = float(text) if text else MEMORY_BUDGET_GIB
    except ValueError:
        gib = math.nan
    if not (math.isfinite(gib) and gib > 0):
        raise ScenarioError("(environment)", MEMORY_BUDGET_ENV, text,
                            "must be a positive number of GiB")
    return gib * GIB


def n_sites(s: Scenario) -> int:
    at = s.sites.at_pixels
    return s.chip.n_pixels if at == "all" else 1 if at == "centre" else len(at)


def frames_held(s: Scenario, n_frames: int) -> int:
    """Frames whose codes and moments are alive at once: the block being made plus what the frame
    memory holds (a DSP that keeps up frees a block as the next arrives; one that cannot lets the
    memory fill)."""
    c = s.chip
    block = frames_per_block(c.n_pixels, c.dsp.cms_samples)
    memory = max(0, (c.memory.capacity_bits - c.memory.word_bits * c.n_pixels) // c.frame_bits)
    dsp_s = c.n_pixels * c.samples_per_frame * c.dsp.cycles_per_sample / c.dsp.clock_hz
    if dsp_s <= c.timing.frame_period_s:
        memory = min(memory, c.dsp.n_dark_frames + 2 * c.dsp.average_frames)
    return min(n_frames, block + memory)


def _kernel_radius(s: Scenario) -> int:
    """Pixels out to which the sparse coupling keeps a site's light (the doubling search of
    ``chiptwin.twin.stages._sparse_coupling``, on a point at the footprint's nearest edge: never
    smaller than the one it makes). A top that returns light adds, as a bound, an isotropic image
    source ``2 · solution_depth_um`` above the site putting all its lower half on the plane
    (the top returns at most the upper half of the light)."""
    if s.assay.kind == "flux" or s.optics.coupling == "lens":
        return 0
    from chiptwin.optics.psf import point_rectangle_fraction

    c, px = s.chip, s.chip.pixel
    hw, hh = 0.5 * px.diode_w_um, 0.5 * px.diode_h_um
    image_um = s.sites.height_um + 2.0 * s.optics.top.solution_depth_um

    def share(offset_um: float) -> float:
        x = max(offset_um, 0.0)
        direct = float(point_rectangle_fraction(x - hw, x + hw, -hh, hh, s.sites.height_um,
                                                convention=s.optics.closed_form_convention))
        if not s.optics.top.present:
            return direct
        return direct + float(point_rectangle_fraction(x - hw, x + hw, -hh, hh, image_um,
                                                       convention="isotropic"))

    centre, radius = share(0.0), 2
    while share(radius * c.pitch_um - s.sites.footprint_radius_um) >= (
            COUPLING_DROP_RTOL * centre) and 2 * radius + 1 <= max(c.rows, c.cols):
        radius *= 2
    return radius


@dataclass(frozen=True)
class Quadrature:
    """How :mod:`chiptwin.pixel.expected_adc` takes a scene's converter-as-built moments by its
    quadrature: ``nodes`` a pixel-frame and pass, the white rms ``u`` (LSB) whose ±10 ``u``
    window of codes each node sums, ``table`` (a transition table: always the window; else from
    ``END_CLOSED_FROM_LSB`` of ``u`` the ends' closed form instead)."""

    nodes: int
    u: float
    table: bool


def _lsb_per_volt(s: Scenario) -> float:
    """A volt at the converter's input, in LSB (its gain error included)."""
    a = s.chip.adc
    return (1.0 + a.gain_error) / ((a.v_max_V - a.v_min_V) / 2**a.bits)


def _lsb_per_electron(s: Scenario) -> float:
    """A pixel electron at the converter, through the conversion gain and the gain error."""
    from chiptwin.pixel.sensor import conversion_gain_uV_per_e

    return conversion_gain_uV_per_e(s.chip.pixel.capacitance_fF) * 1e-6 * _lsb_per_volt(s)


def as_built_white_lsb(s: Scenario) -> float:
    """The white noise at the converter (read noise and comparator noise, rms): what dithers its
    codes, and sets the series' harmonics or the quadrature's grid. Unit: LSB."""
    return math.hypot(s.chip.pixel.read_noise_e * _lsb_per_electron(s),
                      s.chip.adc.comparator_noise_total_lsb)


def as_built_quadrature(s: Scenario) -> Quadrature | None:
    """The quadrature of ``s``'s converter as built, or None where none runs (no ``[chip.adc]``
    effect, or the sawtooth's series answers every pixel-frame). The quadrature when the converter
    has a transition table, its white noise (read + comparator) is below the series' floor, or
    the dark level sits within ``10 (u + kTC)`` of code 0 (every dark pixel-frame then leaves the
    series: ccd_two_wells with a 128-LSB comparator, its pedestal at code 1,311); a smooth INL bow
    without DNL stays on the series where its curvature allows (``SMOOTH_INL_TOL``); its nodes by
    the kTC's ratio to ``u`` (:func:`~chiptwin.pixel.expected_adc.node_count`)."""
    from chiptwin.pixel.expected_adc import SERIES_MIN_WHITE_LSB, SMOOTH_INL_TOL, node_count
    from chiptwin.pixel.ramp import AsBuilt, bow_curvature
    from chiptwin.pixel.sensor import ktc_noise_e

    a, p = s.chip.adc, s.chip.pixel
    if not a.as_built_keys:
        return None
    u = as_built_white_lsb(s)
    ktc = ktc_noise_e(p.capacitance_fF, p.temperature_C + ZERO_C_K) * _lsb_per_electron(s)
    dark = (p.pedestal_V - a.v_min_V) * _lsb_per_volt(s) + a.offset_error_lsb
    spec = AsBuilt.from_keys(a)
    smooth = (spec.inl_shape != "table" and spec.dnl_rms_lsb == 0.0
              and bow_curvature(spec.inl_max_lsb, spec.inl_shape, a.bits) * (u + ktc) ** 2
              <= SMOOTH_INL_TOL)
    table = spec.shaped and not smooth
    if table or u < SERIES_MIN_WHITE_LSB or dark - 10.0 * (u + ktc) - abs(spec.inl_max_lsb) < 0.5:
        return Quadrature(node_count(ktc, u), u, table)
    return None


def memory_estimate(s: Scenario) -> list[MemoryTerm]:
    """The peak a run of ``s`` holds, term by term (before :data:`MARGIN`). Unit: bytes."""
    c = s.chip
    frames = s_to_ticks(s.run.duration_s) // s_to_ticks(c.timing.frame_period_s)
    pixels, sites = c.n_pixels, n_sites(s)
    size = "chip.rows × chip.cols"
    length = "run.duration_s / chip.timing.frame_period_s"
    flux_twice = 2 if s.assay.kind == "flux" else 1  # the required flux reruns the chip model
    terms = [
        MemoryTerm("interpreter and libraries", BASE_BYTES, ""),
        MemoryTerm(f"{frames} frames × {FRAME_BYTES} B (event trace, memory occupancy)",
                   flux_twice * frames * FRAME_BYTES, length),
        MemoryTerm(f"{sites} sites × {frames} frames × {SITE_FRAME_BYTES} B (light per site, "
                   "DSP outputs at the sites)", sites * frames * SITE_FRAME_BYTES,
                   f"sites.at_pixels, {length}"),
        MemoryTerm(f"{pixels} pixels × {PIXEL_BYTES} B (maps, dark reference)",
                   pixels * PIXEL_BYTES, size),
    ]
    held = frames_held(s, frames)
    per = np.dtype(code_dtype(c.adc.bits)).itemsize * c.samples_per_frame + HELD_PIXEL_FRAME_BYTES
    terms.append(MemoryTerm(f"{held} frames held × {pixels} pixels × {per} B (ADC codes and "
                            "moments)", held * pixels * per,
                            f"{size}, chip.dsp.cms_samples, chip.memory.capacity_bits"))
    job = min(frames, max(c.dsp.n_dark_frames, c.dsp.average_frames))
    stacked = 8 * (3 * c.dsp.cms_samples + 1) * (2 if s.dsp_level != "float" else 1)
    terms.append(MemoryTerm(f"the DSP's largest job, {job} frames × {pixels} pixels × {stacked} B "
                            "(codes stacked for CMS)", job * pixels * stacked,
                            f"chip.dsp.n_dark_frames, {size}, chip.dsp.cms_samples"))
    if as_built_quadrature(s) is not None:
        from chiptwin.pixel.expected_adc import QUAD_SLICE_VALUES

        terms.append(MemoryTerm(f"the converter-as-built quadrature's slices, "
                                f"{QUADRATURE_ARRAYS} × {QUAD_SLICE_VALUES} values × 8 B",
                                QUADRATURE_ARRAYS * QUAD_SLICE_VALUES * 8,
                                "chip.adc (" + ", ".join(c.adc.as_built_keys) + ")"))
    if s.assay.kind != "flux" and s.optics.coupling == "contact" and s.optics.stated_stack:
        terms.append(MemoryTerm("the stack psf's profile and quadrature (the psf level through "
                                "a stated stack, the summary's per-law figures)",
                                STACK_PSF_BYTES, "optics.layers"))
    films = _film_table_bytes(s)
    if films:
        terms.append(MemoryTerm("the raytrace level's thin-film tables (at most a group a film, "
                                "the band's nodes for all films together) and their transfer "
                                "matrices' temporaries", films,
                                "optics.layers, optics.thin_film_um, optics.band_fwhm_nm"))
    if coupling_is_dense(pixels, sites):
        terms.append(MemoryTerm(f"coupling {pixels} pixels × {sites} sites × "
                                f"{DENSE_COUPLING_BYTES} B", pixels * sites * DENSE_COUPLING_BYTES,
                                f"{size}, sites.at_pixels"))
    else:
        side = 2 * _kernel_radius(s) + 1
        kernel = side * side
        terms.append(MemoryTerm(
            f"sparse coupling {sites} sites × {min(kernel, pixels)} pixels each × "
            f"{SPARSE_COUPLING_BYTES} B, its {side}² kernel × {DENSE_COUPLING_BYTES} B",
            sites * min(kernel, pixels) * SPARSE_COUPLING_BYTES + kernel * DENSE_COUPLING_BYTES,
            f"sites.at_pixels, sites.height_um / chip.pitch_um, {size}"))
    return terms


def _memory(s: Scenario) -> None:
    terms = memory_estimate(s)
    total = MARGIN * sum(t.bytes for t in terms)
    budget = memory_budget_bytes()
    if total <= budget:
        return
    big = max(terms[1:], key=lambda t: t.bytes)
    first = big.keys.split(",")[0].split(" ")[0]
    value = _value_of(s, first)
    _fail(s, first, value,
          f"the run would hold ≈ {total / GIB:.3g} GiB, above the {budget / GIB:g} GiB budget "
          f"(environment variable {MEMORY_BUDGET_ENV}); most of it {big.what} = "
          f"{MARGIN * big.bytes / GIB:.3g} GiB: lower {big.keys}")


def _value_of(s: Scenario, key: str) -> object:
    obj: object = s
    for part in key.split("."):
        obj = getattr(obj, part, None)
    if key == "sites.at_pixels" and isinstance(obj, list):
        return f"[{len(obj)} sites]"
    return obj


def window_edges(s: Scenario) -> np.ndarray:
    """The assay's windows: a pyrosequencing run's flows, else [start, end of run]. Unit: s."""
    a = s.assay
    if a.kind == "pyrosequencing":
        return a.start_s + a.flow_period_s * np.arange(a.n_flows + 1)
    return np.array([a.start_s, s.run.duration_s])
