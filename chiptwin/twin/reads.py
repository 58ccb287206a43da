"""Reads of a pyrosequencing run: every site's flowgram called, with qualities and figures.

The flow values come normalised by the key's 1-mers
(:func:`chiptwin.kinetics.pyro.normalise_flows`). The noise the caller weighs each flow with is
the one the twin predicts for it: the DSP's propagated variance of each flow's window sum
(:func:`chiptwin.detection.window_sums`), read at the key's empty and single-base flows (the
floor and the shot noise per base), and the variance of the key's 1-mer reference itself, all in
units of that reference (:class:`chiptwin.detection.reads.FlowNoise`).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np

from chiptwin.config import Scenario
from chiptwin.detection import read_stats
from chiptwin.detection.key_pass import key_counts, passes_key
from chiptwin.detection.reads import (
    FlowNoise,
    Read,
    call_dephased,
    call_rounded,
    phred,
)
from chiptwin.kinetics import pyro
from chiptwin.kinetics.phasing import flow_indices
from chiptwin.pixel.chain import available_cores

#: Flows the phase-corrected flow-value statistics pool (summary ``reads``).
CORRECTED_STATS_FLOWS = 100

#: Largest flowgram value SFF stores: uint16 hundredths (454's Standard Flowgram Format).
SFF_MAX_X100 = 65535


def site_noise(var_e2: np.ndarray, ref_e: float, ref_sd_e: float, key_n: np.ndarray
               ) -> FlowNoise:
    """The predicted noise of one site's normalised flow values.

    Parameters
    ----------
    var_e2 : (n_flows,) predicted variance of each flow's window sum, e⁻²
    ref_e : the key's 1-mer level, e⁻ (> 0)
    ref_sd_e : standard deviation of that level, e⁻
    key_n : expected counts of the key flows
    """
    zeros, ones = var_e2[: key_n.size][key_n == 0], var_e2[: key_n.size][key_n == 1]
    floor = float(zeros.mean()) if zeros.size else float(ones.min())
    shot = max(float(ones.mean()) - floor, 0.0)
    return FlowNoise(floor / ref_e**2, shot / ref_e**2, (ref_sd_e / ref_e) ** 2)


def spill_ratio(s: Scenario) -> float:
    """The share of a flow's light estimate that lands in the next flow's window,
    ``r = exp(−k_a·P)`` (k_a the apyrase rate, P the flow period): a flow's light decays as
    ``exp(−k_a t)`` (Salama et al. 2004, eq. 19), so window ``k + m`` gets ``r^m`` of what window
    ``k`` got, for the plain sum and for the matched filter alike (its weight in window ``k + m``
    is the same exponential restarted)."""
    a = s.assay
    return float(np.exp(-a.k_a_per_s * a.flow_period_s))


def despill(values: np.ndarray, r: float, key_n: np.ndarray) -> np.ndarray:
    """Undo the spill of each flow's light into the next windows, ``x_k = y_k − r·y_{k−1}``
    (the inverse of ``y_k = x_k + r·y_{k−1}``), then normalise again by the key's 1-mers."""
    x = values.copy()
    x[..., 1:] -= r * values[..., :-1]
    ref = x[..., : key_n.size][..., key_n == 1].mean(axis=-1)
    return x / np.where(ref > 0, ref, 1.0)[..., None]


def caller_input(s: Scenario, values: np.ndarray) -> np.ndarray:
    """The flow values the caller reads and the SFF stores: as normalised for ``round`` (today's
    caller); for ``dephase`` also freed of the light spilled from the previous flows."""
    if s.assay.caller != "dephase":
        return values
    key_n = pyro.key_flow_counts(s.assay.key, s.assay.flow_order)
    return despill(values, spill_ratio(s), key_n)


def call_reads(s: Scenario, values: np.ndarray, var_e2: np.ndarray, ref_e: np.ndarray,
               ref_sd_e: np.ndarray) -> list[Read]:
    """Every site's read by the scenario's caller (``[assay] caller``).

    ``values`` (n_sites, n_flows) as :func:`caller_input` gives them; ``var_e2``
    (n_flows, n_sites), the predicted variance of each flow's sum."""
    a = s.assay
    flows = flow_indices(a.flow_order, a.n_flows)
    key_n = pyro.key_flow_counts(a.key, a.flow_order)
    gain = 1.0 + spill_ratio(s) ** 2 if a.caller == "dephase" else 1.0  # x_k = y_k − r y_{k−1}

    def one(j: int) -> Read:
        y = np.asarray(values[j], dtype=np.float64)
        if not ref_e[j] > 0:
            y, noise = np.zeros_like(y), FlowNoise(1.0, 0.0, 0.0)
        else:
            noise = site_noise(var_e2[:, j] * gain, float(ref_e[j]), float(ref_sd_e[j]), key_n)
        return (call_dephased(y, flows, noise) if a.caller == "dephase"
                else call_rounded(y, flows, noise))

    # the caller's kernels release the GIL: reads in threads, each read's result independent of
    # the thread count (no random draws); both callers' qualities read the phasing model
    workers = min(available_cores(), len(values))
    if workers <= 1:
        return [one(j) for j in range(len(values))]
    with ThreadPoolExecutor(workers) as pool:
        return list(pool.map(one, range(len(values))))


