"""Reads of a pyrosequencing run: every site's flowgram called, with qualities and figures.

The flow values come normalised by the key's 1-mers
(:func:`chiptwin.kinetics.pyro.normalise_flows`). The noise the caller weighs each flow with is
the one the twin predicts for it: the DSP's propagated variance of each flow's window sum
(:func:`chiptwin.detection.window_sums`), read at the key's empty and single-base flows (the
floor and the shot noise per base), and the variance of the key's 1-mer reference itself, all in
units of that reference (:class:`chiptwin.detection.reads.FlowNoise`).

With a flow-value model (``[assay] chemistry`` or its keys,
:class:`chiptwin.kinetics.chemistry.FlowModel`) two things follow the chemistry, and only then
(a scene without one is called exactly as before):

* the key's 1-mer reference is the 1-mer's light alone: the model's additive light
  (``flow_background``, in 1-mers) rides on every flow, so dividing by the key's 1-mers reads an
  ``h``-mer as ``(h + a)/(1 + a)``; the values are multiplied back by ``1 + a``
  (:func:`key_scale`), so an ``h``-mer reads ``h + a`` as the model, fitted to 454's values,
  says it does (subtracting the key's empty flows instead, as ``normalise_flows`` can, would
  take the empty flows' own light, 0.07 of a 1-mer on FLX, off every flow and stretch the
  scale by 1/(1 − 0.07): a 4-mer would read 4.3);
* the noise the caller weighs a flow with adds the chemistry's own (:func:`site_noise`).

The empty flows' light stays in the values the dephase caller reads, and the caller estimates it
per read as a term of its model (:data:`chiptwin.detection.reads.EMPTY_LIGHT_GRID`): left out,
it read that light as carry-forward (λ 1.5 % for the scene's 1 %). Moving each read's 0-mer
level to 0 first instead (as :func:`chiptwin.detection.measured_reads.caller_input` does for
measured, already phase-corrected flowgrams) made ``pyro_454_flx``'s phased reads worse (read
accuracy 0.83 → 0.65–0.79); the model term made them better (0.83 → 0.87, Q20 length median
171.5 → 188).
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
from chiptwin.kinetics.chemistry import FlowModel
from chiptwin.kinetics.phasing import flow_indices
from chiptwin.pixel.chain import available_cores
from chiptwin.twin.stages import flow_model

#: Flows the phase-corrected flow-value statistics pool (summary ``reads``).
CORRECTED_STATS_FLOWS = 100

#: Largest flowgram value SFF stores: uint16 hundredths (454's Standard Flowgram Format).
SFF_MAX_X100 = 65535


def site_noise(var_e2: np.ndarray, ref_e: float, ref_sd_e: float, key_n: np.ndarray,
               model: FlowModel | None = None) -> FlowNoise:
    """The predicted noise of one site's normalised flow values.

    Parameters
    ----------
    var_e2 : (n_flows,) predicted variance of each flow's window sum, e⁻²
    ref_e : the key's 1-mer level, e⁻ (> 0)
    ref_sd_e : standard deviation of that level, e⁻
    key_n : expected counts of the key flows
    model : the scene's flow-value model, or None. Its terms in :class:`FlowNoise`'s
        ``floor + shot·m + ref·m²`` (averaged over the wells' noise levels, mean 1): the
        additive light's variance and the empty flows' own in ``floor`` (one floor for every
        flow: the empty flows' variance, 6 % of the additive one's on 454 FLX, is counted on
        the others too); the yield spread, a multiplicative factor of each flow's light, in
        ``ref``, with the error it leaves on the key's 1-mer scale (the mean of the key's K
        1-mers: ``(cv² + sd²)/K``). The dephase caller's rescale
        (:func:`chiptwin.detection.reads.rescale`) puts its own scale error in ``ref`` after
        its first pass: the yield spread then counts in that pass only.
    """
    zeros, ones = var_e2[: key_n.size][key_n == 0], var_e2[: key_n.size][key_n == 1]
    floor = float(zeros.mean()) if zeros.size else float(ones.min())
    shot = max(float(ones.mean()) - floor, 0.0)
    noise = FlowNoise(floor / ref_e**2, shot / ref_e**2, (ref_sd_e / ref_e) ** 2)
    if model is None:
        return noise
    cv2, sd2 = model.flow_yield_cv**2, model.flow_noise_sd**2
    k = int((key_n == 1).sum())
    return FlowNoise(noise.floor + sd2 + model.empty_flow_sd**2, noise.shot,
                     noise.ref + cv2 + (cv2 + sd2) / k)


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


def key_scale(s: Scenario) -> float:
    """The factor that turns values normalised by the key's 1-mers into 1-mers of incorporated
    light: ``1 + a``, ``a`` the flow-value model's additive light (``flow_background``, in
    1-mers, on every flow, the key's 1-mers too); 1 without a model (module docstring)."""
    model = flow_model(s)
    return 1.0 + model.flow_background if model is not None else 1.0


