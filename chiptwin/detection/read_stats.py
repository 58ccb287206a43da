"""Figures of merit of pyrosequencing reads, as the field measures a sequencer.

Errors are counted in flow space, where the called and the true flowgram align flow for flow:
a flow called ``c`` for a true homopolymer of ``t`` bases carries ``|c − t|`` errors (insertions
when ``c > t``, deletions when ``c < t``; pyrosequencing makes no substitutions in one flow).

* read length at 99 % accuracy: the most called bases, at a flow boundary, whose errors are at
  most 1 % of them (measured against the template);
* read length at Q20: the same from the stated qualities alone, the most bases whose summed
  error probability is at most 1 % of them (what an instrument reports without a reference;
  phred, Ewing & Green, Genome Res. 8:186, 1998);
* error rate by homopolymer length (over- and under-calls), accuracy against read position, and
  the calibration of the qualities (bases binned by stated quality, the observed error rate with
  its Clopper–Pearson interval).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from chiptwin.detection.stats import clopper_pearson

#: Accuracy of the "99 %" and "Q20" read lengths: one error in 100 bases.
Q20_ERROR = 0.01

#: Read-position bins of the accuracy curve (bases).
POSITION_BIN = 25

#: Stated-quality bins of the calibration table: [lo, hi) phred.
QUALITY_BINS = ((0, 10), (10, 15), (15, 20), (20, 25), (25, 30), (30, 35), (35, 41))


def called_truth(true_n: np.ndarray, n_called: int | None) -> np.ndarray:
    """The true counts of the flows a read calls (those after ``n_called`` set to 0): a caller
    that leaves a flowgram's last flows uncalled is judged on the flows it calls."""
    t = np.array(true_n, dtype=np.int64)
    if n_called is not None:
        t[n_called:] = 0
    return t


def flow_errors(calls: np.ndarray, true_n: np.ndarray) -> np.ndarray:
    """``|c − t|`` per flow."""
    return np.abs(np.asarray(calls, dtype=np.int64) - np.asarray(true_n, dtype=np.int64))


def length_at_accuracy(calls: np.ndarray, true_n: np.ndarray, max_error: float = Q20_ERROR
                       ) -> int:
    """Most called bases (at a flow boundary) with errors ≤ ``max_error`` of them."""
    c = np.cumsum(calls)
    e = np.cumsum(flow_errors(calls, true_n))
    ok = (c > 0) & (e <= max_error * c)
    return int(c[ok].max()) if ok.any() else 0


def length_at_quality(p_error: np.ndarray, max_error: float = Q20_ERROR) -> int:
    """Most bases whose summed error probability is ≤ ``max_error`` of them."""
    if p_error.size == 0:
        return 0
    n = np.arange(1, p_error.size + 1)
    ok = np.cumsum(p_error) <= max_error * n
    return int(n[ok].max()) if ok.any() else 0


def base_truth(calls: np.ndarray, true_n: np.ndarray) -> np.ndarray:
    """Whether each called base is wrong, by the quality's convention (454's): base ``i`` of a
    called ``h``-mer is wrong when the true length is below ``i``; an under-call charges the
    run's last base, a run missed entirely (a flow called 0 whose truth is not) the base before
    the gap (the read's first base when none is)."""
    calls = np.asarray(calls, dtype=np.int64)
    out = []
    for k in np.flatnonzero(calls):
        h, t = int(calls[k]), int(true_n[k])
        i = np.arange(1, h + 1)
        out.append((t < i) | ((i == h) & (t > h)))
    wrong = np.concatenate(out) if out else np.zeros(0, dtype=bool)
    missed = np.flatnonzero((calls == 0) & (np.asarray(true_n) > 0))
    if wrong.size and missed.size:
        wrong[np.maximum(np.cumsum(calls)[missed] - 1, 0)] = True
    return wrong


def site_figures(calls: np.ndarray, true_n: np.ndarray, p_error: np.ndarray) -> dict[str, Any]:
    """One read's figures: bases, errors within the template's flows, accuracy, lengths."""
    last = int(np.flatnonzero(true_n)[-1]) + 1 if np.any(true_n) else 0
    errors = int(flow_errors(calls[:last], true_n[:last]).sum())
    bases = int(np.sum(calls[:last]))
    return {"bases": int(np.sum(calls)), "template_bases": int(np.sum(true_n)),
            "errors": errors, "accuracy": 1.0 - errors / max(bases, 1),
            "q20_read_length": length_at_quality(p_error),
            "read_length_99": length_at_accuracy(calls, true_n),
            "mean_quality": float(np.mean(-10 * np.log10(np.maximum(p_error, 1e-4))))
            if p_error.size else 0.0}