def _stats(x: list[float]) -> dict[str, float]:
    v = np.asarray(x, dtype=np.float64)
    return {"median": float(np.median(v)), "mean": float(v.mean()), "min": float(v.min()),
            "p10": float(np.percentile(v, 10)), "p90": float(np.percentile(v, 90)),
            "max": float(v.max())}


def read_figures(s: Scenario, values: np.ndarray, reads: list[Read], true_n: np.ndarray
                 ) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """``summary['reads']`` and the arrays the SFF and the plots are made from."""
    a = s.assay
    calls = np.array([r.calls for r in reads])
    p_err = [r.base_error() for r in reads]
    quals = [phred(p) for p in p_err]
    sites = []
    truths = [read_stats.called_truth(true_n, r.n_called) for r in reads]
    key_n = key_counts(a.key, "".join(a.flow_order[k % len(a.flow_order)]
                                      for k in range(a.n_flows)))
    for j, r in enumerate(reads):
        row = read_stats.site_figures(r.calls, truths[j], p_err[j])
        row.update(id=j, incomplete_extension=r.eps, carry_forward=r.lam, droop_per_flow=r.droop,
                   gain=r.gain, key_pass=key_n is not None and passes_key(r.calls, key_n))
        if r.noise is not None:  # the caller's noise model: var = floor + shot·m + ref·m²
            row["noise"] = {"floor": r.noise.floor, "shot": r.noise.shot, "ref": r.noise.ref}
        sites.append(row)
    wrong = np.concatenate([read_stats.base_truth(r.calls, t) for r, t in zip(reads, truths,
                                                                               strict=True)])
    true_n = truths[0]  # every read calls the same flows
    pe, q = np.concatenate(p_err), np.concatenate(quals)
    bases = sum(x["bases"] for x in sites)
    errors = sum(x["errors"] for x in sites)
    template_bases = int(true_n.sum())
    summary = {
        "caller": a.caller,
        "n_reads": len(reads),
        "template_bases": template_bases,
        "q20_read_length": _stats([x["q20_read_length"] for x in sites]),
        "read_length_99": _stats([x["read_length_99"] for x in sites]),
        "chip_q20_bases": int(sum(x["q20_read_length"] for x in sites)),
        "sites_q20_at_least_200": int(sum(x["q20_read_length"] >= 200 for x in sites)),
        # the key-pass filter (454, Ion): reads.sff leaves out the reads whose first flows do
        # not spell the key; the figures here are every site's
        "key_fail_reads": int(sum(not x["key_pass"] for x in sites)),
        "errors": int(errors),
        "called_bases": int(bases),
        "read_accuracy": 1.0 - errors / max(sum(min(x["bases"], template_bases)
                                                 for x in sites), 1),
        "homopolymer_errors": read_stats.homopolymer_errors(calls, true_n),
        "accuracy_by_position": read_stats.accuracy_by_position(calls, true_n),
        "calibration": read_stats.calibration_table(wrong, pe, q),
        # the caller's input values by true homopolymer length, all the template's flows read
        "flow_value_by_length": read_stats.flow_value_by_length(values, truths[0]),
        # ... and phase-corrected by the caller's model, (y − leak) / in-phase share, over the
        # first 100 flows (25 cycles of a 4-base order, where a 454 read is still in phase)
        "corrected_flow_value_by_length": read_stats.flow_value_by_length(
            np.array([r.corrected if r.corrected is not None else v
                      for r, v in zip(reads, values, strict=True)]), truths[0],
            n_flows=CORRECTED_STATS_FLOWS),
        "phasing_estimated": {
            k: _stats([x[k] for x in sites]) for k in
            ("incomplete_extension", "carry_forward", "droop_per_flow")},
        "sites": sites,
        "sff": "reads.sff",
    }
    offsets = np.concatenate([[0], np.cumsum([x.size for x in quals])]).astype(np.int64)
    arrays = {
        "read_calls": calls.astype(np.int64),
        "read_flowgram_x100": np.clip(np.rint(np.maximum(values, 0.0) * 100), 0,
                                      SFF_MAX_X100).astype(np.uint16),
        "read_quality": q.astype(np.uint8),
        "read_quality_offsets": offsets,
        "read_true_n": np.asarray(true_n, dtype=np.int64),
    }
    return summary, arrays