def caller_input(s: Scenario, values: np.ndarray) -> np.ndarray:
    """The flow values the caller reads and the SFF stores: as normalised for ``round`` (today's
    caller); for ``dephase`` also freed of the light spilled from the previous flows. With a
    flow-value model, scaled by :func:`key_scale`."""
    if s.assay.caller == "dephase":
        key_n = pyro.key_flow_counts(s.assay.key, s.assay.flow_order)
        values = despill(values, spill_ratio(s), key_n)
    scale = key_scale(s)
    return values * scale if scale != 1.0 else values


def call_reads(s: Scenario, values: np.ndarray, var_e2: np.ndarray, ref_e: np.ndarray,
               ref_sd_e: np.ndarray) -> list[Read]:
    """Every site's read by the scenario's caller (``[assay] caller``).

    ``values`` (n_sites, n_flows) as :func:`caller_input` gives them; ``var_e2``
    (n_flows, n_sites), the predicted variance of each flow's sum."""
    a = s.assay
    flows = flow_indices(a.flow_order, a.n_flows)
    key_n = pyro.key_flow_counts(a.key, a.flow_order)
    gain = 1.0 + spill_ratio(s) ** 2 if a.caller == "dephase" else 1.0  # x_k = y_k − r y_{k−1}
    model, scale = flow_model(s), key_scale(s)

    def one(j: int) -> Read:
        y = np.asarray(values[j], dtype=np.float64)
        if not ref_e[j] > 0:
            y, noise = np.zeros_like(y), FlowNoise(1.0, 0.0, 0.0)
        else:
            noise = site_noise(var_e2[:, j] * gain * scale**2, float(ref_e[j]),
                               float(ref_sd_e[j]), key_n, model)
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
    corrected = np.array([r.corrected if r.corrected is not None else v
                          for r, v in zip(reads, values, strict=True)], dtype=np.float64)
    p_err = [r.base_error() for r in reads]
    quals = [phred(p) for p in p_err]
    sites = []
    truths = [read_stats.called_truth(true_n, r.n_called) for r in reads]
    key_n = key_counts(a.key, "".join(a.flow_order[k % len(a.flow_order)]
                                      for k in range(a.n_flows)))
    for j, r in enumerate(reads):
        row = read_stats.site_figures(r.calls, truths[j], p_err[j])
        row.update(id=j, incomplete_extension=r.eps, carry_forward=r.lam, droop_per_flow=r.droop,
                   empty_flow_light=r.empty_light, gain=r.gain,
                   key_pass=key_n is not None and passes_key(r.calls, key_n))
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
            corrected, truths[0], n_flows=CORRECTED_STATS_FLOWS),
        "phasing_estimated": {
            k: _stats([x[k] for x in sites]) for k in
            ("incomplete_extension", "carry_forward", "droop_per_flow", "empty_flow_light")},
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
        # the caller's phase-corrected values (the input values where it corrects nothing)
        "read_corrected": corrected,
    }
    return summary, arrays

