"""numba kernel behind :mod:`chiptwin.detection.align`: a read against its truth by edit
distance, both starting together, either one allowed to end first.

Arrays and scalars in, arrays out; no validation (:func:`chiptwin.detection.align.align` checks
once). The slow obvious reference is in ``tests/detection/test_align.py``.
"""

from __future__ import annotations

import numpy as np

from chiptwin._numba import NJIT

MATCH, MISMATCH, INSERTION, DELETION = 0, 1, 2, 3
"""Column kinds of an alignment: a read base on an equal truth base, on another one, a read
base with no truth base (an insertion), a truth base with no read base (a deletion)."""


@NJIT
def edit_table(read: np.ndarray, truth: np.ndarray) -> np.ndarray:  # pragma: no cover
    """``d[i, j]``: the fewest edits turning ``read[:i]`` into ``truth[:j]`` (unit costs)."""
    n, m = read.size, truth.size
    d = np.empty((n + 1, m + 1), dtype=np.int32)
    for j in range(m + 1):
        d[0, j] = j
    for i in range(1, n + 1):
        d[i, 0] = i
        r = read[i - 1]
        for j in range(1, m + 1):
            best = d[i - 1, j - 1] + (0 if r == truth[j - 1] else 1)
            best = min(best, d[i - 1, j] + 1, d[i, j - 1] + 1)
            d[i, j] = best
    return d


@NJIT
def align_kernel(read: np.ndarray, truth: np.ndarray) -> tuple:  # pragma: no cover - compiled
    """(kind, read index, truth index) per column of the best alignment that starts both
    sequences at their first base and ends where either has run out (the other's rest is not
    scored); the index is −1 where the column has no base of that sequence. Of equal ends the
    one covering more of the truth wins; the trace prefers a diagonal step, then a deletion."""
    n, m = read.size, truth.size
    d = edit_table(read, truth)
    bi, bj = n, 0  # the read run out ...
    for j in range(m + 1):
        if d[n, j] < d[bi, bj] or (d[n, j] == d[bi, bj] and j > bj):
            bi, bj = n, j
    for i in range(n + 1):  # ... or the truth, sooner
        if d[i, m] < d[bi, bj] or (d[i, m] == d[bi, bj] and (m > bj or i > bi)):
            bi, bj = i, m
    size = bi + bj
    kind = np.empty(size, dtype=np.int8)
    ri = np.empty(size, dtype=np.int64)
    ti = np.empty(size, dtype=np.int64)
    i, j, c = bi, bj, size
    while i > 0 or j > 0:
        c -= 1
        if i > 0 and j > 0 and d[i, j] == d[i - 1, j - 1] + (0 if read[i - 1] == truth[j - 1]
                                                               else 1):
            kind[c] = MATCH if read[i - 1] == truth[j - 1] else MISMATCH
            i -= 1
            j -= 1
            ri[c], ti[c] = i, j
        elif j > 0 and d[i, j] == d[i, j - 1] + 1:
            kind[c] = DELETION
            j -= 1
            ri[c], ti[c] = -1, j
        else:
            kind[c] = INSERTION
            i -= 1
            ri[c], ti[c] = i, -1
    return kind[c:], ri[c:], ti[c:]
