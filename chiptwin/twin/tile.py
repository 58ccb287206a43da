"""A representative tile: a periodic site layout on a large array run as 9 tiles of its sites
(``[run] tile``), with every neighbour's light, the figures scaled to the whole array.

Which sites and with what weights is geometry (:mod:`chiptwin.config.tiling`: the 4 corner
tiles, 4 edge tiles and 1 interior tile of a site lattice). Here the light: every simulated
site's pixel receives the light of every site of the array within the coupling's reach
(:func:`chiptwin.twin.stages.coupling_kernel`), each neighbour's share booked to the column of
the simulated site that stands for it (all sites hold the same light, so each pixel's light is
the whole array's, exactly). Only the sites' pixels are simulated (today's DSP chain is per
pixel, and the detection reads the sites' pixels alone), on the whole array's schedule; the
chip's figures (frames, memory, DSP load, ADC power) are the whole array's.

The figures are then weighted by the sites each simulated site stands for (:func:`scale`):
fractions and means are weighted means, percentiles weighted, counts scaled to the array, each
fraction and mean with its Monte Carlo standard error. Where the coupling reaches further than a
tile, a middle site near an edge stands for sites that see fewer neighbours than it does: the
summary states the largest relative error of a site pixel's light this leaves
(:func:`light_error`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy import signal, sparse

from chiptwin import limits
from chiptwin.config import Scenario, ScenarioError, tiling
from chiptwin.config.tiling import TilePlan
from chiptwin.twin import chip_cost, stages
from chiptwin.twin.optics_summary import optics_figures
from chiptwin.twin.results import SNR_PERCENTILES, chip_figures

if TYPE_CHECKING:
    from chiptwin.chip import Schedule
    from chiptwin.twin.scene import ChainOutput


#: The error a tiled run's figures carry, as its summary states it (measured by
#: ``benchmarks/bench_tile.py`` on pyro_array_256 at seeds 20261123 and 20261124: fraction
#: called right 0.187 and 0.221 tiled against 0.192 and 0.206 whole, fraction detected 0.261 and
#: 0.247 against 0.253 and 0.239, mean power SNR 7.24 and 7.50 against 7.39 and 7.19, each
#: within 0.84 standard errors of the difference; ``tests/test_tile.py`` holds it to 3).
ERROR_BOUND = ("each fraction and mean in summary['array'] is a weighted estimate with its Monte "
               "Carlo standard_error (the whole array's figure lies within 3 of the combined "
               "standard errors; pyro_array_256 measured within 0.84 at two seeds); "
               "light_error_rel bounds the light a stand-in site misstates")


@dataclass(frozen=True, eq=False)
class Tiled:
    """What :func:`tile` decided: the plan (None: the whole array runs, ``section`` says why),
    the simulated pixels' coupling ``(n_simulated, n_simulated)``, the ``summary['tiled']``
    section, and the whole array's ``summary['optics']``."""

    plan: TilePlan | None
    coupling: np.ndarray | None
    section: dict[str, Any]
    optics: dict[str, Any] | None = None


def tile(s: Scenario) -> Tiled | None:
    """The tile of ``s``, or None when ``[run] tile = "off"``.

    ``"auto"`` takes tiles of ``⌈R / pitch⌉`` sites a side (R the coupling's reach in pixels,
    so that the edge tiles hold every site that sees fewer neighbours), within
    :data:`~chiptwin.config.tiling.AUTO_MIN_SITES` … :data:`~chiptwin.config.tiling.AUTO_MAX_SITES`;
    a scene that cannot be tiled runs whole and the section says why. A size in pixels was
    checked when the scenario was (:func:`chiptwin.config.tiling.check_tile`).
    """
    if s.run.tile == "off":
        return None
    why = tiling.not_tileable(s)
    if why is None and not stages.identical_sites(s):
        why = "the sites' light is drawn per site (a flow-value model): not periodic"
        if s.run.tile != "auto":
            raise ScenarioError(s.source, "run.tile", s.run.tile, f"cannot tile this scene: {why}")
    if why is not None:
        return Tiled(None, None, {"applies": False, "reason": why})
    (_, pr, _), (_, pc, _), _ = tiling.lattice(tiling.site_rc(s))
    kernel, reach = stages.coupling_kernel(s, mirrored=True)
    k = tiling.tile_sites(s, pr, pc) or tuple(
        int(np.clip(math.ceil(reach / p), tiling.AUTO_MIN_SITES, tiling.AUTO_MAX_SITES))
        for p in (pr, pc))
    plan = tiling.plan(s, *k)
    if plan is None:
        return Tiled(None, None, {"applies": False, "reason": (
            f"3 tiles of {k[0]} × {k[1]} sites hold the whole site lattice: nothing to save")})
    lat = lattice_kernel(kernel, reach, pr, pc)
    return Tiled(plan, tile_coupling(plan, lat), _section(s, plan, k, (pr, pc), reach, lat),
                 site_optics(s, kernel, reach))


