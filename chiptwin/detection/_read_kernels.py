"""numba kernels behind :mod:`chiptwin.detection.reads`: the posterior of each flow's call and
the left-to-right dephasing sweep and the hill climb of a whole read's likelihood.

Arrays and scalars in, arrays out; no validation (the public functions check once). The numpy
reference of each is in ``tests/detection/test_reads.py``; the sweep and the hill climb as they
were first written (the whole flowgram predicted again for every candidate) are in
``tests/detection/naive_caller.py``, and these give the same calls.

Why these are fast: a call changed at flow k changes the template from position D on, and every
flow that reads only template positions below D (:func:`chiptwin.kinetics._phasing_kernels.
model_advance` records how far each flow reads) keeps its prediction, its prior and its share
of the likelihood; so a candidate is scored from the last checkpoint before the first flow that
reads D, with the prefix's likelihood summed as before (the same bits). A candidate of the hill
climb is dropped as soon as its likelihood so far, plus the least the remaining flows can add
(:func:`least_term`), is already worse than the current calls'.
"""

from __future__ import annotations

import math

import numpy as np

from chiptwin._numba import NJIT
from chiptwin.kinetics._phasing_kernels import (
    CHECK_EVERY,
    first_reaching,
    model_advance,
    model_buffers,
    model_restore,
    phase_flows,
    run_table,
    run_table_into,
)


@NJIT
def template_of(calls: np.ndarray, flows: np.ndarray) -> np.ndarray:  # pragma: no cover
    """The template the calls spell, as base indices."""
    out = np.empty(calls.sum(), dtype=np.int64)
    template_into(calls, flows, out)
    return out


@NJIT
def template_into(calls: np.ndarray, flows: np.ndarray, out: np.ndarray) -> int:  # pragma: no cover
    """:func:`template_of` written into ``out`` (long enough); returns its length."""
    p = 0
    for k in range(calls.size):
        for _ in range(calls[k]):
            out[p] = flows[k]
            p += 1
    return p


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
        l0, l1 = math.log(1.0 - p_pos[k]), math.log(p_pos[k])
        for h in range(m):
            mean = a[k] * h + b[k]
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
def _score(y: np.ndarray, flows: np.ndarray, calls: np.ndarray, eps: float, lam: float,
           droop: float, comp: np.ndarray, log_len: np.ndarray, floor: float, shot: float,
           ref: float) -> tuple:  # pragma: no cover - compiled
    """(nll, signal, ideal) of a call set: its template's flowgram and prior."""
    signal, _, ideal = phase_flows(template_of(calls, flows), flows, eps, lam, droop)
    p_pos = context_prior(ideal, flows, comp, comp.size)
    return nll_kernel(y, signal, ideal, floor, shot, ref, p_pos, log_len, y.size), signal, ideal




@NJIT
def prior_from(calls: np.ndarray, flows: np.ndarray, comp: np.ndarray, k0: int, k1: int,
               mask: int, allow: np.ndarray, p_pos: np.ndarray) -> int:  # pragma: no cover
    """:func:`context_prior` for flows ``k0 … k1 − 1`` from the allowed bases ``mask`` (bit b:
    base b may come next) before flow ``k0``; ``allow[k]`` keeps the mask before each flow.
    Returns the mask after flow ``k1 − 1``."""
    for k in range(k0, k1):
        allow[k] = mask
        x = flows[k]
        total = 0.0
        for b in range(comp.size):
            if (mask >> b) & 1:
                total += comp[b]
        q = comp[x] / total if (mask >> x) & 1 and total > 0.0 else 0.0
        p_pos[k] = min(max(q, P_POS_MIN), 1.0 - P_POS_MIN)
        if calls[k] > 0:
            mask = (1 << comp.size) - 1
        mask &= ~(1 << x)
    return mask


