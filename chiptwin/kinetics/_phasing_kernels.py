"""numba kernel behind :func:`chiptwin.kinetics.phasing.phased_signal`.

Arrays and scalars in, arrays out; no validation (the public wrapper checks once). The slow,
obvious reference is :func:`chiptwin.kinetics.phasing.phased_flows` (tests compare the two).
"""

from __future__ import annotations

import numpy as np

from chiptwin._numba import NJIT

#: Strand shares below this are dropped from the lagging and leading tails: each flow drops at
#: most a few 1e-9 of the strands, so a flow value moves by < 1e-5 of a base over 1,000 flows,
#: far below any flow's noise (the tails, else, spread over the whole template under λ).
TINY = 1e-9


@NJIT
def run_table(tmpl: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """``run[j, b]``: length of the homopolymer of base ``b`` starting at position ``j``."""
    n_pos = tmpl.size
    run = np.zeros((n_pos + 1, 4), dtype=np.int64)
    for j in range(n_pos - 1, -1, -1):
        run[j, tmpl[j]] = run[j + 1, tmpl[j]] + 1
    return run


@NJIT
def phase_flows(tmpl: np.ndarray, flows: np.ndarray, eps: float, lam: float,
                droop: float) -> tuple:  # pragma: no cover - compiled
    """The phased, drooping flowgram of one strand population starting at position 0.

    Parameters
    ----------
    tmpl : int64 (L,)
        Template bases as indices into ``ACGT``.
    flows : int64 (n,)
        Base index dispensed in each flow.
    eps, lam : float
        Incomplete extension and carry-forward per flow (Eltoukhy & El Gamal, ICASSP 2006).
    droop : float
        Share of the active template lost in each flow.

    Returns
    -------
    signal : float64 (n,)
        Bases added per starting strand in each flow, times ``(1 - droop)**k``.
    in_phase : float64 (n,)
        The weight of the in-phase homopolymer in ``signal``: ``(1 - eps)`` times the share of
        strands at the ideal position before flow ``k``, times ``(1 - droop)**k``; so
        ``signal - in_phase * ideal`` is the out-of-phase leak.
    ideal : int64 (n,)
        Bases the ideal (unphased) program adds in each flow.
    """
    n_pos = tmpl.size
    run = run_table(tmpl)
    dist = np.zeros(n_pos + 1)
    new = np.zeros(n_pos + 1)
    dist[0] = 1.0
    n = flows.size
    signal = np.zeros(n)
    in_phase = np.zeros(n)
    ideal = np.zeros(n, dtype=np.int64)
    lo, hi, pos, prev, scale = 0, 0, 0, -1, 1.0
    for k in range(n):
        x = flows[k]
        ideal[k] = run[pos, x]
        in_phase[k] = (1.0 - eps) * dist[pos] * scale
        bases = 0.0
        new_hi = hi
        for j in range(lo, hi + 1):
            d = dist[j]
            if d == 0.0:
                continue
            held = eps * d
            active = d - held
            carry = lam * active if prev >= 0 else 0.0
            normal = active - carry
            r = run[j, x]
            new[j] += held
            new[j + r] += normal
            bases += normal * r
            if j + r > new_hi:
                new_hi = j + r
            if carry > 0.0:
                r2 = run[j + r, prev]
                new[j + r + r2] += carry
                bases += carry * (r + r2)
                if j + r + r2 > new_hi:
                    new_hi = j + r + r2
        signal[k] = bases * scale
        tmp = dist
        dist = new
        new = tmp
        new[lo:hi + 1] = 0.0
        hi = new_hi
        while lo < hi and dist[lo] < TINY:
            dist[lo] = 0.0  # a share below TINY of the strands: dropped, not carried
            lo += 1
        while hi > lo and dist[hi] < TINY:
            dist[hi] = 0.0
            hi -= 1
        pos += ideal[k]
        prev = x
        scale *= 1.0 - droop
    return signal, in_phase, ideal
