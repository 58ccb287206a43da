"""Thin adapters: unpack a :class:`Scenario` into the pure functions of each stage.

The physics lives in the stage packages as array functions with explicit arguments; this module is
the only place that knows both the scenario's field names and those functions' signatures.
"""

from __future__ import annotations

import functools
import math
import zlib
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from scipy import sparse

from chiptwin import kinetics, limits, optics, pixel
from chiptwin.config import Scenario
from chiptwin.config.budget import amount_key
from chiptwin.constants import ZERO_C_K
from chiptwin.kinetics import pyro
from chiptwin.kinetics.chemistry import FlowModel, flow_light
from chiptwin.kinetics.chemistry_presets import PRESET_KEYS
from chiptwin.kinetics.light_source import LightSource, Replicated
from chiptwin.kinetics.pulse_train import PulseTrain

FMOL, AMOL = 1e-15, 1e-18


def stage_rng(seed: int, stage: str) -> np.random.Generator:
    """The random stream of one stage: ``SeedSequence(seed)``'s child keyed by the stage's name
    (re-exported by :mod:`chiptwin.twin.scene`)."""
    key = zlib.crc32(stage.encode())
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(key,)))


def child_rng(rng: np.random.Generator, name: str) -> np.random.Generator:
    """A stream of its own under ``rng``'s seed, keyed ``crc32(name)`` (far above any chunk
    number :func:`chiptwin.pixel.chunk_streams` keys), made without advancing ``rng``."""
    ss = rng.bit_generator.seed_seq
    return np.random.default_rng(np.random.SeedSequence(
        ss.entropy, spawn_key=(*ss.spawn_key, zlib.crc32(name.encode())), pool_size=ss.pool_size))