@NJIT
def terms_from(y: np.ndarray, signal: np.ndarray, calls: np.ndarray, floor: float, shot: float,
               ref: float, p_pos: np.ndarray, log_len: np.ndarray, k0: int, k1: int,
               total: float, cum: np.ndarray) -> float:  # pragma: no cover - compiled
    """:func:`nll_kernel`'s sum continued over flows ``k0 … k1 − 1`` from ``total``, in the same
    order (the same bits); ``cum[k + 1]`` keeps the sum through flow ``k``."""
    top = log_len.size - 1
    for k in range(k0, k1):
        mp = max(signal[k], 0.0)
        var = floor + shot * mp + ref * mp * mp
        d = y[k] - signal[k]
        h = min(calls[k], top)
        lp = math.log(1.0 - p_pos[k]) if h == 0 else math.log(p_pos[k]) + log_len[h]
        total += 0.5 * d * d / var + 0.5 * math.log(var) - lp
        cum[k + 1] = total
    return total


@NJIT
def least_term(floor: float) -> float:  # pragma: no cover - compiled
    """A lower bound of any flow's share of the negative log-posterior: the squared residual
    is ≥ 0, the variance ≥ ``floor``, and the prior of any length ≤ 1 − :data:`P_POS_MIN`."""
    return 0.5 * math.log(floor) + math.log(1.0 / (1.0 - P_POS_MIN)) if floor > 0 else -np.inf


@NJIT
def call_of(yk: float, ak: float, bk: float, floor: float, shot: float, ref: float,
            p: float, log_len: np.ndarray, row: np.ndarray) -> int:  # pragma: no cover
    """The likeliest length of one flow: ``argmax`` of :func:`posterior_kernel`'s row (the same
    arithmetic; normalised as there, so ties break the same way, unless the best log-posterior
    leads the next by more than rounding could close); ``row`` is scratch."""
    m = log_len.size
    top, second, best = -np.inf, -np.inf, 0
    l0, l1 = math.log(1.0 - p), math.log(p)
    for h in range(m):
        mean = ak * h + bk
        mp = max(mean, 0.0)
        var = (floor + shot * mp + ref * mp * mp) * 1.0
        d = yk - mean
        lp = l0 if h == 0 else l1 + log_len[h]
        ll = -0.5 * d * d / var - 0.5 * math.log(var) + lp
        row[h] = ll
        if ll > top:
            top, second, best = ll, top, h
        elif ll > second:
            second = ll
    if top - second > 1e-12 * max(1.0, abs(top)):
        return best  # exp and the normalisation keep an order this wide
    total = 0.0
    for h in range(m):
        row[h] = math.exp(row[h] - top)
        total += row[h]
    best = 0
    for h in range(m):
        row[h] /= total
        if row[h] > row[best]:
            best = h
    return best


@NJIT
def dephase_kernel(y: np.ndarray, flows: np.ndarray, eps: float, lam: float, droop: float,
                   start: np.ndarray, comp: np.ndarray, log_len: np.ndarray, floor: float,
                   shot: float, ref: float, n_score: int, n_iter: int, window: int
                   ) -> tuple:  # pragma: no cover - compiled
    """The sweep of :func:`chiptwin.detection.reads.dephase`: returns (calls, nll).

    Each step re-predicts the flowgram only from the first flow the last change can reach, and
    looks for the first flow whose likeliest length is not its call only from there (the flows
    before it kept their prediction and their calls)."""
    n = y.size
    calls = start.copy()
    best_calls = calls.copy()
    best_nll = np.inf
    width = 2 * int(calls.sum()) + 16
    (state, scale, buf, ck_dist, ck_int, ck_scale, signal, a, ideal,
     reach) = model_buffers(n, width)
    allow = np.zeros(n, dtype=np.int64)
    p_pos = np.zeros(n)
    cum = np.zeros(n + 1)
    row = np.zeros(log_len.size)
    full = (1 << comp.size) - 1
    k_model, k_prior = 0, 0
    for _ in range(n_iter + 1):
        tmpl = template_of(calls, flows)
        if tmpl.size + 2 > width:  # a longer template: new buffers, the model from flow 0
            width = 2 * (tmpl.size + 2)
            (state, scale, buf, ck_dist, ck_int, ck_scale, signal, a, ideal,
             reach) = model_buffers(n, width)
            k_model = 0
        k = model_restore(k_model, state, scale, buf, ck_dist, ck_int, ck_scale)
        model_advance(run_table(tmpl), flows, eps, lam, droop, k, n, state, scale, buf,
                      ck_dist, ck_int, ck_scale, signal, a, ideal, reach)
        prior_from(calls, flows, comp, k_prior, n, allow[k_prior] if k_prior > 0 else full,
                   allow, p_pos)
        kt = min(k, k_prior)
        if kt < n_score:
            terms_from(y, signal, calls, floor, shot, ref, p_pos, log_len, kt, n_score,
                       cum[kt], cum)
        nll = cum[n_score]
        if nll < best_nll:
            best_nll = nll
            best_calls[:] = calls
        first = -1
        for j in range(kt, n):
            if call_of(y[j], a[j], signal[j] - a[j] * calls[j], floor, shot, ref, p_pos[j],
                       log_len, row) != calls[j]:
                first = j
                break
        if first < 0:
            break
        new = np.empty(min(first + window, n) - first, dtype=np.int64)
        for j in range(first, first + new.size):
            new[j - first] = call_of(y[j], a[j], signal[j] - a[j] * calls[j], floor, shot, ref,
                                     p_pos[j], log_len, row)
        k_model = first_reaching(reach, calls[:first].sum())
        k_prior = first
        calls[first:first + new.size] = new
    return best_calls, best_nll


