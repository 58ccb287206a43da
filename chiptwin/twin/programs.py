"""A scenario's DSP program: its plans (kinetics windows, the Wiener equalizer of the optics'
PSF), the pipeline the chip model runs, and the figures the summary reports.

The stages and their costs are :mod:`chiptwin.dsp.program`; the pipeline is
:mod:`chiptwin.dsp.program_pipeline`. This module knows the scenario (assay windows, optics),
so it sits beside :mod:`chiptwin.twin.runner`, above the DSP package.

Figures (``summary['dsp_program']``, and for programs with ``wiener`` ``summary['crosstalk']``,
with ``bin_rows`` ``summary['column_profile']``):

* cross-talk of a site: the share of its light read at its neighbouring sites' cells (4-nearest
  on the output grid), ``Σ_n |A[n, j]| / A[j, j]`` in dB, before (``A`` = the coupling onto the
  grid) and after the equalizer (``A`` = what the chip's fixed-point stages read back when only
  site ``j`` shines, measured by pushing its light through them);
* SNR cost of equalizing: the site's power SNR after over before, from the propagated noise of
  the run (pixel noise only; the neighbours' light is the cross-talk figure);
* minimum pitch: the smallest pixel pitch (fill factor, height and footprint kept) at which the
  nearest neighbour's leak into a site is ≤ :data:`RESOLVED_LEAK_DB`, with and without the
  equalizer (float design at the scenario's λ, on a 5 × 5 array).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np

from chiptwin.chip import Schedule
from chiptwin.config.budget import window_edges
from chiptwin.config.fields import ScenarioError
from chiptwin.dsp.filters import WienerConfig, design_wiener
from chiptwin.dsp.pipeline import Pipeline
from chiptwin.dsp.program import (
    DECAY_KEYS,
    SPATIAL,
    bin_factor,
    grid_shape,
    input_pixels,
    is_default,
    program_formats,
    stage_costs,
)
from chiptwin.dsp.program_pipeline import (
    KineticsPlan,
    ProgramPipeline,
    SpatialPlan,
    spatial_matrix,
)
from chiptwin.dsp.program_pipeline import kinetics_plan as plan_kinetics
from chiptwin.dsp.reference import wiener_matrix
from chiptwin.twin import stages
from chiptwin.twin.figures import save_figure

if TYPE_CHECKING:
    from chiptwin.config import Scenario
    from chiptwin.twin.scene import ChainOutput, Scene

#: A neighbour is resolved when its leak into a site is at most this (−10 dB: a neighbour as
#: bright as the site adds ≤ 10 % to it, below a 1-mer/0-mer call's half-way threshold). Choice.
RESOLVED_LEAK_DB = -10.0
#: Pitches scanned for the minimum pitch, as multiples of the scenario's.
PITCH_SCAN = np.geomspace(0.1, 4.0, 60)


# ---------------------------------------------------------------------------------------------
# plans and the pipeline
# ---------------------------------------------------------------------------------------------


def kinetics_plan(s: Scenario, sch: Schedule) -> KineticsPlan:
    """The scenario's kinetics stage: :func:`chiptwin.dsp.program_pipeline.kinetics_plan` over
    the assay's windows (:func:`chiptwin.config.budget.window_edges`) and its decay rate."""
    return plan_kinetics(s.chip, sch, window_edges(s), getattr(s.assay, DECAY_KEYS[s.assay.kind]))


def grid_coupling(s: Scenario) -> np.ndarray:
    """(n_pixels, n_pixels): the coupling of a site above every pixel (the system PSF sampled on
    the array), with the scenario's height, footprint and optics, without the transmission: a
    scalar loss the equalizer's normalisation (each cell at its own gain) removes anyway, and
    which could underflow the matrix. At the raytrace level the equalizer is still designed
    from the psf level's matrix (the paper's "modelled system PSF", Salama et al. 2004, Sec. 3.3),
    while the light follows the traced one: the model's error is then part of what the run
    measures."""
    every = replace(s, sites=replace(s.sites, at_pixels="all"),
                    optics=replace(s.optics, transmission=1.0))
    if s.run.fidelity.optics == "raytrace":  # the DSP's model of the PSF is the psf level's
        every = replace(every, run=replace(every.run, fidelity=replace(
            every.run.fidelity, optics="psf")))
    c = stages.coupling(every)
    return c.toarray() if hasattr(c, "toarray") else np.asarray(c)


