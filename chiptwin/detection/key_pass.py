"""The key-pass filter, as 454 and Ion apply it: a read whose first flows do not spell the key
(the known prefix of every template, e.g. TCAG) is a failed read (no bead, two templates, a
dud), dropped from the reads and counted.

In flow space: every flow up to the key's last one must be called as the key puts bases in it;
the last may hold more, the read's first bases when they repeat the key's last base.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray


def key_counts(key: str, flow_order: str) -> NDArray[np.int64] | None:
    """Bases the key puts in each flow up to its last one (the last flow may also hold the
    read's first bases)."""
    out: list[int] = []
    i = 0
    for base in flow_order:
        n = 0
        while i < len(key) and key[i] == base:
            n, i = n + 1, i + 1
        out.append(n)
        if i == len(key):
            return np.array(out, dtype=np.int64)
    return None


def passes_key(calls: np.ndarray, key_n: np.ndarray) -> bool:
    """The calls spell the key: its flows as the key puts them, the last at least as many."""
    m = key_n.size
    if calls.size < m:
        return False
    return bool(np.array_equal(calls[:m - 1], key_n[:-1]) and calls[m - 1] >= key_n[-1])


__all__ = ["key_counts", "passes_key"]
