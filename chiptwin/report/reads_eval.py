"""The figures of a set of calls on measured reads, against their truth or against the
instrument's calls: the same for the twin's callers and for the instrument's own.

Against a truth (:func:`against_truth`), as the field judges a sequencer: the errors by kind per
truth base (:func:`chiptwin.detection.align.error_counts`), the called length of every truth
homopolymer (right, under-called, over-called), the read length at 99 % accuracy, the read
length at Q20 from the stated qualities alone, and the calibration of those qualities (bases
binned by stated quality, wrong as :func:`chiptwin.detection.align.wrong_bases` says).
Without one (:func:`against_instrument`), how far the calls agree with the instrument's: its
stored bases as the reference, an ``N`` it stored agreeing with nothing.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from chiptwin.detection import align as al
from chiptwin.detection import read_stats

#: Longest true homopolymer given its own row; longer runs share the last row.
MAX_ROW = 8


@dataclass(frozen=True)
class Calls:
    """One caller's reads after the key, in flow order: bases, phred qualities and the error
    probability each quality states; ``None`` for a read the caller dropped (key-pass)."""

    label: str
    bases: list[str | None]
    quality: list[np.ndarray | None]
    p_error: list[np.ndarray | None]

    @classmethod
    def of_instrument(cls, bases: list[str], quality: list[np.ndarray]) -> Calls:
        p = [10.0 ** (-np.asarray(q, dtype=np.float64) / 10.0) for q in quality]
        return cls("instrument", list(bases), list(quality), p)


def stats(x: list[float]) -> dict[str, float]:
    """Median, mean, extremes and the 10th and 90th percentiles ({} when empty)."""
    if not x:
        return {}
    v = np.asarray(x, dtype=np.float64)
    return {"median": float(np.median(v)), "mean": float(v.mean()), "min": float(v.min()),
            "p10": float(np.percentile(v, 10)), "p90": float(np.percentile(v, 90)),
            "max": float(v.max())}


def length_at_accuracy(a: al.Alignment, max_error: float = read_stats.Q20_ERROR) -> int:
    """Most read bases from the start whose errors (scored columns) are ≤ ``max_error`` of
    them, counted at the end of a column."""
    scored = a.scored()
    bases = np.cumsum(a.read_index >= 0)
    errors = np.cumsum(scored & (a.kind != al.MATCH))
    ok = (bases > 0) & (errors <= max_error * bases) & scored
    return int(bases[ok].max()) if ok.any() else 0


def _homopolymer_rows(pairs: list[tuple[int, int]]) -> list[dict[str, Any]]:
    rows = []
    t = np.array([p[0] for p in pairs], dtype=np.int64)
    h = np.array([p[1] for p in pairs], dtype=np.int64)
    for n in range(1, MAX_ROW + 1):
        m = (t == n) if n < MAX_ROW else (t >= n)
        k = int(m.sum())
        if not k:
            continue
        right, under, over = (int(np.sum(h[m] == t[m])), int(np.sum(h[m] < t[m])),
                              int(np.sum(h[m] > t[m])))
        rows.append({"length": n if n < MAX_ROW else f"{n}+", "runs": k, "right": right,
                     "under_calls": under, "over_calls": over, "accuracy": right / k})
    inserted = h[t == 0]
    rows.append({"length": 0, "runs": None, "right": None, "under_calls": 0,
                 "over_calls": int(inserted.size), "accuracy": None,
                 "inserted_bases": int(inserted.sum())})
    return rows


def against_truth(calls: Calls, truths: list[str | None], truth_from: list[int]
                  ) -> dict[str, Any]:
    """The figures of ``calls`` against each read's truth (module docstring); reads without a
    truth or without calls are left out."""
    totals = dict.fromkeys(("truth_bases", "mismatches", "insertions", "deletions", "errors"), 0)
    pairs: list[tuple[int, int]] = []
    wrong, p_err, qual, q20, l99 = [], [], [], [], []
    n = 0
    for bases, q, p, truth, skip in zip(calls.bases, calls.quality, calls.p_error, truths,
                                        truth_from, strict=True):
        if bases is None or truth is None:
            continue
        n += 1
        a = al.align(bases, truth, skip)
        for k, v in al.error_counts(a).items():
            totals[k] += v
        pairs += al.homopolymers(a)
        w = al.wrong_bases(a)
        counted = np.zeros(len(bases), bool)
        counted[a.read_index[a.scored() & (a.read_index >= 0)]] = True
        wrong.append(w[counted])
        p_err.append(p[counted])
        qual.append(q[counted])
        q20.append(read_stats.length_at_quality(p))
        l99.append(length_at_accuracy(a))
    tb = max(totals["truth_bases"], 1)
    out: dict[str, Any] = {
        "caller": calls.label, "reads": n, **totals,
        "error_rate": totals["errors"] / tb, "accuracy": 1.0 - totals["errors"] / tb,
        **{f"{k}_rate": totals[k] / tb for k in ("mismatches", "insertions", "deletions")},
        "homopolymers": _homopolymer_rows(pairs),
        "q20_read_length": stats(q20), "read_length_99": stats(l99),
        "q20_bases": int(sum(q20)),
    }
    if n:
        w, p, q = np.concatenate(wrong), np.concatenate(p_err), np.concatenate(qual)
        out["calibration"] = read_stats.calibration_table(w, p, q.astype(np.int64))
    return out


def against_instrument(calls: Calls, instrument: Calls) -> dict[str, Any]:
    """How far ``calls`` agree with the instrument's stored bases, read by read over the
    instrument's length (an ``N`` it stored agrees with nothing)."""
    totals = dict.fromkeys(("truth_bases", "mismatches", "insertions", "deletions", "errors"), 0)
    q20, n = [], 0
    for bases, p, ref in zip(calls.bases, calls.p_error, instrument.bases, strict=True):
        if bases is None or not ref:
            continue
        n += 1
        for k, v in al.error_counts(al.align(bases, ref)).items():
            totals[k] += v
        q20.append(read_stats.length_at_quality(p))
    tb = max(totals["truth_bases"], 1)
    return {"caller": calls.label, "reads": n, "instrument_bases": totals.pop("truth_bases"),
            **{f"differing_{k}": v for k, v in totals.items()},
            "agreement": 1.0 - totals["errors"] / tb,
            "q20_read_length": stats(q20), "q20_bases": int(sum(q20))}


def instrument_q20(instrument: Calls) -> dict[str, Any]:
    """The instrument's own read length at Q20, from its stated qualities."""
    q20 = [read_stats.length_at_quality(p) for p in instrument.p_error if p is not None]
    return {"q20_read_length": stats(q20), "q20_bases": int(sum(q20))}