def spatial_plan(s: Scenario) -> SpatialPlan:
    """The spatial stages, with the Wiener equalizer designed for the response of everything
    before it (PSF, binning, FIR) onto the grid, normalised so each cell reads its own light at
    the gain it had before equalizing."""
    chip = s.chip
    fmts = program_formats(chip)
    g_rows, cols = grid_shape(chip)
    r, c = np.divmod(np.arange(chip.n_pixels), cols)
    binned = "bin_rows" in chip.dsp.program
    cell = (r // bin_factor(chip)) * cols + c if binned else np.arange(chip.n_pixels)
    plan = SpatialPlan(tuple(x for x in chip.dsp.program if x in SPATIAL), chip.rows, cols,
                       fmts, None, g_rows, cell)
    if "wiener" not in plan.stages:
        return plan
    d = chip.dsp
    h = response_on_grid(plan, grid_coupling(s))
    cfg = WienerConfig(noise_to_signal=d.wiener_noise_to_signal, in_fmt=fmts.wiener_in,
                       coef_word_bits=d.wiener_coef_bits, rounding=d.rounding,
                       overflow=d.overflow, acc_overflow=d.acc_overflow)
    try:
        eq = design_wiener(h / np.diag(h)[None, :], cfg)
    except (np.linalg.LinAlgError, ValueError) as err:
        # zero forcing (λ → 0) of a coupling whose cells read the same light has no finite
        # inverse, or one whose gains no 64-bit register holds; known only once the PSF is made
        raise ScenarioError(
            s.source, "chip.dsp.wiener_noise_to_signal", d.wiener_noise_to_signal,
            f"stage 'wiener' cannot invert this {plan.n_grid}-cell grid's coupling ({err}): "
            "its cells read (nearly) the same light; raise λ (0.01 for a site SNR of 20 dB)"
        ) from None
    return replace(plan, wiener=eq)


def response_on_grid(plan: SpatialPlan, coupling: np.ndarray) -> np.ndarray:
    """(n_grid, n_grid): what the equalizer's input reads of one unit of light in each grid cell
    (a binned cell's light spread evenly over its rows)."""
    n_pix = plan.rows * plan.cols
    spread = np.zeros((n_pix, plan.n_grid))
    counts = np.bincount(plan.cell_of_pixel, minlength=plan.n_grid)
    spread[np.arange(n_pix), plan.cell_of_pixel] = 1.0 / counts[plan.cell_of_pixel]
    return spatial_matrix(plan, upto="wiener") @ coupling @ spread


def program_pipeline(s: Scenario, keep_codes: bool = False) -> ProgramPipeline:
    """The DSP of a scenario whose program goes beyond today's chain, at its DSP level."""
    chip, level = s.chip, s.dsp_level
    fmts = program_formats(chip)
    chain = fmts.front if level in ("fixed", "rtl") else None
    report = chip.dsp.report_error
    routines = None
    if level == "rtl":
        from chiptwin.twin.rtl import RtlPipeline, routines

        front = RtlPipeline(chain, report_error=False, keep_codes=keep_codes)
    else:
        front = Pipeline(level, chain, report_error=False, keep_codes=keep_codes)
    kin = None
    if "kinetics" in chip.dsp.program:
        kin = kinetics_plan(s, Schedule.from_chip(chip, s.run.duration_s))
    spatial = spatial_plan(s) if any(x in SPATIAL for x in chip.dsp.program) else None
    return ProgramPipeline(front, level, kin, spatial, report_error=report,
                           float_front=Pipeline("float") if report else None,
                           rtl_routines=routines)


# ---------------------------------------------------------------------------------------------
# figures
# ---------------------------------------------------------------------------------------------


def program_figures(s: Scenario, scene: Scene, out: ChainOutput, summary: dict[str, Any],
                    arrays: dict[str, np.ndarray]) -> None:
    """Add the program's figures to a run's summary and arrays (``results.detect`` calls it)."""
    chip, sch = s.chip, scene.sch
    costs, pixels = stage_costs(chip), input_pixels(chip)
    fig: dict[str, Any] = {
        "stages": list(chip.dsp.program),
        "is_default": is_default(chip.dsp.program),
        "memory_bits": {k: c.memory_bits for k, c in costs.items()},
        "memory_words": {k: c.layout for k, c in costs.items() if c.layout},
        "resident_bits": sum(c.memory_bits for c in costs.values()),
        "cycles_per_pixel_per_frame": {k: c.cycles_per_pixel_frame for k, c in costs.items()},
        "cycles_per_pixel_per_output": {k: c.cycles_per_pixel_output for k, c in costs.items()},
        "input_pixels": {k: pixels[k] for k in costs},
        "dsp_time_per_output_s": sch.dsp_ns_per_output / 1e9,
        "frames_per_dsp_job": sch.block_frames,
    }
    dsp = out.dsp
    if isinstance(dsp, ProgramPipeline):
        if dsp.stage_bounds:
            fig["stage_error_bounds"] = dsp.stage_bounds
            fig["front_error_gain"] = dsp.error_gain("front")
        if dsp.kin is not None:
            fig["kinetics"] = {"window_frames": len(dsp.kin.cfg.t_s),
                               "k_per_s": dsp.kin.cfg.k_per_s,
                               "output_scale": dsp.kin.scale}
        if dsp.spatial is not None and dsp.spatial.wiener is not None:
            summary["crosstalk"] = crosstalk_figures(s, dsp)
        if dsp.spatial is not None and "bin_rows" in dsp.spatial.stages and dsp.profiles:
            summary["column_profile"] = profile_figures(s, dsp, arrays, scene.sensor.e_per_lsb)
    summary["dsp_program"] = fig


def _site_cells(s: Scenario, plan: SpatialPlan) -> np.ndarray:
    return plan.cell_of_pixel[stages.site_pixel_indices(s)]


def _neighbours(cells: np.ndarray, cols: int) -> list[np.ndarray]:
    """For each site cell, the other site cells 4-adjacent to it on the grid."""
    r, c = np.divmod(cells, cols)
    return [np.flatnonzero(np.abs(r - r[i]) + np.abs(c - c[i]) == 1) for i in range(len(cells))]


def leak_db(a: np.ndarray, cells: np.ndarray, neighbours: list[np.ndarray]) -> np.ndarray:
    """Per site ``j``: ``10 log10(Σ_n |A[n, j]| / A[j, j])`` over its neighbours' cells
    (−inf without neighbours)."""
    out = np.full(len(cells), -np.inf)
    for i, nb in enumerate(neighbours):
        if len(nb):
            share = np.abs(a[cells[nb], cells[i]]).sum() / a[cells[i], cells[i]]
            out[i] = 10 * np.log10(share) if share > 0 else -np.inf
    return out


def measured_response(dsp: ProgramPipeline, h_norm: np.ndarray, cells: np.ndarray,
                      level_lsb: float) -> np.ndarray:
    """(n_grid, n_sites): what the chip's equalizer (at its DSP level, in fixed point where it
    runs so) reads when only site ``j`` shines, ``level_lsb`` at its own cell; columns scaled
    back to a unit of light."""
    plan = dsp.spatial
    probe = ProgramPipeline(dsp.front, dsp.level, None, replace(
        plan, stages=("wiener",), rows=plan.grid_rows, cell_of_pixel=np.arange(plan.n_grid),
        formats=replace(plan.formats, binning=None, fir=None,
                        kinetics_out=plan.formats.wiener_in)), rtl_routines=dsp.rtl)
    fmt = plan.formats.wiener_in
    out = np.zeros((plan.n_grid, len(cells)))
    for i, j in enumerate(cells):
        x = np.ldexp(np.rint(np.ldexp(h_norm[:, j] * level_lsb, fmt.frac_bits)), -fmt.frac_bits)
        out[:, i] = probe._spatial(x) / level_lsb
    return out


def crosstalk_figures(s: Scenario, dsp: ProgramPipeline) -> dict[str, Any]:
    """Per-site cross-talk before and after the equalizer, its SNR cost, the minimum pitch."""
    plan = dsp.spatial
    h = response_on_grid(plan, grid_coupling(s))
    h_norm = h / np.diag(h)[None, :]
    cells = _site_cells(s, plan)
    nb = _neighbours(cells, plan.cols)
    level = float(plan.formats.wiener_in.max_value) / 4  # a bright site, well inside range
    measured = measured_response(dsp, h_norm, cells, level)
    a_after = np.zeros((plan.n_grid, plan.n_grid))
    a_after[:, cells] = measured
    before, after = leak_db(h_norm, cells, nb), leak_db(a_after, cells, nb)
    predicted = leak_db(plan.wiener.g @ h_norm, cells, nb)
    has = np.isfinite(before)
    cost = snr_cost_db(dsp, h_norm, cells)
    pitch = minimum_pitch(s)
    return {
        "definition": "share of a site's light read at its 4-nearest neighbouring sites, dB "
                      "(10 log10 Σ|A[n,j]| / A[j,j]); after = measured through the chip's "
                      "equalizer",
        "sites_with_neighbours": int(has.sum()),
        "before_db_median": _median(before[has]),
        "after_db_median": _median(after[has]),
        "after_predicted_db_median": _median(predicted[has]),
        "reduction_db_median": _median(before[has] - after[has]),
        "before_db_worst": float(before[has].max()) if has.any() else None,
        "after_db_worst": float(after[has].max()) if has.any() else None,
        "per_site_before_db": [_finite(v) for v in before],
        "per_site_after_db": [_finite(v) for v in after],
        "snr_cost_db_median": _median(cost),
        "per_site_snr_cost_db": [float(v) for v in cost],
        "wiener_noise_to_signal": s.chip.dsp.wiener_noise_to_signal,
        "resolved_leak_db": RESOLVED_LEAK_DB,
        "min_pitch_um_without": pitch[0],
        "min_pitch_um_with": pitch[1],
        "pitch_um": s.chip.pitch_um,
    }


def _finite(v: float) -> float | None:
    """A figure for JSON: None for a site without neighbours (−inf)."""
    return float(v) if np.isfinite(v) else None


def _median(x: np.ndarray) -> float | None:
    return float(np.median(x)) if len(x) else None


def snr_cost_db(dsp: ProgramPipeline, h_norm: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Power SNR of each site before over after equalizing (dB; > 0 is a loss), from the
    variances the run propagated: noise ``(L∘L) var`` before and after the equalizer, the site's
    own gain ``(G H')[j, j]``."""
    plan = dsp.spatial
    var = dsp.front_var if dsp.front_var is not None else np.ones(plan.rows * plan.cols)
    pre = spatial_matrix(plan, upto="wiener")
    v_before = (pre**2) @ var
    v_after = (spatial_matrix(plan) ** 2) @ var
    gain = np.diag(plan.wiener.g @ h_norm)
    return 10 * np.log10(v_after[cells] / v_before[cells] / gain[cells] ** 2)


def minimum_pitch(s: Scenario) -> tuple[float | None, float | None]:
    """Smallest scanned pitch (µm) at which the nearest neighbour's leak into the centre site of
    a 5 × 5 array is ≤ RESOLVED_LEAK_DB: without and with the Wiener equalizer (λ of the
    scenario, float). The diode keeps the scenario's fill factor; height and footprint are
    kept (the footprint at most the pitch)."""
    px, chip = s.chip.pixel, s.chip
    fill_w, fill_h = px.diode_w_um / chip.pitch_um, px.diode_h_um / chip.pitch_um
    lam = chip.dsp.wiener_noise_to_signal
    found: list[float | None] = [None, None]
    for p in PITCH_SCAN * chip.pitch_um:
        small = replace(s, chip=replace(chip, rows=5, cols=5, pitch_um=float(p), pixel=replace(
            px, diode_w_um=fill_w * p, diode_h_um=fill_h * p)), sites=replace(
            s.sites, at_pixels="all",
            footprint_radius_um=min(s.sites.footprint_radius_um, float(p))))
        c = grid_coupling(small)
        c = c / np.diag(c)[None, :]
        centre, nbs = 12, [7, 11, 13, 17]
        for k, a in enumerate((c, _equalized(c, lam))):
            if a is None:  # no equalizer at this pitch: not resolved with it
                continue
            leak = max(abs(a[n, centre]) for n in nbs) / a[centre, centre]
            if found[k] is None and leak > 0 and 10 * math.log10(leak) <= RESOLVED_LEAK_DB:
                found[k] = float(p)
        if all(f is not None for f in found):
            break
    return found[0], found[1]


def _equalized(c: np.ndarray, lam: float) -> np.ndarray | None:
    """``G C`` of the Wiener equalizer of ``c`` at λ, or None where there is none: zero forcing
    (λ → 0) of a coupling whose pixels all read the same light (a pitch far below the height)
    is singular."""
    try:
        a = wiener_matrix(c, lam) @ c
    except np.linalg.LinAlgError:
        return None
    return a if np.isfinite(a).all() else None


def profile_figures(s: Scenario, dsp: ProgramPipeline, arrays: dict[str, np.ndarray],
                    e_per_lsb: float) -> dict[str, Any]:
    """The column profile (the sum of every output over the run, on the binned grid) before the
    FIR and the equalizer and after the whole program, and the separation of the sites."""
    plan = dsp.spatial
    before = np.sum([b for b, _, _, _ in dsp.profiles], axis=0) * e_per_lsb
    after = np.sum([a for _, a, _, _ in dsp.profiles], axis=0) * e_per_lsb
    before_mean = np.sum([m for _, _, m, _ in dsp.profiles], axis=0) * e_per_lsb
    after_mean = np.sum([m for _, _, _, m in dsp.profiles], axis=0) * e_per_lsb
    shape = (plan.grid_rows, plan.cols)
    for name, v in (("before", before), ("after", after), ("before_expected", before_mean),
                    ("after_expected", after_mean)):
        arrays[f"column_profile_{name}_e"] = v.reshape(shape)
    cells = np.unique(_site_cells(s, plan))
    fig: dict[str, Any] = {"definition": "peak-to-valley: mean of the profile at the two "
                                         "outermost sites' cells over its minimum between them"}
    for name, v in (("before", before), ("after", after), ("before_expected", before_mean),
                    ("after_expected", after_mean)):
        fig.update({f"{k}_{name}": val for k, val in separation(v, cells).items()})
    return fig


def separation(profile: np.ndarray, cells: np.ndarray) -> dict[str, float | None]:
    """Peak-to-valley of a profile between its first and last site cell (same grid row)."""
    if len(cells) < 2:
        return {"peak_to_valley": None, "valley_to_peak": None}
    a, b = int(cells.min()), int(cells.max())
    peak = float(np.mean(profile[[a, b]]))
    valley = float(profile[a + 1:b].min()) if b > a + 1 else peak
    return {"peak_to_valley": peak / valley if valley > 0 else None,
            "valley_to_peak": valley / peak if peak else None}


def program_plots(result: Any, folder: Any) -> list[tuple[str, str]]:
    """``column_profile.png`` (programs with bin_rows): the profile before and after the
    program, as the paper's Fig. 12 (a) and (b); ``(file name, caption)`` pairs."""
    a = result.arrays
    if "column_profile_before_e" not in a:
        return []
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
    cols = np.arange(a["column_profile_before_e"].shape[1])
    cells = stages.site_pixels(result.scenario)[:, 1]
    for ax, name, title in ((axes[0], "before", "(a) background-subtracted, binned"),
                            (axes[1], "after", "(b) after the 8-tap FIR and PSF equalization")):
        for row, v in enumerate(a[f"column_profile_{name}_e"]):
            ax.plot(cols, v, lw=1.0, label="measured" if row == 0 else None)
        for row, v in enumerate(a[f"column_profile_{name}_expected_e"]):
            ax.plot(cols, v, "k--", lw=0.7, label="expected" if row == 0 else None)
        for c in cells:
            ax.axvline(c, color="grey", lw=0.5, ls=":")
        sep = result.summary["column_profile"][f"valley_to_peak_{name}"]
        shown = "—, no light at the sites" if sep is None else f"{sep:.2f}"
        ax.set(ylabel="e⁻ (sum of outputs)", title=f"{title}: valley/peak {shown}")
        ax.legend(fontsize=7)
    axes[1].set_xlabel("column")
    return [save_figure(fig, folder, "column_profile.png", "Column profile of the sites before "
                        "and after the DSP program (dotted: site columns)")]