def _section(s: Scenario, plan: TilePlan, k: tuple[int, int], pitch: tuple[int, int],
             reach: int, lat: np.ndarray) -> dict[str, Any]:
    """``summary['tiled']`` of a tile that applies: what ran, how, and its error."""
    w = plan.weights.astype(np.float64)
    return {
        "applies": True,
        "note": f"tiled: {plan.n_simulated} of {plan.n_sites} sites simulated",
        "tile_sites": list(k), "tile_pixels": [k[0] * pitch[0], k[1] * pitch[1]],
        "tiles": "4 corners, 4 edges, 1 interior (an axis of ≤ 3 tiles is simulated whole)",
        "edges": "corner and edge tiles at the array's corners and edges; each edge position "
                 "stands for its own row or column of sites, each interior one for every k-th",
        "coupling_reach_pixels": int(reach),
        "effective_sites": round(float(w.sum() ** 2 / (w**2).sum()), 1),
        "light_error_rel": light_error(plan, lat),
        "error_bound": ERROR_BOUND,
        "simulated_pixels": plan.n_simulated,
        "of_pixels": s.chip.n_pixels,
    }


def lattice_kernel(kernel: np.ndarray, reach: int, pr: int, pc: int) -> np.ndarray:
    """The kernel at whole site pitches: ``K[R_r + di, R_c + dj]`` is the share of a site's light
    on the pixel of the site ``di`` rows and ``dj`` columns of the lattice away (the pixel under
    each site sits where the site does). Shares below the sparse coupling's drop tolerance
    (:data:`chiptwin.limits.COUPLING_DROP_RTOL` of the own pixel's) are 0, as there."""
    dr, dc = reach // pr, reach // pc
    lat = kernel[reach - dr * pr: reach + dr * pr + 1: pr, reach - dc * pc: reach + dc * pc + 1: pc]
    return np.where(lat >= limits.COUPLING_DROP_RTOL * kernel[reach, reach], lat, 0.0)


def tile_coupling(plan: TilePlan, lat: np.ndarray) -> np.ndarray | sparse.csr_matrix:
    """``(n_simulated, n_simulated)``: on each simulated site's pixel (rows), the light of every
    array site within reach, booked to the column of the simulated site that stands for it;
    dense or sparse as the whole array's coupling would be at that size
    (:func:`chiptwin.limits.coupling_is_dense`)."""
    rows, cols = plan.rows, plan.cols
    dr, dc = (lat.shape[0] - 1) // 2, (lat.shape[1] - 1) // 2
    ia = np.repeat(rows.sim, len(cols.sim))  # lattice position of each simulated site
    ja = np.tile(cols.sim, len(rows.sim))
    di, dj = (g.ravel() for g in np.meshgrid(np.arange(-dr, dr + 1), np.arange(-dc, dc + 1),
                                             indexing="ij"))
    share = lat[di + dr, dj + dc]
    ib, jb = ia[:, None] - di[None, :], ja[:, None] - dj[None, :]  # the sites di, dj away
    inside = (ib >= 0) & (ib < rows.n) & (jb >= 0) & (jb < cols.n) & (share[None, :] > 0)
    n = plan.n_simulated
    row = np.broadcast_to(np.arange(n)[:, None], ib.shape)[inside]
    col = rows.rep[ib[inside]] * len(cols.sim) + cols.rep[jb[inside]]
    values = np.broadcast_to(share[None, :], ib.shape)[inside]
    if limits.coupling_is_dense(n, n):
        return np.bincount(row * n + col, weights=values, minlength=n * n).reshape(n, n)
    return sparse.csr_matrix((values, (row, col)), shape=(n, n))  # duplicates summed


