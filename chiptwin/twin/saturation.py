"""When a site's well fills: from the event stream, and in closed form from the expected charge.

A pixel integrates until its well holds ``full_well_e``; light beyond that is lost, and a flow
value read from clipped frames says "full", not "how much". With the paper's eq. 19 yield
(17.6 photons per base) 1 fmol of template fills the reference pixel's 1 pF well within the first
frame of every flow. This module reports, per site (``summary['saturation']``):

* the expected charge of its pixel in every frame (before the clip) and how many frames reach the
  full well — the closed form, at every photon level;
* at the ``events`` level, the time each well filled, the order statistic of its electrons'
  arrivals given the window's count (:class:`chiptwin.twin.stages.EventPixels`), per flow:
  the time into the flow at which the well first filled and how many of the flow's frames
  filled, beside the closed-form fill time ``t*`` with ``Λ(t*) = full well`` (Λ: the
  expected electrons since the window opened);
* what the chip spends on its frames: frame period, frames, frame memory and DSP load, so that a
  configuration that fills and one that does not can be compared at their cost.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from scipy import sparse

from chiptwin.pixel import mean_electrons

if TYPE_CHECKING:
    from chiptwin.config import Scenario
    from chiptwin.twin.scene import ChainOutput, Scene

#: The section is reported when a site pixel's expected charge comes within this share of the
#: full well in some frame (or at the ``events`` level, which times the filling).
REPORT_FROM_FULL_WELL = 0.5
#: Bisection steps of the closed-form fill time: 2^-60 of a window, below one nanosecond tick.
BISECTION_STEPS = 60


def site_charge_e(scene: Scene, idx: np.ndarray) -> np.ndarray:
    """Expected charge of the site pixels ``idx`` in every frame, before the full-well clip
    (:func:`chiptwin.pixel.mean_electrons` of the photons on them). Shape (n_sites, n_frames).
    Unit: e⁻."""
    sensor = scene.sensor
    photons = np.asarray(scene.coupling[idx] @ scene.site_photons)  # sparse or dense rows
    return mean_electrons(photons, sensor.qe, sensor.gain_map[idx, None],
                          sensor.dark_e_per_s[idx, None] * scene.sch.t_int_ns * 1e-9)


def expected_electrons(scene: Scene, pixel: int, t0_s: float, t_s: float) -> float:
    """Λ(t): expected electrons of one pixel from ``t0_s`` to ``t_s``. Unit: e⁻."""
    weights = scene.coupling[pixel]
    weights = weights.toarray().ravel() if sparse.issparse(weights) else np.asarray(weights)
    sensor = scene.sensor
    photons = float(weights @ scene.source.photons(np.array([t0_s, t_s]))[:, 0])
    return float(mean_electrons(photons, sensor.qe, sensor.gain_map[pixel],
                                sensor.dark_e_per_s[pixel] * (t_s - t0_s)))


def fill_time_s(scene: Scene, pixel: int, t0_s: float, t1_s: float, full_well_e: float) -> float:
    """The time ``t*`` in ``[t0_s, t1_s]`` at which the expected charge since ``t0_s`` reaches
    ``full_well_e`` (Λ is increasing: bisection), or ``inf`` when it does not. Unit: s."""
    if expected_electrons(scene, pixel, t0_s, t1_s) < full_well_e:
        return float("inf")
    lo, hi = t0_s, t1_s
    for _ in range(BISECTION_STEPS):
        mid = 0.5 * (lo + hi)
        if expected_electrons(scene, pixel, t0_s, mid) < full_well_e:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


#: Sites whose expected charge is made at once (a chunk of sites × frames float64 arrays).
CHUNK_SITES = 256


def _charge_bound_e(scene: Scene, idx: np.ndarray) -> float:
    """An upper bound on any site pixel's expected charge in one frame, without the per-frame
    products: the brightest site's brightest window times the largest share a site pixel gets
    of all sites together, at the highest gain, plus the hottest dark charge. Unit: e⁻."""
    sensor = scene.sensor
    rows = scene.coupling[idx]
    share = float(np.max(np.asarray(rows.sum(axis=1)))) if rows.shape[0] else 0.0
    light = float(scene.site_photons.max()) if scene.site_photons.size else 0.0
    return (sensor.qe * float(sensor.gain_map[idx].max()) * share * light
            + float(sensor.dark_e_per_s[idx].max()) * scene.sch.t_int_ns * 1e-9)


def _charge_stats(scene: Scene, idx: np.ndarray) -> tuple[np.ndarray, ...]:
    """Per site: the peak expected charge, its frame and the frames reaching the full well,
    made a chunk of sites at a time (an array of 4,096 sites × 1,520 frames is 50 MB)."""
    peak, frame, full = (np.zeros(len(idx)), np.zeros(len(idx), np.int64),
                         np.zeros(len(idx), np.int64))
    for lo in range(0, len(idx), CHUNK_SITES):
        charge = site_charge_e(scene, idx[lo:lo + CHUNK_SITES])
        if charge.shape[1]:
            frame[lo:lo + len(charge)] = np.argmax(charge, axis=1)
            peak[lo:lo + len(charge)] = np.max(charge, axis=1)
        full[lo:lo + len(charge)] = np.count_nonzero(charge >= scene.sensor.full_well_e, axis=1)
    return peak, frame, full


def saturation_figures(s: Scenario, scene: Scene, out: ChainOutput, idx: np.ndarray
                       ) -> dict[str, Any] | None:
    """``summary['saturation']``, or None when no site pixel comes near its full well."""
    full_well = scene.sensor.full_well_e
    events = out.saturation_s
    if events is None and _charge_bound_e(scene, idx) < REPORT_FROM_FULL_WELL * full_well:
        return None
    peak, frame, n_full = _charge_stats(scene, idx)
    if events is None and not (peak >= REPORT_FROM_FULL_WELL * full_well).any():
        return None
    if events is not None:  # the frames' windows, to place the fills in their flows
        windows = np.array([scene.sch.window_s(k) for k in range(scene.sch.n_frames)])
        periods = _periods(s, windows[:, 0])
    sites = []
    for i, pix in enumerate(idx):
        site: dict[str, Any] = {
            "pixel": [int(pix // s.chip.cols), int(pix % s.chip.cols)],
            "peak_charge_e": float(peak[i]),
            "peak_fraction_of_full_well": float(peak[i] / full_well),
            "peak_frame_t_s": scene.sch.window_s(int(frame[i]))[0],
            "frames_at_full_well_expected": int(n_full[i]),
        }
        if events is not None:
            charge = site_charge_e(scene, idx[i:i + 1])[0]
            site["frames_saturated"] = int(np.isfinite(events[:, i]).sum())
            site["fills"] = _fills(scene, int(pix), charge, events[:, i], windows, periods,
                                   full_well)
        sites.append(site)
    return {"full_well_e": full_well, "photon_level": s.run.fidelity.photons,
            "report_from_fraction": REPORT_FROM_FULL_WELL, "sites": sites}


def _periods(s: Scenario, window_start_s: np.ndarray) -> list[tuple[str, float, np.ndarray]]:
    """(label, start, frames) of each flow (pyrosequencing), or of the whole light (others)."""
    a = s.assay
    if a.kind != "pyrosequencing":
        return [("light", a.start_s, np.flatnonzero(window_start_s >= a.start_s))]
    order = (a.flow_order * (a.n_flows // len(a.flow_order) + 1))[:a.n_flows]
    starts = a.start_s + a.flow_period_s * np.arange(a.n_flows + 1)
    flow = np.searchsorted(starts, window_start_s, side="right") - 1
    return [(order[f], float(starts[f]), np.flatnonzero(flow == f)) for f in range(a.n_flows)]


def _fills(scene: Scene, pixel: int, charge: np.ndarray, events: np.ndarray,
           windows: np.ndarray, periods, full_well: float) -> list[dict[str, Any]]:
    """Per flow with a filled frame: when the well first filled (event stream and closed form,
    for the same frame), measured from the flow's start, and the frames that filled."""
    rows = []
    for f, (label, start, frames) in enumerate(periods):
        full = frames[np.isfinite(events[frames])]
        if not len(full):
            continue
        k = int(full[0])
        closed = fill_time_s(scene, pixel, windows[k, 0], windows[k, 1], full_well)
        rows.append({"flow": f, "nucleotide": label, "frame_in_flow": int(k - frames[0]),
                     "fill_s": float(events[k] - start),
                     # None: the frame's expected charge stays below the well (it filled by chance)
                     "fill_expected_s": float(closed - start) if np.isfinite(closed) else None,
                     "window_start_s": float(windows[k, 0] - start),
                     "frames_saturated": int(len(full)),
                     "frames_at_full_well_expected": int(np.count_nonzero(
                         charge[frames] >= full_well)),
                     "frames": int(len(frames))})
    return rows


def frame_cost(s: Scenario, chip_summary: dict[str, Any]) -> dict[str, Any]:
    """What the frames cost the chip (from ``summary['chip']``): frame period and integration,
    frames, the frame memory held at peak and the DSP's load (busy time over run time)."""
    return {"frame_period_s": s.chip.timing.frame_period_s, "t_int_s": s.chip.timing.t_int_s,
            "frames": chip_summary["frames"],
            "memory_peak_bits": chip_summary["memory_peak_frames"] * s.chip.frame_bits,
            "memory_capacity_bits": s.chip.memory.capacity_bits,
            "dsp_utilization": chip_summary["dsp_utilization"]}
