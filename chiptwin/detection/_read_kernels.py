"""numba kernels behind :mod:`chiptwin.detection.reads`: the posterior of each flow's call and
the left-to-right dephasing sweep.

Arrays and scalars in, arrays out; no validation (the public functions check once). The numpy
reference of each is in ``tests/detection/test_reads.py``.
"""

from __future__ import annotations

import math

import numpy as np

from chiptwin._numba import NJIT
from chiptwin.kinetics._phasing_kernels import phase_flows


@NJIT
def template_of(calls: np.ndarray, flows: np.ndarray) -> np.ndarray:  # pragma: no cover
    """The template the calls spell, as base indices."""
    out = np.empty(calls.sum(), dtype=np.int64)
    p = 0
    for k in range(calls.size):
        for _ in range(calls[k]):
            out[p] = flows[k]
            p += 1
    return out


#: Bounds of the contextual prior P(h > 0): a call the flow order forbids is improbable, not
#: impossible (the calls it is conditioned on may be wrong).
P_POS_MIN = 0.1


@NJIT
def context_prior(calls: np.ndarray, flows: np.ndarray, comp: np.ndarray,
                  n_bases: int) -> np.ndarray:  # pragma: no cover - compiled
    """P(h_k > 0) from the flows since the last called base: the next homopolymer's base is
    not the last one's and none dispensed since (those would have extended), so its share is
    ``comp[X_k]`` over the remaining bases' composition."""
    n = calls.size
    p = np.empty(n)
    allowed = np.ones(n_bases, dtype=np.bool_)
    for k in range(n):
        x = flows[k]
        total = 0.0
        for b in range(n_bases):
            if allowed[b]:
                total += comp[b]
        q = comp[x] / total if allowed[x] and total > 0.0 else 0.0
        p[k] = min(max(q, P_POS_MIN), 1.0 - P_POS_MIN)
        if calls[k] > 0:
            allowed[:] = True
        allowed[x] = False
    return p


@NJIT
def posterior_kernel(y: np.ndarray, a: np.ndarray, b: np.ndarray, floor: float, shot: float,
                     ref: float, p_pos: np.ndarray, log_len: np.ndarray, inflate: np.ndarray
                     ) -> np.ndarray:  # pragma: no cover - compiled
    """P(h | y_k), h = 0 … len(log_len) − 1: Normal(a h + b, floor + shot m + ref m²) times the
    prior ``1 − p_pos[k]`` (h = 0) or ``p_pos[k]·exp(log_len[h])`` (h ≥ 1)."""
    n, m = y.size, log_len.size
    post = np.empty((n, m))
    for k in range(n):
        top = -np.inf
        for h in range(m):
            mean = a[k] * h + b[k]
            mp = max(mean, 0.0)
            var = (floor + shot * mp + ref * mp * mp) * inflate[k]
            d = y[k] - mean
            lp = math.log(1.0 - p_pos[k]) if h == 0 else math.log(p_pos[k]) + log_len[h]
            ll = -0.5 * d * d / var - 0.5 * math.log(var) + lp
            post[k, h] = ll
            top = max(top, ll)
        total = 0.0
        for h in range(m):
            post[k, h] = math.exp(post[k, h] - top)
            total += post[k, h]
        for h in range(m):
            post[k, h] /= total
    return post


@NJIT
def nll_kernel(y: np.ndarray, signal: np.ndarray, calls: np.ndarray, floor: float, shot: float,
               ref: float, p_pos: np.ndarray, log_len: np.ndarray, n_score: int
               ) -> float:  # pragma: no cover - compiled
    """Negative log-posterior of the calls over the first ``n_score`` flows."""
    total = 0.0
    top = log_len.size - 1
    for k in range(n_score):
        mp = max(signal[k], 0.0)
        var = floor + shot * mp + ref * mp * mp
        d = y[k] - signal[k]
        h = min(calls[k], top)
        lp = math.log(1.0 - p_pos[k]) if h == 0 else math.log(p_pos[k]) + log_len[h]
        total += 0.5 * d * d / var + 0.5 * math.log(var) - lp
    return total