def site_pixels(s: Scenario) -> np.ndarray:
    """(n_sites, 2) array of the [row, col] each site sits above."""
    at = s.sites.at_pixels
    if at == "all":
        return np.array([[r, c] for r in range(s.chip.rows) for c in range(s.chip.cols)])
    if at == "centre":
        return np.array([[s.chip.rows // 2, s.chip.cols // 2]])
    return np.array(at, dtype=np.int64).reshape(-1, 2)


def site_pixel_indices(s: Scenario) -> np.ndarray:
    """Index (row-major) of the pixel under each site."""
    rc = site_pixels(s)
    return rc[:, 0] * s.chip.cols + rc[:, 1]


def flow_program(s: Scenario) -> tuple[list[str], np.ndarray]:
    """Nucleotide and incorporations of each flow (pyrosequencing only)."""
    a = s.assay
    return pyro.flow_incorporations(a.template, a.flow_order, a.n_flows)


def expected_incorporations(s: Scenario) -> np.ndarray:
    """Mean bases added per starting strand in each flow (pyrosequencing): the flow program's
    counts, or with ``incomplete_extension``, ``carry_forward`` or ``droop_per_flow`` the phased,
    drooping flowgram (:func:`chiptwin.kinetics.phasing.phased_signal`; Eltoukhy & El Gamal,
    ICASSP 2006). Unit: incorporations per strand."""
    a = s.assay
    if not (a.incomplete_extension or a.carry_forward or a.droop_per_flow):
        return flow_program(s)[1]
    return kinetics.phased_signal(a.template, a.flow_order, a.n_flows,
                                  a.incomplete_extension, a.carry_forward, a.droop_per_flow)[0]


def flow_model(s: Scenario) -> FlowModel | None:
    """The scene's flow-value model (``[assay]`` flow_*, well_*, homopolymer_*, empty_flow_*
    keys, or a named chemistry's), or None when it changes no flow's light."""
    a = s.assay
    if a.kind != "pyrosequencing":
        return None
    model = FlowModel(**{k: getattr(a, k) for k in PRESET_KEYS})
    return model if model.active else None


def site_incorporations(s: Scenario, n: int) -> np.ndarray:
    """Each site's light per flow in incorporations per strand: the flowgram
    (:func:`expected_incorporations`) for every site, or with a flow-value model
    (:func:`chiptwin.kinetics.chemistry.flow_light`) each site's and flow's own, drawn from the
    run's ``flow_yield`` stream. Shape (n_flows,) or (n, n_flows)."""
    signal = expected_incorporations(s)
    model = flow_model(s)
    if model is None:
        return signal
    return flow_light(signal, flow_program(s)[1], model,
                      stage_rng(s.scenario.seed, "flow_yield"), n)


def site_copies(s: Scenario, n: int) -> np.ndarray:
    """Each site's DNA copies relative to ``dna_fmol``: 1, or with ``[assay] dna_cv`` a gamma
    draw of mean 1 and that coefficient of variation per site, from the run's ``dna_copies``
    stream (a new chip per seed). Clonal beads or wells vary in template load; a gamma law is
    the choice (positive, its CV a single number)."""
    cv = s.assay.dna_cv if s.assay.kind == "pyrosequencing" else 0.0
    if not cv:
        return np.ones(n)
    k = 1.0 / cv**2
    return stage_rng(s.scenario.seed, "dna_copies").gamma(k, 1.0 / k, size=n)


def light_source(s: Scenario) -> LightSource:
    """The light of every site. Unit: photons/s.

    ``closed_form``: Salama et al. 2004, eqs. 5–8, 12, 13, 19. ``cascade`` (pyrosequencing
    only): the multi-enzyme ODE (:mod:`chiptwin.kinetics.cascade`) in the paper's limit set by
    k_t and k_a; with a measured photon yield, the luciferase amount is fitted to give it.

    ``[sites] amounts_fmol`` gives each site its own amount (:func:`scale_source`: the closed
    forms are linear in it).

    The ``flux`` kind gives light at the sensor plane instead: photons/s on the diode under each
    site (flux × diode area), with :func:`coupling` passing it straight through.
    """
    n = len(site_pixels(s))
    if s.run.fidelity.kinetics == "cascade":
        return _cascade_source(s, n)
    if n > 1 and identical_sites(s):  # identical sites: shared
        return Replicated(_closed_form_source(s, 1), n)
    return scale_source(s, _closed_form_source(s, n))


def identical_sites(s: Scenario) -> bool:
    """Every site emits the same light (closed forms): no per-site amounts, DNA draws or
    flow-value model draws (a tiled run books a neighbour's light to the site standing for it,
    exact only then: :mod:`chiptwin.twin.tile`)."""
    return site_scale(s) is None and not s.assay.dna_cv and flow_model(s) is None


def assay_amount_fmol(s: Scenario) -> float:
    """The ``[assay]`` amount of the analyte (``dna_fmol``, ``atp_fmol``, ``luciferase_amol``, …)
    in fmol: the amount every site holds unless ``[sites] amounts_fmol`` says otherwise."""
    key = amount_key(s)
    return getattr(s.assay, key) * (1e-3 if key.endswith("_amol") else 1.0)


def site_amounts_fmol(s: Scenario, n_sites: int) -> np.ndarray:
    """Analyte per site, fmol: ``[sites] amounts_fmol``, or the ``[assay]`` amount at each."""
    if s.sites.amounts_fmol:
        return np.asarray(s.sites.amounts_fmol, dtype=np.float64)
    return np.full(n_sites, assay_amount_fmol(s))


def site_scale(s: Scenario) -> np.ndarray | None:
    """Each site's share of the ``[assay]`` amount's light, or None when every site holds it."""
    if not s.sites.amounts_fmol:
        return None
    return np.asarray(s.sites.amounts_fmol, dtype=np.float64) / assay_amount_fmol(s)


def scale_source(s: Scenario, source: LightSource) -> LightSource:
    """The light of each site scaled to its amount (``[sites] amounts_fmol``); ``source`` itself
    when every site holds the ``[assay]`` amount.

    The closed forms are sums of pulses ``A·e^{−k t}`` with ``A`` proportional to the analyte
    (eqs. 5–19), so scaling each pulse's amplitude is exact. (The cascade is not linear in the
    amount; :func:`chiptwin.config.consistency` refuses amounts with it.)
    """
    scale = site_scale(s)
    if scale is None:
        return source
    if not isinstance(source, PulseTrain):
        raise TypeError(f"per-site amounts scale closed-form light, not {type(source).__name__}")
    return PulseTrain(site=source.site, onset_s=source.onset_s,
                      amplitude_per_s=source.amplitude_per_s * scale[source.site],
                      decay_per_s=source.decay_per_s, n_sites=source.n_sites)


def _closed_form_source(s: Scenario, n: int) -> LightSource:
    """Every site with the ``[assay]`` amount (``[sites] amounts_fmol`` scales it after)."""
    a = s.assay
    if a.kind == "pyrosequencing":
        return kinetics.pyrosequencing(
            a.dna_fmol * FMOL * site_copies(s, n), site_incorporations(s, n), a.flow_period_s,
            start_s=a.start_s,
            turnover_per_s=a.k_t_per_s, apyrase_per_s=a.k_a_per_s, alpha=a.quantum_yield,
            photons_per_incorporation=a.photons_per_incorporation or None,
        )
    if a.kind == "atp":
        return kinetics.atp_assay(np.full(n, a.atp_fmol * FMOL), a.start_s,
                                  turnover_per_s=a.turnover_per_s, alpha=a.quantum_yield)
    if a.kind == "luciferase_label":
        return kinetics.luciferase_label(np.full(n, a.luciferase_amol * AMOL), a.start_s,
                                         turnover_per_s=a.turnover_per_s, alpha=a.quantum_yield)
    if a.kind == "substrate":
        return kinetics.substrate_detection(
            np.full(n, a.substrate_amol * AMOL), a.start_s, k_f_per_M_per_s=a.k_f_per_M_per_s,
            enzyme_M=a.enzyme_M, alpha=a.quantum_yield)
    if a.kind == "catalyst":
        return kinetics.catalyst_detection(
            np.full(n, a.enzyme_amol * AMOL), a.start_s, k_f_per_M_per_s=a.k_f_per_M_per_s,
            substrate_max_M=a.substrate_max_M, alpha=a.quantum_yield)
    area = s.chip.pixel.diode_w_um * s.chip.pixel.diode_h_um
    return PulseTrain(site=np.arange(n), onset_s=np.full(n, a.start_s),
                      amplitude_per_s=np.full(n, a.photons_per_s_per_um2 * area),
                      decay_per_s=np.zeros(n), n_sites=n)


@functools.lru_cache(maxsize=32)
def _fitted_yield(target: float, params: kinetics.CascadeParams,
                  dna_mol: float) -> kinetics.CascadeParams:
    """The cascade's parameters fitted to a measured photon yield, once per distinct input: a
    deterministic root search of ≈ 1 s that a ladder or a study would redo for every scene it
    prepares (the parameters are frozen, so they key the cache)."""
    return kinetics.fit_photon_yield(target, params, dna_mol=dna_mol).params


def _cascade_source(s: Scenario, n: int) -> LightSource:
    a = s.assay
    params = kinetics.CascadeParams.from_closed_form(a.k_t_per_s, a.k_a_per_s, a.quantum_yield)
    if a.photons_per_incorporation:
        params = _fitted_yield(a.photons_per_incorporation, params, a.dna_fmol * FMOL)
    if a.incomplete_extension or a.carry_forward:
        params = replace(params, incomplete_extension=a.incomplete_extension,
                         carry_forward=a.carry_forward)
    return kinetics.cascade_pyrosequencing(np.full(n, a.dna_fmol * FMOL), a.template,
                                           a.flow_order, a.n_flows, a.flow_period_s, a.start_s,
                                           params)


def coupling(s: Scenario) -> np.ndarray | sparse.csr_matrix:
    """(n_pixels, n_sites): the share of each site's emitted photons on each pixel's diode.

    Dense up to :data:`chiptwin.limits.DENSE_COUPLING_ENTRIES` entries and
    :data:`~chiptwin.limits.DENSE_COUPLING_PIXELS` pixels; above either, sparse
    (:func:`_sparse_coupling`).
    """
    rc = site_pixels(s)
    if not limits.coupling_is_dense(s.chip.n_pixels, len(rc)):
        return _sparse_coupling(s, rc)
    chip, o = s.chip, s.optics
    under = np.zeros((chip.n_pixels, len(rc)))
    under[rc[:, 0] * chip.cols + rc[:, 1], np.arange(len(rc))] = 1.0
    if s.assay.kind == "flux":
        return under
    if o.coupling == "lens":
        return under * _lens_efficiency(s)
    rows, cols = np.arange(chip.rows), np.arange(chip.cols)
    return _optics_grid(s, rows, cols, rc) * o.transmission


def _lens_efficiency(s: Scenario) -> float:
    o = s.optics
    eff = optics.collection_efficiency(o.aperture_diameter_um, o.object_distance_um,
                                       convention=o.closed_form_convention)
    return float(eff) * o.transmission


#: Index of the medium when a scenario states no layers (water/buffer at 560 nm, textbook;
#: sources.md O11): it enters nothing at na2 and psf (one medium: the index cancels), only the
#: raytrace level's silicon interface when ``silicon_n`` is given.
DEFAULT_MEDIUM_N = 1.33


def optics_stack(s: Scenario) -> optics.Stack:
    """The scenario's planar stack (:class:`chiptwin.optics.Stack`): ``[optics] layers`` (``k``
    as ``alpha_per_um = 4πk/λ``; a first layer without ``thickness_um`` fills the site height
    above the others and the faceplate), or one medium of ``sites.height_um``; the silicon's index
    ``silicon_n``, or (0: the diode plane absorbs all) the last layer's own index, so that no
    light is reflected there."""
    o = s.optics
    if o.layers:
        lam_um = o.wavelength_nm * 1e-3
        fp = o.faceplate.thickness_um if o.faceplate.present else 0.0
        fill = s.sites.height_um - fp - sum(float(t["thickness_um"]) for t in o.layers[1:])
        layers = tuple(optics.Layer(
            str(t.get("name", f"layer {i}")), float(t["n"]), float(t.get("thickness_um", fill)),
            float(t["alpha_per_um"]) if "alpha_per_um" in t else
            4.0 * math.pi * float(t.get("k", 0.0)) / lam_um) for i, t in enumerate(o.layers))
    else:
        layers = (optics.Layer("medium", DEFAULT_MEDIUM_N, s.sites.height_um),)
    return optics.Stack(layers, o.silicon_n or layers[-1].n, thin_film_um=o.thin_film_um,
                        band=optics.Band(o.wavelength_nm, o.band_fwhm_nm))


def optics_faceplate(s: Scenario) -> optics.Faceplate | None:
    """``[optics.faceplate]`` as a :class:`chiptwin.optics.Faceplate`, or None."""
    f = s.optics.faceplate
    if not f.present:
        return None
    return optics.Faceplate(na=f.na, fiber_pitch_um=f.fiber_pitch_um,
                            thickness_um=f.thickness_um, open_area_ratio=f.open_area_ratio,
                            core_n=f.core_n or None)


def optics_top(s: Scenario) -> optics.Top | None:
    """``[optics.top]`` as a :class:`chiptwin.optics.Top`, or None when nothing returns
    (``"solution"``: the coupling is bit for bit that of a scenario without the section)."""
    t = s.optics.top
    if not t.present:
        return None
    return optics.Top(medium=t.medium, solution_depth_um=t.solution_depth_um,
                      lid_n=t.lid_index, lid_thickness_um=t.lid_thickness_um)


def _grid(s: Scenario, rows: np.ndarray, cols: np.ndarray, rc: np.ndarray) -> dict:
    px = s.chip.pixel
    return dict(n_rows=len(rows), n_cols=len(cols), pitch_um=s.chip.pitch_um,
                diode_w_um=px.diode_w_um, diode_h_um=px.diode_h_um,
                site_x_um=(rc[:, 1] + 0.5) * s.chip.pitch_um,
                site_y_um=(rc[:, 0] + 0.5) * s.chip.pitch_um)


def _optics_grid(s: Scenario, rows: np.ndarray, cols: np.ndarray, rc: np.ndarray) -> np.ndarray:
    """The coupling of sites ``rc`` onto a ``len(rows) × len(cols)`` grid of pixels at the
    scenario's optics level: ``na2``; ``psf`` (today's one-medium closed form when the scenario
    states no stack, else through it: :func:`chiptwin.optics.coupling_stack`); ``raytrace``."""
    o, level = s.optics, s.run.fidelity.optics
    grid = _grid(s, rows, cols, rc)
    if level == "raytrace":
        return raytrace_result(s, grid).coupling
    if level == "na2":
        return optics.coupling_na2(**grid, height_um=s.sites.height_um,
                                   convention=o.closed_form_convention)
    if not o.stated_stack or o.law == "lambertian_na2":  # the convention: one medium
        return optics.coupling_psf(**grid, height_um=s.sites.height_um,
                                   convention=o.closed_form_convention,
                                   site_radius_um=s.sites.footprint_radius_um)
    c = optics.coupling_stack(**grid, stack=optics_stack(s), emitter=o.law,
                              faceplate=optics_faceplate(s), into_silicon=o.silicon_n > 0,
                              site_radius_um=s.sites.footprint_radius_um, top=optics_top(s))
    # the general path's corner sums leave ±1e-18 where no light lands (within its rtol): a
    # share of light is ≥ 0 (the closed form's, returned above, is untouched)
    return np.clip(c, 0.0, None)


def raytrace_result(s: Scenario, grid: dict | None = None):
    """The raytrace level's :class:`~chiptwin.optics.raytrace.RaytraceResult` of the scene's
    sites (``grid``: another grid of pixels and sites, as :func:`_optics_grid` makes). Its rays
    come from the stream ``"optics"`` of ``optics.raytrace_seed`` (not ``scenario.seed``: the
    matrix is an estimate of the geometry, shared by a study's replicates), cached per geometry
    and seed in ``$XDG_CACHE_HOME/chiptwin/raytrace``."""
    from chiptwin.optics.raytrace import raytrace

    o = s.optics
    if grid is None:
        rc = site_pixels(s)
        grid = _grid(s, np.arange(s.chip.rows), np.arange(s.chip.cols), rc)
    walls = {} if o.walls == "none" else dict(walls=o.walls, well_side_um=o.well_side_um)
    return raytrace(optics_stack(s), **grid, rng=stage_rng(o.raytrace_seed, "optics"),
                    site_radius_um=s.sites.footprint_radius_um, rel_error=o.raytrace_rel_error,
                    emitter=o.law, faceplate=optics_faceplate(s), cache_tag=o.raytrace_seed,
                    top=optics_top(s), **walls)


def _sparse_coupling(s: Scenario, rc: np.ndarray) -> sparse.csr_matrix:
    """The coupling as a CSR matrix, from one site's kernel shifted to every site.

    Every site sits at its pixel's centre at the same height with the same footprint, and a
    pixel's share depends only on where it is relative to the site, so one kernel, computed on
    a (2R + 1)² grid around a site, serves all (clipped at the array's edges, as the dense
    matrix is). R grows until the kernel's outer ring is below
    :data:`~chiptwin.limits.COUPLING_DROP_RTOL` of its centre (at most the array's size); the ring
    itself is then left out.
    """
    chip = s.chip
    kernel, radius = coupling_kernel(s)
    dr, dc = np.nonzero(kernel >= limits.COUPLING_DROP_RTOL * kernel[radius, radius])
    values = kernel[dr, dc]
    r = rc[:, :1] + (dr - radius)[None, :]
    c = rc[:, 1:] + (dc - radius)[None, :]
    inside = (r >= 0) & (r < chip.rows) & (c >= 0) & (c < chip.cols)
    site = np.broadcast_to(np.arange(len(rc))[:, None], r.shape)
    data = np.broadcast_to(values[None, :], r.shape)
    return sparse.csr_matrix((data[inside], ((r * chip.cols + c)[inside], site[inside])),
                             shape=(chip.n_pixels, len(rc)))


def coupling_kernel(s: Scenario, mirrored: bool = False) -> tuple[np.ndarray, int]:
    """One site's share of its photons on each pixel of a ``(2R + 1)²`` grid around it, and R.

    R grows (doubling from 2) until the kernel's outer ring is below
    :data:`~chiptwin.limits.COUPLING_DROP_RTOL` of its centre, or it covers every pixel-site
    offset of the array (R ≥ its rows and columns − 1; it stopped at half that before, leaving
    out the far light of a small array under a lid); light
    at the sensor (``flux``) and a lens have a kernel of one pixel. The shares include
    ``optics.transmission``. Pixels of the ring or beyond are what the sparse coupling leaves
    out (:func:`_sparse_coupling`).

    ``mirrored``: one quadrant (offsets 0 … R) computed and mirrored into the other three, a
    quarter of the work: the site sits at its pixel's centre over a diode centred in its pixel,
    so a share depends on the offsets' magnitudes only (equal to the whole grid's within
    rounding; tested). A tiled run's kernel (:mod:`chiptwin.twin.tile`); the whole array's
    sparse coupling keeps the whole grid's bits.
    """
    chip = s.chip
    if s.assay.kind == "flux" or s.optics.coupling == "lens":
        gain = 1.0 if s.assay.kind == "flux" else _lens_efficiency(s)
        return np.full((1, 1), gain), 0
    radius = 2
    while True:
        n = 2 * radius + 1
        if mirrored:
            q = _optics_grid(s, np.arange(radius + 1), np.arange(radius + 1),
                             np.array([[0, 0]])).reshape(radius + 1, radius + 1)
            k = np.concatenate([q[:0:-1], q])
            k = np.concatenate([k[:, :0:-1], k], axis=1)
        else:
            k = _optics_grid(s, np.arange(n), np.arange(n), np.array([[radius, radius]]))
        kernel = k.reshape(n, n) * s.optics.transmission
        ring = np.max(np.concatenate([kernel[0], kernel[-1], kernel[:, 0], kernel[:, -1]]))
        if (ring < limits.COUPLING_DROP_RTOL * kernel[radius, radius]
                or radius >= max(chip.rows, chip.cols) - 1):  # every offset in the array
            return kernel, radius
        radius *= 2


@dataclass(frozen=True)
class SensorModel:
    """Per-pixel constants of the sensor, resolved once per run (fixed pattern drawn here)."""

    qe: float
    gain_map: np.ndarray
    dark_e_per_s: np.ndarray
    full_well_e: float
    ktc_e: float
    read_noise_e: float
    cms_samples: int
    true_cds: bool
    conversion_gain_uV_per_e: float
    pedestal_V: float
    lsb_V: float
    e_per_lsb: float
    #: The per-pixel converters as built (:func:`converter`); ideal: today's rounding ADC.
    converter: pixel.Converter | None = None


def converter(s: Scenario, rng: np.random.Generator) -> pixel.Converter:
    """The chip's per-pixel single-slope converters as ``[chip.adc]`` builds them
    (:func:`chiptwin.pixel.build_converter`): comparator noise (from ``comparator_noise_lsb`` or
    ``comparator_noise_uV``), the ramp's INL, DNL and the converters' offset and gain mismatch,
    fixed per chip and drawn from ``rng`` (nothing is drawn for an ideal converter). A relative
    ``inl_table`` is read from the scenario's folder."""
    adc = s.chip.adc
    if s.run.fidelity.adc == "ideal":  # the ADC's cheaper level: every as-built effect off
        return pixel.Converter.ideal_adc(adc.bits, adc.v_min_V, adc.v_max_V,
                                         adc.offset_error_lsb, adc.gain_error)
    folder = Path(s.source).parent if Path(s.source).is_file() else None
    spec = replace(pixel.AsBuilt.from_keys(adc, folder),
                   comparator_noise_lsb=adc.comparator_noise_total_lsb)
    return pixel.build_converter(rng, (s.chip.rows, s.chip.cols), bits=adc.bits,
                                 v_min_V=adc.v_min_V, v_max_V=adc.v_max_V,
                                 offset_lsb=adc.offset_error_lsb, gain_error=adc.gain_error,
                                 as_built=spec)


def sensor_model(s: Scenario, rng: np.random.Generator,
                 adc_rng: np.random.Generator) -> SensorModel:
    """Resolve the pixel and ADC parameters; draws the PRNU and DSNU maps from ``rng`` and the
    converters' fixed errors (:func:`converter`) from ``adc_rng``, a stream of their own, so a
    converter as built never shifts the maps."""
    px, adc = s.chip.pixel, s.chip.adc
    gain_map, dark_map = pixel.fixed_pattern_maps(rng, s.chip.n_pixels, px.prnu_frac, px.dsnu_frac)
    dark = pixel.dark_current_e_per_s(px.dark_current_nA_per_cm2, px.diode_w_um * px.diode_h_um,
                                      px.temperature_C, px.ref_temp_C, px.dark_doubling_C)
    cg = pixel.conversion_gain_uV_per_e(px.capacitance_fF)
    lsb = pixel.lsb_V(adc.bits, adc.v_min_V, adc.v_max_V)
    return SensorModel(
        qe=px.qe, gain_map=gain_map, dark_e_per_s=dark * dark_map, full_well_e=px.full_well_e,
        ktc_e=pixel.ktc_noise_e(px.capacitance_fF, px.temperature_C + ZERO_C_K),
        read_noise_e=px.read_noise_e, cms_samples=s.chip.dsp.cms_samples, true_cds=px.true_cds,
        conversion_gain_uV_per_e=cg, pedestal_V=px.pedestal_V, lsb_V=lsb,
        e_per_lsb=lsb / (cg * 1e-6),
        converter=converter(s, adc_rng),
    )


class EventPixels:
    """The ``events`` photon level for the pixels under the sites: when each well filled.

    Photons arrive as an inhomogeneous Poisson process, are thinned by QE × gain and merged with
    dark electrons: the electrons of a window are a Poisson process of rate λ(t), mean
    Λ(T) = ∫λ. The collected charge is their count N, clipped at the full well: the ``binned``
    level's count, which the pixel kernel draws and reports (:func:`chiptwin.pixel.binned_codes`'s
    ``report_pixels``), so the two levels read the same codes bit for bit. What counts cannot
    give is the time the well filled: given N, the arrival times are N i.i.d. draws of density
    λ/Λ(T) (Snyder & Miller, *Random Point Processes in Time and Space*, 1991, Thm 2.3.1), so
    the ``need``-th arrival is ``Λ⁻¹(Λ(T)·B)`` with ``B ~ Beta(need, N − need + 1)``, the
    ``need``-th order statistic of N uniforms (David & Nagaraja, *Order Statistics*, 2003,
    §2.1). That is the joint law of (count, filling time) of drawing every arrival
    (:func:`chiptwin.photons.arrival_times`, tested against it), at the cost of the windows whose
    well fills; drawing every arrival of a dim window over the cascade's dense output took
    16–100 ms a window.
    """

    def __init__(self, source: LightSource, coupling: np.ndarray, pixels: np.ndarray,
                 sensor: SensorModel, rng: np.random.Generator) -> None:
        weights = coupling[pixels]
        if sparse.issparse(weights):
            weights = weights.toarray()
        self.source, self.weights, self.pixels = source, weights, pixels
        self.qe = sensor.qe * sensor.gain_map[pixels]
        self.dark = sensor.dark_e_per_s[pixels]
        self.need = int(np.ceil(sensor.full_well_e))
        self.rng = rng
        self.saturation_s: list[np.ndarray] = []

    def electrons_until(self, t0_s: float, t_s: np.ndarray,
                        at: np.ndarray | None = None) -> np.ndarray:
        """Λ(t): expected electrons of each site pixel (or those at positions ``at``) from
        ``t0_s`` to ``t_s`` (one t each)."""
        at = np.arange(len(self.pixels)) if at is None else at
        photons = np.array([self.weights[p] @ self.source.photons(np.array([t0_s, t]))[:, 0]
                            for p, t in zip(at, t_s, strict=True)])
        return self.qe[at] * photons + self.dark[at] * (t_s - t0_s)

    def fill(self, t0_s: float, t1_s: float, counts: np.ndarray) -> None:
        """Record when each site pixel's well filled in the window ``[t0_s, t1_s)``, given the
        electrons it drew there (before the full-well clip): ``inf`` where it did not fill."""
        sat = np.full(len(self.pixels), np.inf)
        full = np.flatnonzero(counts >= self.need)
        if full.size:
            b = self.rng.beta(self.need, counts[full] - self.need + 1)
            total = self.electrons_until(t0_s, np.full(full.size, t1_s), full)
            sat[full] = self._invert(t0_s, t1_s, b * total, total, full)
        self.saturation_s.append(sat)

    def _electron_rate(self, t_s: np.ndarray, at: np.ndarray) -> np.ndarray:
        """λ(t) = dΛ/dt: electrons per second of the site pixels at positions ``at``, each at
        its own time ``t_s[i]``."""
        rate = self.source.rate(t_s)  # (n_sites, len(at)): every site at every pixel's time
        return self.qe[at] * np.einsum("ps,sp->p", self.weights[at], rate) + self.dark[at]

    def _invert(self, t0_s: float, t1_s: float, target: np.ndarray, total: np.ndarray,
                at: np.ndarray | None = None) -> np.ndarray:
        """Λ⁻¹: the time each site pixel (those at positions ``at``, default all) reaches
        ``target`` electrons (``total`` = Λ(t1)).

        Newton's method on Λ, whose derivative is the electron rate, kept inside a bracket that
        starts as the window (Λ is increasing, so the root is in it) and shrinks with every
        evaluation; a step that leaves the bracket, or a rate of 0 (before a flow's light
        starts), halves the bracket instead. It starts on the chord (Λ is concave along a
        decaying pulse, so Newton then closes in from one side, quadratically) and stops when
        the next step would move the time by 4 ulp or less, where the 60 halvings of plain
        bisection also ended: 3 evaluations of Λ instead of 60, on average over pyro_1fmol's
        and pyro_paper_yield's flows, the times within 3 ulp of bisection's.
        """
        at = np.arange(len(self.pixels)) if at is None else at
        lo, hi = np.full(len(target), t0_s), np.full(len(target), t1_s)
        t = t0_s + (t1_s - t0_s) * np.clip(target / np.where(total > 0, total, 1.0), 0.0, 1.0)
        tol = 4 * np.spacing(max(abs(t0_s), abs(t1_s)))
        for _ in range(100):  # a safeguard: the bracket alone halves to an ulp in < 64 steps
            excess = self.electrons_until(t0_s, t, at) - target
            below = excess < 0
            lo, hi = np.where(below, t, lo), np.where(below, hi, t)
            rate = self._electron_rate(t, at)
            with np.errstate(divide="ignore", invalid="ignore"):
                delta = excess / rate
            done = ((rate > 0) & (np.abs(delta) <= tol)) | (hi - lo <= tol)
            if done.all():
                break
            inside = (rate > 0) & (t - delta > lo) & (t - delta < hi)
            t = np.where(done, t, np.where(inside, t - delta, 0.5 * (lo + hi)))
        return t
