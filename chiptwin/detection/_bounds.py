"""Bounds the hill climb (:func:`chiptwin.detection._read_kernels.polish_kernel`) drops
candidates on before scoring them to the read's end: how far the flows left can move a
candidate's likelihood from the current calls', given how much of the two strand populations
(Eltoukhy & El Gamal, ICASSP 2006) still differ. Each is an upper bound, never an estimate: a
candidate is dropped only when the exact sum could not have won either (tests: drawn reads,
the exact flowgrams of both call sets, ``tests/detection/test_leak_bound.py``).

A flow's term of the negative log-likelihood, ``f(s) = (y − s)²/2v(s) + log v(s)/2`` (prior
apart: the same for both call sets where their flow programs agree), moves by at most
``g·|Δs|`` when its light moves by ``Δs`` within ``span``, ``g`` the slope bound of
:func:`slope_at`.
"""

from __future__ import annotations

import numpy as np

from chiptwin._numba import NJIT, NJIT_NORC

#: The spans of light (bases per starting strand) :func:`slopes_from` bounds the slopes over;
#: a candidate's light moved by more than the last is not bounded (scored on).
SPANS = np.array([0.01, 0.1, 1.0])

#: The most light (summed over the flows left) a run resized may still move for
#: :func:`leak_left`'s bound to be used: the first span.
LEAK_SPAN = 0.01


@NJIT
def slope_at(yk: float, sk: float, floor: float, shot: float, ref: float,
             span: float) -> float:  # pragma: no cover - compiled
    """The largest ``|f'(s)|`` of one flow over ``|s − sk| ≤ span``: with ``|y − s| ≤ r``,
    ``v ≥ v_lo`` and ``v' ≤ w`` there (``v`` rises with ``s``), ``|f'| ≤ r/v_lo + r²w/2v_lo² +
    w/2v_lo``."""
    s_lo, s_hi = max(sk - span, 0.0), max(sk + span, 0.0)
    v_lo = floor + shot * s_lo + ref * s_lo * s_lo
    w = shot + 2.0 * ref * s_hi
    r = abs(yk - sk) + span
    return r / v_lo + 0.5 * r * r * w / (v_lo * v_lo) + 0.5 * w / v_lo


@NJIT
def slopes_from(y: np.ndarray, signal: np.ndarray, floor: float, shot: float, ref: float,
                k0: int, g: np.ndarray) -> None:  # pragma: no cover - compiled
    """``g[i, j]``: the slope bound (:func:`slope_at`, span ``SPANS[i]``) of each flow
    ``j ≥ k0``; the flows before ``k0`` keep theirs (their light has not changed)."""
    for i in range(SPANS.size):
        for j in range(k0, y.size):
            g[i, j] = slope_at(y[j], signal[j], floor, shot, ref, SPANS[i])


@NJIT
def prefix_bounds(g: np.ndarray, pre: np.ndarray, lip: np.ndarray,
                  k0: int) -> None:  # pragma: no cover - compiled
    """From the slopes ``g`` (:func:`slopes_from`): ``pre[i, k] = Σ_{j < k} g[i, j]``, so that
    light moved by at most ``e ≤ SPANS[i]`` in every flow moves the terms of flows ``k`` on by at
    most ``e·(pre[i, n] − pre[i, k])``, rewritten from ``k0`` on (the sums below it keep theirs,
    as :func:`slopes_from` keeps their slopes); and ``lip[k] = max_{j ≥ k} g[0, j]`` (light
    moved by ``Δ_j`` with ``Σ|Δ_j| ≤`` :data:`LEAK_SPAN` moves them by at most
    ``lip[k]·Σ|Δ_j|``)."""
    n = g.shape[1]
    for i in range(g.shape[0]):
        acc = pre[i, k0]
        for k in range(k0, n):
            acc += g[i, k]
            pre[i, k + 1] = acc
    lip[n] = 0.0
    top = 0.0
    for k in range(n - 1, -1, -1):
        top = max(g[0, k], top)
        lip[k] = top


@NJIT_NORC
def leak_left(state: np.ndarray, scale: np.ndarray, buf: np.ndarray,
              d0: int) -> float:  # pragma: no cover - compiled
    """Share of the strands (times the droop scale) at template positions ``≤ d0`` in a model's
    current state: an upper bound of the light a run starting at ``d0`` lengthened or shortened
    by one base still changes, summed over the flows to come.

    Why: strands only ever stand at the ends of runs, so the two templates' strand populations
    are the same, position for position once those after the run are shifted by one (the same
    arithmetic, so the same bits); each flow's light differs by the share that crosses the
    changed run in that flow (one base more or less each), and every strand crosses it once.
    Strands dropped as negligible never cross, so the sum can only be smaller."""
    lo, hi, cur = state[0], min(state[1], d0), state[4]
    m = 0.0
    for p in range(lo, hi + 1):
        m += buf[cur, p]
    return m * scale[0]


@NJIT_NORC
def apart(cur: np.ndarray, lo_c: int, hi_c: int, new: np.ndarray, lo_n: int, hi_n: int,
          past_c: int, past_n: int) -> float:  # pragma: no cover - compiled
    """How much two strand populations can still differ, now and in every later flow: the
    shares not yet past the change (positions below ``past_c`` in the current template's
    population ``cur[lo_c..hi_c]``, below ``past_n`` in the candidate's ``new[lo_n..hi_n]``),
    both counted whole, plus ``Σ|new − cur|`` over the positions past it (``p`` of the current
    template is ``p + past_n − past_c`` of the candidate's: the templates agree from there).

    Why it bounds every later flow: strands past the change read the same template in both, so
    the same flows move both populations alike, and the difference there never grows (the flow
    step is linear and loses no strands but the held-back tails); strands not yet past it add
    at most their own share, wherever they go. A flow's light then differs by at most this
    times the most bases one strand adds in a flow, plus the strands dropped as negligible."""
    t = 0.0
    for p in range(lo_c, min(hi_c, past_c - 1) + 1):
        t += cur[p]
    for p in range(lo_n, min(hi_n, past_n - 1) + 1):
        t += new[p]
    shift = past_n - past_c
    start = max(past_c, min(lo_c, lo_n - shift))
    for p in range(start, max(hi_c, hi_n - shift) + 1):
        a = cur[p] if lo_c <= p <= hi_c and p >= past_c else 0.0
        q = p + shift
        b = new[q] if lo_n <= q <= hi_n and q >= past_n else 0.0
        t += abs(b - a)
    return t