@NJIT
def dephase_kernel(y: np.ndarray, flows: np.ndarray, eps: float, lam: float, droop: float,
                   start: np.ndarray, comp: np.ndarray, log_len: np.ndarray, floor: float,
                   shot: float, ref: float, n_score: int, n_iter: int, window: int
                   ) -> tuple:  # pragma: no cover - compiled
    """The sweep of :func:`chiptwin.detection.reads.dephase`: returns (calls, post, nll)."""
    calls = start.copy()
    best_calls = calls.copy()
    best_nll = np.inf
    best_post = np.zeros((y.size, log_len.size))
    ones = np.ones(y.size)
    for _ in range(n_iter + 1):
        signal, a, _ = phase_flows(template_of(calls, flows), flows, eps, lam, droop)
        p_pos = context_prior(calls, flows, comp, comp.size)
        post = posterior_kernel(y, a, signal - a * calls, floor, shot, ref, p_pos, log_len,
                                ones)
        nll = nll_kernel(y, signal, calls, floor, shot, ref, p_pos, log_len, n_score)
        if nll < best_nll:
            best_nll = nll
            best_calls[:] = calls
            best_post = post
        first = -1
        for k in range(y.size):
            if np.argmax(post[k]) != calls[k]:
                first = k
                break
        if first < 0:
            break
        for k in range(first, min(first + window, y.size)):
            calls[k] = np.argmax(post[k])
    return best_calls, best_post, best_nll


@NJIT
def _score(y: np.ndarray, flows: np.ndarray, calls: np.ndarray, eps: float, lam: float,
           droop: float, comp: np.ndarray, log_len: np.ndarray, floor: float, shot: float,
           ref: float) -> tuple:  # pragma: no cover - compiled
    """(nll, signal, ideal) of a call set: its template's flowgram and prior."""
    signal, _, ideal = phase_flows(template_of(calls, flows), flows, eps, lam, droop)
    p_pos = context_prior(ideal, flows, comp, comp.size)
    return nll_kernel(y, signal, ideal, floor, shot, ref, p_pos, log_len, y.size), signal, ideal


@NJIT
def polish_kernel(y: np.ndarray, flows: np.ndarray, eps: float, lam: float, droop: float,
                  start: np.ndarray, comp: np.ndarray, log_len: np.ndarray, floor: float,
                  shot: float, ref: float, n_try: int, z_min: float, rounds: int
                  ) -> np.ndarray:  # pragma: no cover - compiled
    """Hill-climb the whole read's likelihood: at the ``n_try`` flows with the largest
    standardised residuals (above ``z_min``), try one base more or less (the template's flow
    program re-derived) and keep the first change that lowers the negative log-likelihood;
    repeat up to ``rounds`` times."""
    top = log_len.size - 1
    nll, signal, calls = _score(y, flows, start, eps, lam, droop, comp, log_len, floor, shot,
                                ref)
    if calls.max() > top:  # the start's template merges runs beyond the caller's range
        return start
    for _ in range(rounds):
        z = np.empty(y.size)
        for k in range(y.size):
            mp = max(signal[k], 0.0)
            z[k] = abs(y[k] - signal[k]) / math.sqrt(floor + shot * mp + ref * mp * mp)
        order = np.argsort(-z)
        improved = False
        for i in range(min(n_try, y.size)):
            k = order[i]
            if z[k] < z_min:
                break
            for d in (-1, 1):
                h = calls[k] + d
                if h < 0 or h > top:
                    continue
                trial = calls.copy()
                trial[k] = h
                t_nll, t_signal, t_ideal = _score(y, flows, trial, eps, lam, droop, comp,
                                                  log_len, floor, shot, ref)
                if t_nll < nll - 1e-9 and t_ideal.max() <= top:
                    nll, signal, calls = t_nll, t_signal, t_ideal
                    improved = True
                    break
            if improved:
                break
        if not improved:
            break
    return calls