def homopolymer_errors(calls: np.ndarray, true_n: np.ndarray) -> list[dict[str, Any]]:
    """Over- and under-call rates per true homopolymer length, over the template's flows of
    every read (``calls`` (n_reads, n_flows))."""
    last = int(np.flatnonzero(true_n)[-1]) + 1 if np.any(true_n) else 0
    c, t = calls[:, :last], np.broadcast_to(true_n[:last], calls[:, :last].shape)
    rows = []
    for n in range(int(true_n.max(initial=0)) + 1):
        m = t == n
        k = int(m.sum())
        if not k:
            continue
        over, under = int((c[m] > n).sum()), int((c[m] < n).sum())
        rows.append({"length": n, "flows": k, "over_calls": over, "under_calls": under,
                     "over_rate": over / k, "under_rate": under / k,
                     "error_rate": (over + under) / k})
    return rows


def accuracy_by_position(calls: np.ndarray, true_n: np.ndarray, bin_bases: int = POSITION_BIN
                         ) -> dict[str, list]:
    """Accuracy in bins of read position: errors of each flow placed at the read position of
    its first called base (a deletion where the base is missing), pooled over reads, up to the
    template's length."""
    length = int(true_n.sum())
    n_bins = max(1, -(-length // bin_bases))
    err, bases = np.zeros(n_bins), np.zeros(n_bins)
    for row in calls:
        pos = np.concatenate([[0], np.cumsum(row)[:-1]])
        keep = pos < length
        np.add.at(err, pos[keep] // bin_bases, flow_errors(row, true_n)[keep])
        called = min(int(row.sum()), length)
        bases += np.bincount(np.arange(called) // bin_bases, minlength=n_bins)[:n_bins]
    acc = np.where(bases > 0, 1.0 - err / np.maximum(bases, 1), np.nan)
    return {"bin_start": (np.arange(n_bins) * bin_bases).tolist(),
            "bases": bases.astype(int).tolist(), "errors": err.astype(int).tolist(),
            "accuracy": [None if np.isnan(a) else float(a) for a in acc]}


def calibration_table(wrong: np.ndarray, p_error: np.ndarray, quality: np.ndarray,
                      confidence: float = 0.95) -> list[dict[str, Any]]:
    """Bases binned by stated quality: the stated and observed error rates, the observed one
    with its two-sided Clopper–Pearson interval, and whether the stated rate lies inside."""
    rows = []
    for lo, hi in QUALITY_BINS:
        m = (quality >= lo) & (quality < hi)
        n = int(m.sum())
        if not n:
            continue
        k = int(wrong[m].sum())
        low, high = clopper_pearson(k, n, confidence)
        stated = float(p_error[m].mean())
        rows.append({"q_lo": lo, "q_hi": hi, "bases": n, "errors": k, "stated_error": stated,
                     "observed_error": k / n, "ci_low": low, "ci_high": high,
                     "calibrated": bool(low <= stated <= high)})
    return rows


def flow_value_by_length(values: np.ndarray, true_n: np.ndarray, n_flows: int | None = None,
                         max_length: int = 8) -> list[dict[str, Any]]:
    """Mean and standard deviation of the flow value per true homopolymer length, pooled over
    reads (``values`` (n_reads, n_flows)) and the template's flows (the first ``n_flows`` of
    them if given): the statistic Balzer et al. (Bioinformatics 26:i420, 2010) measured on 454
    runs."""
    last = int(np.flatnonzero(true_n)[-1]) + 1 if np.any(true_n) else 0
    if n_flows is not None:
        last = min(last, n_flows)
    v, t = values[:, :last], np.broadcast_to(true_n[:last], values[:, :last].shape)
    rows = []
    for n in range(max_length + 1):
        x = v[t == n]
        if x.size >= 2:
            rows.append({"length": n, "flows": int(x.size), "mean": float(x.mean()),
                         "sd": float(x.std(ddof=1))})
    return rows
