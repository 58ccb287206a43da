"""A called read against its truth, in base space: errors by kind, homopolymers, wrong bases.

The truth of a measured read is known as a sequence (the reference under an aligned read, a
FASTA template, or the instrument's own calls), not as a flowgram: a substitution or a variant
between sample and reference moves every later base to other flows, so flow-for-flow counting
(:mod:`chiptwin.detection.read_stats`) would charge a whole read for one base. Here the read is
aligned to its truth by edit distance (:func:`align`: unit costs, both starting at their first
base, either allowed to end first, the other's rest not scored), and

* the errors are counted by kind (:func:`error_counts`: mismatches, insertions, deletions);
* every homopolymer of the truth gets its called length (:func:`homopolymers`): the read bases
  matched to it plus those inserted beside them of the same base; a run of the read matched to
  no truth base is an over-called 0-mer; the truth's last run is left out (an aligned read's
  reference may end inside a run);
* every called base is marked right or wrong as its quality promises (:func:`wrong_bases`): as
  454 does, the last ``h − t`` bases of an over-called run are wrong, an under-called run's
  missing bases are charged to its last called base, and a truth run missed entirely (its bases
  deleted or miscalled) to the called base before the gap (the first base if the gap opens the
  read); a mismatched base is wrong itself.

Bases are compared as bytes; an ``N`` matches nothing.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from chiptwin.detection._align_kernels import (
    DELETION,
    INSERTION,
    MATCH,
    MISMATCH,
    align_kernel,
)

__all__ = ["DELETION", "INSERTION", "MATCH", "MISMATCH", "Alignment", "align", "error_counts",
           "homopolymers", "wrong_bases"]


@dataclass(frozen=True)
class Alignment:
    """Columns of a read against its truth: ``kind`` (:data:`MATCH` … :data:`DELETION`), and the
    read's and the truth's base index of each column (−1 where it has none). Columns on truth
    bases before ``scored_from`` are not scored (the truth's unknown head, e.g. a soft-clipped
    start given as the instrument's own calls)."""

    read: str
    truth: str
    kind: NDArray[np.int8]
    read_index: NDArray[np.int64]
    truth_index: NDArray[np.int64]
    scored_from: int = 0

    def scored(self) -> NDArray[np.bool_]:
        """Columns that count: on truth bases from ``scored_from`` on, and insertions after the
        first of them."""
        t = np.maximum.accumulate(np.where(self.truth_index >= 0, self.truth_index, -1))
        return (t >= self.scored_from) if self.scored_from else np.ones(self.kind.size, bool)

    @property
    def truth_covered(self) -> int:
        """Truth bases the read reaches (scored ones)."""
        t = self.truth_index[self.truth_index >= self.scored_from]
        return int(t.max()) + 1 - self.scored_from if t.size else 0


def _codes(seq: str) -> np.ndarray:
    a = np.frombuffer(seq.upper().encode("ascii"), dtype=np.uint8).astype(np.int64)
    return np.where(a == ord("N"), -1, a)


def align(read: str, truth: str, scored_from: int = 0) -> Alignment:
    """The edit-distance alignment of ``read`` to ``truth`` (module docstring).

    Parameters
    ----------
    read, truth : str
        Bases, in the same (flow) orientation; the truth starts where the read starts.
    scored_from : int
        Truth bases before this index are not scored (0 … len(truth)).
    """
    if not 0 <= scored_from <= len(truth):
        raise ValueError(f"scored_from = {scored_from}: must be in 0 … {len(truth)}")
    r, t = _codes(read), _codes(truth)
    t = np.where(t < 0, -2, t)  # N in the truth matches no N in the read either
    kind, ri, ti = align_kernel(r, t)
    return Alignment(read, truth, kind, ri, ti, scored_from)


def error_counts(a: Alignment) -> dict[str, int]:
    """Mismatches, insertions and deletions over the scored columns, and the truth bases the
    read covers there."""
    k = a.kind[a.scored()]
    return {"truth_bases": a.truth_covered, "mismatches": int(np.sum(k == MISMATCH)),
            "insertions": int(np.sum(k == INSERTION)), "deletions": int(np.sum(k == DELETION)),
            "errors": int(np.sum(k != MATCH))}


def _runs(seq: str) -> tuple[np.ndarray, np.ndarray]:
    """(start, length) of every homopolymer run of ``seq``."""
    if not seq:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    s = np.frombuffer(seq.upper().encode("ascii"), dtype=np.uint8)
    starts = np.flatnonzero(np.r_[True, s[1:] != s[:-1]])
    return starts, np.diff(np.r_[starts, s.size])


def _run_maps(a: Alignment) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each read run's truth run (−1: matched to none), the truth run of each truth base, the
    read run of each read base, and each read base's column."""
    rs, rl = _runs(a.read)
    ts, tl = _runs(a.truth)
    read_run = np.repeat(np.arange(rs.size), rl)
    truth_run = np.repeat(np.arange(ts.size), tl)
    col_of_read = np.full(len(a.read), -1, np.int64)
    on_read = a.read_index >= 0
    col_of_read[a.read_index[on_read]] = np.flatnonzero(on_read)
    mapped = np.full(rs.size, -1, np.int64)
    m = a.kind == MATCH
    # a read run matched to two truth runs of its base (the base between them lost) keeps the
    # first: the later one counts as missed, its loss charged beside the gap
    for r_run, t_run in zip(read_run[a.read_index[m]][::-1], truth_run[a.truth_index[m]][::-1],
                            strict=True):
        mapped[r_run] = t_run
    return mapped, truth_run, read_run, col_of_read


def homopolymers(a: Alignment) -> list[tuple[int, int]]:
    """(true length, called length) of every scored truth run the read reaches, and (0, h) for
    every read run matched to no truth base (an over-called 0-mer of h bases)."""
    mapped, truth_run, read_run, _ = _run_maps(a)
    _, tl = _runs(a.truth)
    cols = a.scored()
    scored_read = np.zeros(len(a.read), bool)
    scored_read[a.read_index[cols & (a.read_index >= 0)]] = True
    rl = (np.bincount(read_run, weights=scored_read, minlength=mapped.size).astype(np.int64)
          if read_run.size else np.zeros(0, np.int64))
    called = np.zeros(tl.size, np.int64)
    for r_run in np.flatnonzero(mapped >= 0):
        called[mapped[r_run]] += rl[r_run]
    reached = np.zeros(tl.size, bool)
    reached[truth_run[a.truth_index[cols & (a.truth_index >= 0)]]] = True
    first = truth_run[a.scored_from] if a.scored_from < len(a.truth) else tl.size
    # the truth's last run may be cut by the truth's end (an alignment ends mid-run)
    out = [(int(tl[k]), int(called[k])) for k in range(first, tl.size - 1) if reached[k]]
    for r_run in np.flatnonzero((mapped < 0) & (rl > 0)):
        out.append((0, int(rl[r_run])))
    return out


def wrong_bases(a: Alignment) -> NDArray[np.bool_]:
    """Whether each read base is wrong by the quality's convention (module docstring); bases
    past the truth's end, or before ``scored_from``, are not wrong."""
    n = len(a.read)
    wrong = np.zeros(n, bool)
    if n == 0:
        return wrong
    mapped, truth_run, read_run, _ = _run_maps(a)
    ts, tl = _runs(a.truth)
    scored = a.scored()
    counted = np.zeros(n, bool)
    counted[a.read_index[scored & (a.read_index >= 0)]] = True
    wrong[a.read_index[(a.kind == MISMATCH) & scored]] = True
    lo = np.r_[0, np.flatnonzero(np.diff(read_run)) + 1]
    h = np.add.reduceat(counted.astype(np.int64), lo)  # the run's bases inside the alignment
    end = lo + h
    t = np.where(mapped >= 0, tl[np.maximum(mapped, 0)] if tl.size else 0, 0)
    excess = np.where(h > t, h - t, 0)  # over-calls: the run's last bases
    first = np.repeat(end - excess, excess)
    wrong[first + np.arange(first.size) - np.repeat(np.cumsum(excess) - excess, excess)] = True
    # under-calls: the last called base (not the truth's last run: its end may be cut)
    under = (h > 0) & (h < t) & (mapped != tl.size - 1)
    wrong[end[under] - 1] = True
    # truth runs with no read run mapped to them, inside the reached and scored truth
    hit = np.zeros(tl.size, bool)
    hit[mapped[mapped >= 0]] = True
    reach = a.truth_index[scored & (a.truth_index >= 0)]
    if reach.size:
        runs = np.arange(truth_run[reach.min()], truth_run[reach.max()] + 1)
        missed = runs[~hit[runs]]
        if missed.size:
            # the read base of the last column before each missed run's first base (the
            # read's first base when none comes before)
            last_read = np.maximum.accumulate(np.where(a.read_index >= 0, a.read_index, -1))
            col_of_truth = np.full(len(a.truth), -1, np.int64)
            on = a.truth_index >= 0
            col_of_truth[a.truth_index[on]] = np.flatnonzero(on)
            col = col_of_truth[ts[missed]]
            before = np.where(col > 0, last_read[np.maximum(col - 1, 0)], -1)
            wrong[np.maximum(before, 0)] = True
    return wrong