@NJIT
def polish_kernel(y: np.ndarray, flows: np.ndarray, eps: float, lam: float, droop: float,
                  start: np.ndarray, comp: np.ndarray, log_len: np.ndarray, floor: float,
                  shot: float, ref: float, n_try: int, z_min: float, rounds: int
                  ) -> np.ndarray:  # pragma: no cover - compiled
    """Hill-climb the whole read's likelihood: at the ``n_try`` flows with the largest
    standardised residuals (above ``z_min``), try one base more or less (the template's flow
    program re-derived) and keep the first change that lowers the negative log-likelihood;
    repeat up to ``rounds`` times. Each candidate is scored from the first flow it can change
    (module docstring) and dropped once it cannot win."""
    n = y.size
    top = log_len.size - 1
    full = (1 << comp.size) - 1
    tmpl = template_of(start, flows)
    width = tmpl.size + rounds + 4  # each change kept moves the template's length by one
    base = model_buffers(n, width)
    trial = model_buffers(n, width)
    state, scale, buf, ck_dist, ck_int, ck_scale, signal, a, calls, reach = base
    model_restore(0, state, scale, buf, ck_dist, ck_int, ck_scale)
    model_advance(run_table(tmpl), flows, eps, lam, droop, 0, n, state, scale, buf, ck_dist,
                  ck_int, ck_scale, signal, a, calls, reach)
    if calls.max() > top:  # the start's template merges runs beyond the caller's range
        return start
    allow, t_allow = np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64)
    p_pos, t_pos = np.zeros(n), np.zeros(n)
    cum, t_cum = np.zeros(n + 1), np.zeros(n + 1)
    prior_from(calls, flows, comp, 0, n, full, allow, p_pos)
    nll = terms_from(y, signal, calls, floor, shot, ref, p_pos, log_len, 0, n, 0.0, cum)
    lb = least_term(floor)
    t_tmpl = np.empty(width, dtype=np.int64)
    t_run = np.empty((width + 1, 4), dtype=np.int64)
    z = np.empty(n)
    for _ in range(rounds):
        for k in range(n):
            mp = max(signal[k], 0.0)
            z[k] = abs(y[k] - signal[k]) / math.sqrt(floor + shot * mp + ref * mp * mp)
        order = _largest_first(z, z_min)
        kept = -1
        for i in range(min(n_try, order.size)):
            k = order[i]
            if z[k] < z_min:
                break
            for d in (-1, 1):
                h = calls[k] + d
                if h < 0 or h > top:
                    continue
                calls[k] = h
                n_pos = template_into(calls, flows, t_tmpl)
                calls[k] = h - d
                k0 = first_reaching(reach, calls[:k].sum() + min(calls[k], h))
                run_table_into(t_tmpl, n_pos, t_run)
                kc = _score_from(y, flows, eps, lam, droop, t_run, comp, log_len, floor, shot,
                                 ref, k0, nll, lb, base, trial, allow, t_allow, t_pos, cum,
                                 t_cum, top)
                if kc >= 0:
                    _keep(base, trial, kc, n, allow, t_allow, p_pos, t_pos, cum, t_cum)
                    nll = cum[n]
                    kept = k
                    break
            if kept >= 0:
                break
        if kept < 0:
            break
    return calls.copy()


