"""numba kernels of the posterior the read's qualities come from
(:func:`chiptwin.detection.reads.final_posterior`): each flow's P(h | y) under one model of the
read, the variance widened where the residuals say the model misses, and the mixture over the
phasing estimate's grid neighbours, weighted by the read's likelihood under each.

Arrays and scalars in, arrays out; no validation (the public functions check once). The numpy
reference of :func:`posterior_kernel` is in ``tests/detection/test_reads.py``; the mixture as
first written (every neighbour's posterior computed, in Python) in
``tests/detection/naive_caller.py``.
"""

from __future__ import annotations

import math

import numpy as np

from chiptwin._numba import NJIT
from chiptwin.kinetics._phasing_kernels import droop_scale, phase_bases


@NJIT
def posterior_kernel(y: np.ndarray, a: np.ndarray, b: np.ndarray, floor: float, shot: float,
                     ref: float, p_pos: np.ndarray, log_len: np.ndarray, inflate: np.ndarray,
                     beta: float) -> np.ndarray:  # pragma: no cover - compiled
    """P(h | y_k), h = 0 … len(log_len) − 1: Normal(a h + b, floor + shot m + ref m²) times the
    prior ``1 − p_pos[k]`` (h = 0) or ``p_pos[k]·exp(log_len[h])`` (h ≥ 1); the mean of
    ``h = 0`` has the empty-flow light ``beta`` added."""
    n, m = y.size, log_len.size
    post = np.empty((n, m))
    for k in range(n):
        top = -np.inf
        l0, l1 = math.log(1.0 - p_pos[k]), math.log(p_pos[k])
        for h in range(m):
            mean = a[k] * h + b[k]
            if h == 0:
                mean += beta
            mp = max(mean, 0.0)
            var = (floor + shot * mp + ref * mp * mp) * inflate[k]
            d = y[k] - mean
            lp = l0 if h == 0 else l1 + log_len[h]
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
def window_inflation(y: np.ndarray, signal: np.ndarray, floor: float, shot: float, ref: float,
                     half: int, out: np.ndarray) -> None:  # pragma: no cover - compiled
    """``out[k] = max(1, mean of (y − s)²/var(s) over flows k − half … k + half)``, the window
    clipped to the read."""
    n = y.size
    z2 = np.empty(n)
    for k in range(n):
        mp = max(signal[k], 0.0)
        d = y[k] - signal[k]
        z2[k] = d * d / (floor + shot * mp + ref * mp * mp)
    for k in range(n):
        lo, hi = max(0, k - half), min(n, k + half + 1)
        total = 0.0
        for j in range(lo, hi):
            total += z2[j]
        out[k] = max(1.0, total / (hi - lo))


@NJIT
def mixed_posterior(y: np.ndarray, tmpl: np.ndarray, flows: np.ndarray, calls: np.ndarray,
                    eps_v: np.ndarray, lam_v: np.ndarray, droop_v: np.ndarray, floor: float,
                    shot: float, ref: float, p_pos: np.ndarray, log_len: np.ndarray,
                    half: int, widen: float, w_min: float,
                    beta: float) -> np.ndarray:  # pragma: no cover - compiled
    """The posterior averaged over every (ε, λ, δ) of the three grids' values: each model's
    flowgram of ``tmpl`` (droop only scales it, so one model per ε, λ), its variance widened by
    :func:`window_inflation` times ``widen``, weighted by the read's likelihood under it. A
    model of weight below ``w_min`` is left out and the others' weights renormalised (on a
    400-flow read all but one of the 27 weigh less than 1e-6). Empty flows (``calls``
    0) carry the empty-flow light ``beta`` besides their signal."""
    n, m = y.size, log_len.size
    n_m = eps_v.size * lam_v.size * droop_v.size
    signal, a, infl = np.empty((n_m, n)), np.empty((n_m, n)), np.empty((n_m, n))
    logw, light = np.empty(n_m), np.empty(n)
    i = 0
    for e in eps_v:
        for lm in lam_v:
            bases, in_phase, _ = phase_bases(tmpl, flows, e, lm)
            for d in droop_v:
                scale = droop_scale(n, d)
                for k in range(n):
                    signal[i, k] = bases[k] * scale[k]
                    a[i, k] = in_phase[k] * scale[k]
                    light[k] = signal[i, k] + beta if calls[k] == 0 else signal[i, k]
                window_inflation(y, light, floor, shot, ref, half, infl[i])
                total = 0.0
                for k in range(n):
                    infl[i, k] *= widen
                    mp = max(light[k], 0.0)
                    v = (floor + shot * mp + ref * mp * mp) * infl[i, k]
                    r = y[k] - light[k]
                    total += r * r / v + math.log(v)
                logw[i] = -0.5 * total
                i += 1
    w = np.exp(logw - logw.max())
    w /= w.sum()
    kept = 0.0
    for i in range(n_m):
        if w[i] >= w_min:
            kept += w[i]
    post = np.zeros((n, m))
    b = np.empty(n)
    for i in range(n_m):
        if w[i] >= w_min:
            for k in range(n):
                b[k] = signal[i, k] - a[i, k] * calls[k]
            post += (w[i] / kept) * posterior_kernel(y, a[i], b, floor, shot, ref, p_pos,
                                                     log_len, infl[i], beta)
    return post
