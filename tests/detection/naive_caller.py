"""The dephasing caller as first written: the whole flowgram predicted again for every sweep
step and hill-climb candidate (from flow 0, on the phasing model's kernels as first written,
kept below), every phasing neighbour's posterior computed, the read always called again without
phasing. The per-flow likelihood and posterior kernels (``nll_kernel``, ``posterior_kernel``),
the prior and the rescale are shared with the fast caller. The slow, obvious reference the fast
caller (:mod:`chiptwin.detection._read_kernels`, :mod:`chiptwin.detection.reads`) is held to
(same calls, same likelihoods), and the baseline ``benchmarks/bench_long_reads.py`` times it
against."""

from __future__ import annotations

import math

import numpy as np

from chiptwin._numba import NJIT
from chiptwin.detection._posterior_kernels import posterior_kernel
from chiptwin.detection._read_kernels import (
    context_prior,
    nll_kernel,
    template_of,
)
from chiptwin.kinetics._phasing_kernels import TINY, droop_scale, run_table

# -- the phasing model's kernels as first written (chiptwin.kinetics._phasing_kernels before its
#    flow step summed the shares that stay in a register and dropped reference counting): the
#    baseline is the caller as it was, and the same calls show the new step's bits are these --

@NJIT
def flow_step(run: np.ndarray, x: int, prev: int, eps: float, lam: float, dist: np.ndarray,
              new: np.ndarray, lo: int, hi: int) -> tuple:  # pragma: no cover - compiled
    """One flow: the strands of ``dist[lo..hi]`` held, extended or carried into ``new``."""
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
    return bases, new_hi


@NJIT
def trim(dist: np.ndarray, old: np.ndarray, lo: int, hi: int,
         new_hi: int) -> tuple:  # pragma: no cover - compiled
    """Clear ``old`` and drop the tails' shares below ``TINY``."""
    old[lo:hi + 1] = 0.0
    hi = new_hi
    while lo < hi and dist[lo] < TINY:
        dist[lo] = 0.0  # a share below TINY of the strands: dropped, not carried
        lo += 1
    while hi > lo and dist[hi] < TINY:
        dist[hi] = 0.0
        hi -= 1
    return lo, hi


@NJIT
def phase_flows(tmpl: np.ndarray, flows: np.ndarray, eps: float, lam: float,
                droop: float) -> tuple:  # pragma: no cover - compiled
    """(signal, in-phase weight, ideal counts) per flow of the template, drooping."""
    bases, in_phase, ideal = phase_bases(tmpl, flows, eps, lam)
    scale = droop_scale(flows.size, droop)
    return bases * scale, in_phase * scale, ideal


@NJIT
def phase_bases(tmpl: np.ndarray, flows: np.ndarray, eps: float,
                lam: float) -> tuple:  # pragma: no cover - compiled
    """:func:`phase_flows` without droop."""
    n_pos = tmpl.size
    run = run_table(tmpl)
    dist = np.zeros(n_pos + 1)
    new = np.zeros(n_pos + 1)
    dist[0] = 1.0
    n = flows.size
    bases = np.zeros(n)
    in_phase = np.zeros(n)
    ideal = np.zeros(n, dtype=np.int64)
    lo, hi, pos, prev = 0, 0, 0, -1
    for k in range(n):
        x = flows[k]
        ideal[k] = run[pos, x]
        in_phase[k] = (1.0 - eps) * dist[pos]
        bases[k], new_hi = flow_step(run, x, prev, eps, lam, dist, new, lo, hi)
        dist, new = new, dist
        lo, hi = trim(dist, new, lo, hi, new_hi)
        pos += ideal[k]
        prev = x
    return bases, in_phase, ideal




@NJIT
def _score(y: np.ndarray, flows: np.ndarray, calls: np.ndarray, eps: float, lam: float,
           droop: float, comp: np.ndarray, log_len: np.ndarray, floor: float, shot: float,
           ref: float, beta: float) -> tuple:  # pragma: no cover - compiled
    """(nll, signal, ideal) of a call set, on the model above."""
    signal, _, ideal = phase_flows(template_of(calls, flows), flows, eps, lam, droop)
    p_pos = context_prior(ideal, flows, comp, comp.size)
    return (nll_kernel(y, signal, ideal, floor, shot, ref, p_pos, log_len, y.size, beta),
            signal, ideal)