@NJIT
def _score_from(y, flows, eps, lam, droop, run, comp, log_len, floor, shot, ref, k0, nll, lb,
                base, trial, allow, t_allow, t_pos, cum, t_cum, top):  # pragma: no cover
    """Score a candidate template (its ``run`` table) into ``trial`` from the checkpoint before
    flow ``k0``, a
    checkpoint's worth of flows at a time; returns that checkpoint's flow when the candidate
    beats ``nll`` by more than 1e-9 (and calls no run beyond ``top``), else −1, as soon as the
    sum so far plus ``lb`` per flow left cannot."""
    n = y.size
    state, scale, buf, ck_dist, ck_int, ck_scale, _, _, _, reach = base
    t_state, t_scale, t_buf, t_ck_dist, t_ck_int, t_ck_scale, t_signal, t_a, t_calls, \
        t_reach = trial
    kc = model_restore(k0, t_state, t_scale, t_buf, ck_dist, ck_int, ck_scale)
    if kc > 0:
        t_reach[kc - 1] = reach[kc - 1]
    mask = allow[kc] if kc > 0 else (1 << comp.size) - 1
    total = cum[kc]
    t_cum[kc] = total
    k = kc
    while k < n:
        ke = min(k + CHECK_EVERY, n)
        model_advance(run, flows, eps, lam, droop, k, ke, t_state, t_scale, t_buf, t_ck_dist,
                      t_ck_int, t_ck_scale, t_signal, t_a, t_calls, t_reach)
        for j in range(k, ke):
            if t_calls[j] > top:
                return -1
        mask = prior_from(t_calls, flows, comp, k, ke, mask, t_allow, t_pos)
        total = terms_from(y, t_signal, t_calls, floor, shot, ref, t_pos, log_len, k, ke, total,
                           t_cum)
        left = (n - ke) * lb if ke < n else 0.0
        slack = 1e-6 * (abs(total) + abs(nll) + abs(left) + 1.0)  # far above rounding error
        if total + left - slack >= nll - 1e-9:
            return -1
        k = ke
    return kc if total < nll - 1e-9 else -1


@NJIT
def _keep(base, trial, kc, n, allow, t_allow, p_pos, t_pos, cum, t_cum) -> None:  # pragma: no cover
    """The candidate scored into ``trial`` from flow ``kc`` on becomes the current calls."""
    c = kc // CHECK_EVERY
    for dst, src in ((base[6], trial[6]), (base[7], trial[7]), (p_pos, t_pos)):
        dst[kc:] = src[kc:]
    for dst_i, src_i in ((base[8], trial[8]), (base[9], trial[9]), (allow, t_allow)):
        dst_i[kc:] = src_i[kc:]
    cum[kc + 1:] = t_cum[kc + 1:]
    base[3][c:] = trial[3][c:]
    base[4][c:] = trial[4][c:]
    base[5][c:] = trial[5][c:]



@NJIT
def _largest_first(z: np.ndarray, z_min: float) -> np.ndarray:  # pragma: no cover - compiled
    """``np.argsort(-z)`` up to the last ``z ≥ z_min``: sorted among those alone when they are
    all distinct (then the order is the same), else the whole sort (ties keep its order)."""
    idx = np.flatnonzero(z >= z_min)
    sub = np.sort(z[idx])
    for i in range(1, sub.size):
        if sub[i] == sub[i - 1]:
            return np.argsort(-z)[:idx.size]
    return idx[np.argsort(-z[idx])]
