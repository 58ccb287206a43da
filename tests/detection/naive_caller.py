"""The dephasing caller's sweep and hill climb as first written: the whole flowgram predicted
again for every step and every candidate (:func:`chiptwin.kinetics._phasing_kernels.phase_flows`
from flow 0). The slow, obvious reference the incremental kernels of
:mod:`chiptwin.detection._read_kernels` are held to (same calls, same likelihoods), and the
baseline ``benchmarks/bench_long_reads.py`` times them against."""

from __future__ import annotations

import math

import numpy as np

from chiptwin._numba import NJIT
from chiptwin.detection._read_kernels import (
    _score,
    context_prior,
    nll_kernel,
    posterior_kernel,
    template_of,
)
from chiptwin.kinetics._phasing_kernels import phase_flows


@NJIT
def sweep_with_posterior(y: np.ndarray, flows: np.ndarray, eps: float, lam: float,
                         droop: float, start: np.ndarray, comp: np.ndarray, log_len: np.ndarray,
                         floor: float, shot: float, ref: float, n_score: int, n_iter: int,
                         window: int) -> tuple:  # pragma: no cover - compiled
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


def dephase_kernel(*args) -> tuple:
    """(calls, nll) of :func:`sweep_with_posterior`, as the fast kernel returns them."""
    calls, _, nll = sweep_with_posterior(*args)
    return calls, nll


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


def final_posterior(y: np.ndarray, flows: np.ndarray, noise, calls: np.ndarray,
                    par: tuple[float, float, float]) -> np.ndarray:
    """:func:`chiptwin.detection.reads.final_posterior` as first written: every one of the 27
    neighbours' flowgrams predicted whole and its posterior computed, whatever its weight."""
    from chiptwin.detection import reads

    prior = reads.Prior.of(calls, flows)
    p_pos = prior.p_pos(calls, flows)
    posts, logw = [], []
    for e in reads._neighbours(reads.EPS_GRID, par[0]):
        for lm in reads._neighbours(reads.LAMBDA_GRID, par[1]):
            for d in reads._neighbours(reads.DROOP_GRID, par[2]):
                signal, a, _ = reads.phase_model(calls, flows, e, lm, d)
                inflate = reads.local_inflation(y, signal, noise) * reads.MODEL_INFLATION
                posts.append(reads.posterior(y, a, signal - a * calls, noise, p_pos,
                                             prior.log_len, inflate))
                v = noise.var(signal) * inflate
                logw.append(-0.5 * float(np.sum((y - signal) ** 2 / v + np.log(v))))
    w = np.exp(np.array(logw) - max(logw))
    return np.tensordot(w / w.sum(), np.array(posts), axes=1)


#: What :func:`use_naive` swaps into :mod:`chiptwin.detection.reads`.
NAIVE = {"dephase_kernel": dephase_kernel, "polish_kernel": polish_kernel,
         "final_posterior": final_posterior}


def use_naive(module) -> dict:
    """Swap the naive kernels into ``module`` (``chiptwin.detection.reads``); returns what was
    there, for :func:`restore`."""
    old = {k: getattr(module, k) for k in NAIVE}
    for k, v in NAIVE.items():
        setattr(module, k, v)
    return old


def restore(module, old: dict) -> None:
    for k, v in old.items():
        setattr(module, k, v)