@NJIT
def sweep_with_posterior(y: np.ndarray, flows: np.ndarray, eps: float, lam: float,
                         droop: float, start: np.ndarray, comp: np.ndarray, log_len: np.ndarray,
                         floor: float, shot: float, ref: float, n_score: int, n_iter: int,
                         window: int, beta: float) -> tuple:  # pragma: no cover - compiled
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
                                ones, beta)
        nll = nll_kernel(y, signal, calls, floor, shot, ref, p_pos, log_len, n_score, beta)
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
                  shot: float, ref: float, n_try: int, z_min: float, rounds: int,
                  beta: float) -> np.ndarray:  # pragma: no cover - compiled
    """Hill-climb the whole read's likelihood: at the ``n_try`` flows with the largest
    standardised residuals (above ``z_min``), try one base more or less (the template's flow
    program re-derived) and keep the first change that lowers the negative log-likelihood;
    repeat up to ``rounds`` times."""
    top = log_len.size - 1
    nll, signal, calls = _score(y, flows, start, eps, lam, droop, comp, log_len, floor, shot,
                                ref, beta)
    if calls.max() > top:  # the start's template merges runs beyond the caller's range
        return start
    for _ in range(rounds):
        z = np.empty(y.size)
        for k in range(y.size):
            sk = signal[k] + beta if calls[k] == 0 else signal[k]
            mp = max(sk, 0.0)
            z[k] = abs(y[k] - sk) / math.sqrt(floor + shot * mp + ref * mp * mp)
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
                                                  log_len, floor, shot, ref, beta)
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
                    par: tuple[float, float, float], beta: float = 0.0) -> np.ndarray:
    """:func:`chiptwin.detection.reads.final_posterior` as first written: every one of the 27
    neighbours' flowgrams predicted whole and its posterior computed, whatever its weight."""
    from chiptwin.detection import reads

    prior = reads.Prior.of(calls, flows)
    p_pos = prior.p_pos(calls, flows)
    posts, logw = [], []
    for e in reads._neighbours(reads.EPS_GRID, par[0]):
        for lm in reads._neighbours(reads.LAMBDA_GRID, par[1]):
            for d in reads._neighbours(reads.DROOP_GRID, par[2]):
                signal, a, _ = phase_flows(template_of(calls.astype(np.int64), flows),
                                           flows, e, lm, d)
                light = signal + np.where(calls == 0, beta, 0.0)
                inflate = reads.local_inflation(y, light, noise) * reads.MODEL_INFLATION
                posts.append(reads.posterior(y, a, signal - a * calls, noise, p_pos,
                                             prior.log_len, inflate, beta))
                v = noise.var(light) * inflate
                logw.append(-0.5 * float(np.sum((y - light) ** 2 / v + np.log(v))))
    w = np.exp(np.array(logw) - max(logw))
    return np.tensordot(w / w.sum(), np.array(posts), axes=1)


def keep_phasing(y: np.ndarray, flows: np.ndarray, noise, calls: np.ndarray,
                 par: tuple[float, float, float], prior, beta: float = 0.0) -> tuple:
    """:func:`chiptwin.detection.reads.keep_phasing` as first written: the read called again
    without phasing every time, whether or not such calls could score better."""
    from chiptwin.detection import reads

    if not any(par):
        return calls, par
    cost = reads.PHASING_PENALTY * np.log(max(y.size, 1)) * sum(p > 0 for p in par)
    phased = reads.read_nll(y, flows, noise, calls, par, prior, beta) + cost
    flat = reads.dephase(y, flows, noise, 0.0, 0.0, 0.0,
                         np.clip(np.rint(y), 0, reads.MAX_CALL).astype(np.int64), prior,
                         beta=beta)[0]
    flat = reads.polish(y, flows, noise, (0.0, 0.0, 0.0), flat, prior, beta)
    if reads.read_nll(y, flows, noise, flat, (0.0, 0.0, 0.0), prior, beta) <= phased:
        return flat, (0.0, 0.0, 0.0)
    return calls, par


#: What :func:`use_naive` swaps into :mod:`chiptwin.detection.reads`.
NAIVE = {"dephase_kernel": dephase_kernel, "polish_kernel": polish_kernel,
         "final_posterior": final_posterior, "keep_phasing": keep_phasing}


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