def site_light(n_rows: int, n_cols: int, lat: np.ndarray) -> np.ndarray:
    """``(n_rows, n_cols)``: the share of one site's photons that every site of the lattice
    puts on each site's pixel, its own included (the array's light per site, where all sites
    emit alike). By FFT: a 1,024² lattice and a 33² kernel in ≈ 0.1 s, rounding ≈ 1e-16."""
    return signal.fftconvolve(np.ones((n_rows, n_cols)), lat, mode="same")


def light_error(plan: TilePlan, lat: np.ndarray) -> dict[str, float]:
    """The relative error of each array site's pixel light when its simulated stand-in's is
    used: largest and site-weighted mean over the array (0 where the tile is as wide as the
    coupling's reach)."""
    whole = site_light(plan.rows.n, plan.cols.n, lat)
    stand_in = whole[np.ix_(plan.rows.sim[plan.rows.rep], plan.cols.sim[plan.cols.rep])]
    rel = np.abs(stand_in - whole) / whole
    return {"max": float(f"{rel.max():.3g}"), "mean": float(f"{rel.mean():.3g}")}


def site_optics(s: Scenario, kernel: np.ndarray, reach: int) -> dict[str, Any] | None:
    """``summary['optics']`` of the whole array, from its first site's coupling column (the
    kernel placed at that site, clipped at the array's edges)."""
    (r, c), rows, cols = tiling.site_rc(s)[0], s.chip.rows, s.chip.cols
    col = np.zeros((rows, cols))
    r0, c0 = max(r - reach, 0), max(c - reach, 0)
    r1, c1 = min(r + reach + 1, rows), min(c + reach + 1, cols)
    col[r0:r1, c0:c1] = kernel[r0 - r + reach: r1 - r + reach, c0 - c + reach: c1 - c + reach]
    col[col < limits.COUPLING_DROP_RTOL * kernel[reach, reach]] = 0.0  # as the sparse coupling
    return optics_figures(s, col.reshape(-1, 1))


def scale(s: Scenario, plan: TilePlan, section: dict[str, Any], sch: Schedule,
          out: ChainOutput, summary: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
    """The tile's summary and arrays (made by :func:`chiptwin.twin.results.detect` of the tile's
    own scenario) turned into the array's: sites named by their array index and pixel, with
    their weights; ``array`` and the reads' counts scaled; the chip's figures of the whole
    array; ``tiled`` added."""
    w = plan.weights.astype(np.float64)
    ids, pixels = plan.simulated_ids, plan.simulated_pixels(s.chip.cols)
    for site, i, p, weight in zip(summary["sites"], ids, pixels, w, strict=True):
        site.update(id=int(i), pixel=[int(v) for v in divmod(int(p), s.chip.cols)],
                    weight=int(weight))
    arrays["site_pixel_index"] = pixels
    arrays["site_weight"] = w
    simulated = {"array": summary["array"]}
    summary["array"] = weighted_array(summary, w, plan.n_sites)
    if "reads" in summary:
        simulated["reads"] = {k: summary["reads"][k] for k in READ_COUNTS + ("read_accuracy",)
                              if k in summary["reads"]}
        summary["reads"].update(weighted_reads(summary["reads"], w))
    flags = summary["chip"]["flags"]
    summary["chip"].update({k: v for k, v in chip_figures(s, sch, out.chip).items()
                            if k != "flags"})
    summary["chip"]["flags"] = flags
    if "cost" in summary:  # silicon and yield of the whole array, from its scaled figures
        _whole_cost(s, plan, sch, summary)
    summary["tiled"] = {**section, "simulated": simulated,
                        "peak_frame_e": "the simulated sites' pixels as a grid (rows × columns "
                                        "of the simulated sites), not the array's"}


def _whole_cost(s: Scenario, plan: TilePlan, sch: Schedule, summary: dict[str, Any]) -> None:
    """``summary['cost']`` and ``['throughput']`` of the whole array (:mod:`.chip_cost`), the
    sites an assay detects counted from the weighted fraction."""
    summary["cost"] = chip_cost.cost_figures(s, sch, summary)
    out = summary["throughput"] = chip_cost.throughput_figures(s, summary, summary["cost"])
    if "sites_called_right" not in summary["array"]:
        called = int(round(summary["array"]["fraction_detected"] * plan.n_sites))
        out.update(sites_called=called, sites_per_mm2=called / summary["cost"]["area_mm2"])


def weighted_mean(x: np.ndarray, w: np.ndarray) -> tuple[float, float]:
    """The weighted mean of ``x`` and its standard error, the sites' draws independent:
    ``√(σ² Σw² / W²)`` with σ² the weighted sample variance (Cochran 1977, §5.3 with one
    variance across strata)."""
    if not len(x):
        return math.nan, math.nan
    big_w = w.sum()
    mean = float((w * x).sum() / big_w)
    n = len(x)
    var = float((w * (x - mean) ** 2).sum() / big_w) * (n / (n - 1) if n > 1 else math.nan)
    return mean, math.sqrt(var * (w**2).sum() / big_w**2)


def weighted_percentiles(x: np.ndarray, w: np.ndarray, q: tuple[int, ...]) -> np.ndarray:
    """Percentiles of the array's sites (the inverted weighted CDF: the smallest value whose
    sites reach ``q`` % of the array); p0 and p100 the simulated extremes."""
    order = np.argsort(x, kind="stable")
    cum = np.cumsum(w[order]) / w.sum()
    at = np.searchsorted(cum, np.asarray(q) / 100.0 - 1e-12, side="left")
    return x[order][np.clip(at, 0, len(x) - 1)]


def weighted_array(summary: dict[str, Any], w: np.ndarray, n_sites: int) -> dict[str, Any]:
    """``summary['array']`` of the whole array from the simulated sites and their weights, with
    the standard error of each fraction and mean (:func:`weighted_mean`)."""
    sites = summary["sites"]
    snr_p = np.array([x["snr_power"] for x in sites], dtype=np.float64)
    detected = np.array([x["detected"] for x in sites], dtype=np.float64)
    pct = weighted_percentiles(snr_p, w, SNR_PERCENTILES)
    fd, fd_se = weighted_mean(detected, w)
    mean, mean_se = weighted_mean(snr_p, w)
    out: dict[str, Any] = {
        "n_sites": n_sites, "n_sites_simulated": len(sites), "fraction_detected": fd,
        "snr_power_percentiles": {f"p{q}": float(v) for q, v in zip(SNR_PERCENTILES, pct,
                                                                      strict=True)},
        "snr_power_mean": mean,
        "snr_power_median_db": float(10 * np.log10(pct[3])) if pct[3] > 0 else None,
        "standard_error": {"fraction_detected": fd_se, "snr_power_mean": mean_se},
    }
    if "called_sequences" in summary:
        right = np.array([c == summary["true_sequence"] for c in summary["called_sequences"]],
                         dtype=np.float64)
        fr, fr_se = weighted_mean(right, w)
        out["sites_called_right"] = int(round(fr * n_sites))
        out["fraction_called_right"] = fr
        out["standard_error"]["fraction_called_right"] = fr_se
    return out


#: Counts of ``summary['reads']`` scaled to the array (each a sum over reads).
READ_COUNTS = ("n_reads", "chip_q20_bases", "sites_q20_at_least_200", "key_fail_reads",
               "errors", "called_bases")


def weighted_reads(reads: dict[str, Any], w: np.ndarray) -> dict[str, Any]:
    """The reads' counts over the whole array: each read's count times its weight, rounded."""
    rows = reads["sites"]
    per = {"n_reads": [1] * len(rows),
           "chip_q20_bases": [x["q20_read_length"] for x in rows],
           "sites_q20_at_least_200": [x["q20_read_length"] >= 200 for x in rows],
           "key_fail_reads": [not x["key_pass"] for x in rows],
           "errors": [x["errors"] for x in rows],
           "called_bases": [x["bases"] for x in rows]}
    out = {k: int(round(float(np.dot(np.asarray(v, dtype=np.float64), w))))
           for k, v in per.items() if k in reads}
    template = reads.get("template_bases", 0)
    read = np.minimum([x["bases"] for x in rows], template)
    if "read_accuracy" in reads:
        out["read_accuracy"] = 1.0 - out["errors"] / max(float(np.dot(read, w)), 1.0)
    return out


__all__ = ["Tiled", "light_error", "scale", "tile", "tile_coupling", "weighted_array",
           "weighted_mean", "weighted_percentiles"]
