"""numba kernels behind :mod:`chiptwin.detection.reads`: a read's likelihood, each flow's
likeliest length, the left-to-right dephasing sweep and the hill climb of a whole read's
likelihood (the posterior the qualities come from: :mod:`chiptwin.detection._posterior_kernels`).

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
(:func:`least_term`), is already worse than the current calls'; or as soon as the flows left
can no longer make up the difference to the current calls' terms there: a run resized moves
them only by the light of the strands still at or before it (:func:`chiptwin.detection._bounds.
leak_left`), any change, once both flow programs are past it, by the strands the two models
place apart (:func:`chiptwin.detection._bounds.apart`), each flow's term by at most a slope
bound times its light moved. Every bound decides only what the exact sum would: a candidate
that might win is scored to the end, so the calls and likelihoods are the naive kernels' to the
bit. The candidates' templates are rewritten only from the changed run on, each flow's log
prior is looked up (:func:`prior_table`), and the sweep finds a flow's likeliest length with
one logarithm when one length clearly wins (:func:`likeliest`). A round of the hill climb
re-derives the residuals and slope sums only from the flow its last change reached and keeps
the 24 largest residuals by insertion (:func:`_largest_first`); the scoring loop and the model
steps it calls compile without reference counting (:data:`chiptwin._numba.NJIT_NORC`).
"""

from __future__ import annotations

import math

import numpy as np

from chiptwin._numba import NJIT, NJIT_INLINE, NJIT_NORC
from chiptwin.detection._bounds import (
    LEAK_SPAN,
    SPANS,
    apart,
    leak_left,
    prefix_bounds,
    slopes_from,
)
from chiptwin.kinetics._phasing_kernels import (
    CHECK_EVERY,
    TINY,
    first_reaching,
    model_advance,
    model_buffers,
    model_restore,
    phase_flows,
    run_rows_from,
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


@NJIT_INLINE
def flow_term(yk: float, light: float, lp: float, floor: float, shot: float,
              ref: float) -> float:  # pragma: no cover - compiled
    """One flow's share of the negative log-posterior: Normal(``light``, floor + shot·m + ref·m²)
    at ``yk``, less its log prior ``lp``. Every sum of these terms adds them in flow order, so
    sums over the same flows are the same bits."""
    mp = max(light, 0.0)
    var = floor + shot * mp + ref * mp * mp
    d = yk - light
    return 0.5 * d * d / var + 0.5 * math.log(var) - lp


@NJIT
def nll_kernel(y: np.ndarray, signal: np.ndarray, calls: np.ndarray, floor: float, shot: float,
               ref: float, p_pos: np.ndarray, log_len: np.ndarray, n_score: int,
               beta: float) -> float:  # pragma: no cover - compiled
    """Negative log-posterior of the calls over the first ``n_score`` flows: each flow
    Normal(signal, floor + shot·m + ref·m²), the signal with the empty-flow light ``beta``
    added where the call is 0 (:mod:`chiptwin.detection.reads`)."""
    total = 0.0
    top = log_len.size - 1
    for k in range(n_score):
        sk = signal[k] + beta if calls[k] == 0 else signal[k]
        h = min(calls[k], top)
        lp = math.log(1.0 - p_pos[k]) if h == 0 else math.log(p_pos[k]) + log_len[h]
        total += flow_term(y[k], sk, lp, floor, shot, ref)
    return total


@NJIT
def _score(y: np.ndarray, flows: np.ndarray, calls: np.ndarray, eps: float, lam: float,
           droop: float, comp: np.ndarray, log_len: np.ndarray, floor: float, shot: float,
           ref: float, beta: float) -> tuple:  # pragma: no cover - compiled
    """(nll, signal, ideal) of a call set: its template's flowgram and prior."""
    signal, _, ideal = phase_flows(template_of(calls, flows), flows, eps, lam, droop)
    p_pos = context_prior(ideal, flows, comp, comp.size)
    return (nll_kernel(y, signal, ideal, floor, shot, ref, p_pos, log_len, y.size, beta),
            signal, ideal)


@NJIT
def prior_table(comp: np.ndarray) -> tuple:  # pragma: no cover - compiled
    """:func:`context_prior`'s P(h > 0) for every flow base ``x`` and set of allowed bases
    ``mask`` (bit b: base b may come next), with the logs of it and of its complement:
    ``(p, log(1 − p), log p)``, each (n_bases, 2**n_bases). The same arithmetic as
    :func:`context_prior`, so the same bits; a flow's prior depends on nothing else, so the
    kernels look it up instead of computing two logarithms per flow and candidate."""
    nb = comp.size
    p = np.empty((nb, 1 << nb))
    l0, l1 = np.empty_like(p), np.empty_like(p)
    for x in range(nb):
        for mask in range(1 << nb):
            total = 0.0
            for b in range(nb):
                if (mask >> b) & 1:
                    total += comp[b]
            q = comp[x] / total if (mask >> x) & 1 and total > 0.0 else 0.0
            p[x, mask] = min(max(q, P_POS_MIN), 1.0 - P_POS_MIN)
            l0[x, mask], l1[x, mask] = math.log(1.0 - p[x, mask]), math.log(p[x, mask])
    return p, l0, l1


@NJIT_NORC
def prior_from(calls: np.ndarray, flows: np.ndarray, p_tab: np.ndarray, k0: int, k1: int,
               mask: int, allow: np.ndarray, p_pos: np.ndarray) -> int:  # pragma: no cover
    """:func:`context_prior` for flows ``k0 … k1 − 1`` from the allowed bases ``mask`` before
    flow ``k0``, read from :func:`prior_table`'s ``p``; ``allow[k]`` keeps the mask before each
    flow. Returns the mask after flow ``k1 − 1``."""
    full = (1 << p_tab.shape[0]) - 1
    for k in range(k0, k1):
        allow[k] = mask
        x = flows[k]
        p_pos[k] = p_tab[x, mask]
        if calls[k] > 0:
            mask = full
        mask &= ~(1 << x)
    return mask


@NJIT
def terms_from(y: np.ndarray, signal: np.ndarray, calls: np.ndarray, floor: float, shot: float,
               ref: float, p_pos: np.ndarray, log_len: np.ndarray, k0: int, k1: int,
               total: float, cum: np.ndarray, beta: float) -> float:  # pragma: no cover
    """:func:`nll_kernel`'s sum continued over flows ``k0 … k1 − 1`` from ``total``, in the same
    order (the same bits); ``cum[k + 1]`` keeps the sum through flow ``k``."""
    top = log_len.size - 1
    for k in range(k0, k1):
        sk = signal[k] + beta if calls[k] == 0 else signal[k]
        h = min(calls[k], top)
        lp = math.log(1.0 - p_pos[k]) if h == 0 else math.log(p_pos[k]) + log_len[h]
        total += flow_term(y[k], sk, lp, floor, shot, ref)
        cum[k + 1] = total
    return total


@NJIT_NORC
def terms_tab(y: np.ndarray, signal: np.ndarray, calls: np.ndarray, flows: np.ndarray,
              allow: np.ndarray, l0: np.ndarray, l1: np.ndarray, floor: float, shot: float,
              ref: float, log_len: np.ndarray, k0: int, k1: int, total: float,
              cum: np.ndarray, beta: float) -> float:  # pragma: no cover - compiled
    """:func:`terms_from` with each flow's log prior read from :func:`prior_table` at the flow's
    base and allowed set (``allow``, as :func:`prior_from` keeps it): the same terms in the same
    order, so the same bits."""
    top = log_len.size - 1
    for k in range(k0, k1):
        sk = signal[k] + beta if calls[k] == 0 else signal[k]
        h = min(calls[k], top)
        lp = l0[flows[k], allow[k]] if h == 0 else l1[flows[k], allow[k]] + log_len[h]
        total += flow_term(y[k], sk, lp, floor, shot, ref)
        cum[k + 1] = total
    return total


@NJIT
def least_term(floor: float) -> float:  # pragma: no cover - compiled
    """A lower bound of any flow's share of the negative log-posterior: the squared residual
    is ≥ 0, the variance ≥ ``floor``, and the prior of any length ≤ 1 − :data:`P_POS_MIN`."""
    return 0.5 * math.log(floor) + math.log(1.0 / (1.0 - P_POS_MIN)) if floor > 0 else -np.inf


@NJIT_NORC
def call_of(yk: float, ak: float, bk: float, floor: float, shot: float, ref: float,
            p: float, log_len: np.ndarray, row: np.ndarray,
            beta: float) -> int:  # pragma: no cover - compiled
    """The likeliest length of one flow: ``argmax`` of
    :func:`chiptwin.detection._posterior_kernels.posterior_kernel`'s row (the same
    arithmetic; normalised as there, so ties break the same way, unless the best log-posterior
    leads the next by more than rounding could close); ``row`` is scratch. A length's mean is
    ``ak·h + bk``, plus the empty-flow light ``beta`` for ``h = 0``."""
    m = log_len.size
    top, second, best = -np.inf, -np.inf, 0
    l0, l1 = math.log(1.0 - p), math.log(p)
    for h in range(m):
        mean = ak * h + bk
        if h == 0:
            mean += beta
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


@NJIT_NORC
def likeliest(yk: float, ak: float, bk: float, floor: float, shot: float, ref: float,
              p: float, l0: float, l1: float, log_len: np.ndarray, guess: int,
              row: np.ndarray, beta: float) -> int:  # pragma: no cover - compiled
    """:func:`call_of`, the same answer, without its logarithm per length when one length
    clearly wins: the log-posterior of ``guess`` is computed as there (the same bits), every
    other length's bounded above by its residual term plus ``−log(floor)/2`` (its variance is
    at least ``floor``); when ``guess`` leads every bound by more than :func:`call_of`'s tie
    margin, :func:`call_of` would return it. Else :func:`call_of` decides."""
    if not floor > 0.0:
        return call_of(yk, ak, bk, floor, shot, ref, p, log_len, row, beta)
    cap = -0.5 * math.log(floor)
    mean = ak * guess + bk
    if guess == 0:
        mean += beta
    mp = max(mean, 0.0)
    var = (floor + shot * mp + ref * mp * mp) * 1.0
    d = yk - mean
    lg = -0.5 * d * d / var - 0.5 * math.log(var) + (l0 if guess == 0 else l1 + log_len[guess])
    second = -np.inf
    for h in range(log_len.size):
        if h == guess:
            continue
        mean = ak * h + bk
        if h == 0:
            mean += beta
        mp = max(mean, 0.0)
        var = (floor + shot * mp + ref * mp * mp) * 1.0
        d = yk - mean
        ub = -0.5 * d * d / var + cap + (l0 if h == 0 else l1 + log_len[h])
        second = max(second, ub)
    if lg - second > 1e-12 * max(1.0, abs(lg)):
        return guess
    return call_of(yk, ak, bk, floor, shot, ref, p, log_len, row, beta)


@NJIT
def dephase_kernel(y: np.ndarray, flows: np.ndarray, eps: float, lam: float, droop: float,
                   start: np.ndarray, comp: np.ndarray, log_len: np.ndarray, floor: float,
                   shot: float, ref: float, n_score: int, n_iter: int, window: int,
                   beta: float) -> tuple:  # pragma: no cover - compiled
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
    p_tab, l0, l1 = prior_table(comp)
    top = log_len.size - 1
    k_model, k_prior = 0, 0
    tmpl, run = np.zeros(width, dtype=np.int64), np.zeros((width + 1, 4), dtype=np.int64)
    d_new = 0  # the run table's rows from here on are written again
    for _ in range(n_iter + 1):
        n_pos = int(calls.sum())
        if n_pos + 2 > width:  # a longer template: new buffers, the model from flow 0
            width = 2 * (n_pos + 2)
            (state, scale, buf, ck_dist, ck_int, ck_scale, signal, a, ideal,
             reach) = model_buffers(n, width)
            tmpl, run = np.zeros(width, dtype=np.int64), np.zeros((width + 1, 4), dtype=np.int64)
            k_model, d_new = 0, 0
        template_into(calls, flows, tmpl)
        run_rows_from(tmpl, n_pos, run, d_new)
        k = model_restore(k_model, state, scale, buf, ck_dist, ck_int, ck_scale)
        model_advance(run, flows, eps, lam, droop, k, n, state, scale, buf,
                      ck_dist, ck_int, ck_scale, signal, a, ideal, reach)
        prior_from(calls, flows, p_tab, k_prior, n, allow[k_prior] if k_prior > 0 else full,
                   allow, p_pos)
        kt = min(k, k_prior)
        if kt < n_score:
            terms_tab(y, signal, calls, flows, allow, l0, l1, floor, shot, ref, log_len, kt,
                      n_score, cum[kt], cum, beta)
        nll = cum[n_score]
        if nll < best_nll:
            best_nll = nll
            best_calls[:] = calls
        first = -1
        for j in range(kt, n):
            x, m = flows[j], allow[j]
            if likeliest(y[j], a[j], signal[j] - a[j] * calls[j], floor, shot, ref, p_pos[j],
                         l0[x, m], l1[x, m], log_len, min(calls[j], top), row,
                         beta) != calls[j]:
                first = j
                break
        if first < 0:
            break
        new = np.empty(min(first + window, n) - first, dtype=np.int64)
        for j in range(first, first + new.size):
            x, m = flows[j], allow[j]
            new[j - first] = likeliest(y[j], a[j], signal[j] - a[j] * calls[j], floor, shot,
                                       ref, p_pos[j], l0[x, m], l1[x, m], log_len,
                                       min(calls[j], top), row, beta)
        d_new = calls[:first].sum()
        k_model = first_reaching(reach, d_new)
        # the sweep's calls may put one base in two flows' runs: the rows of a run that went on
        # past d_new counted the bases now changed
        while 0 < d_new < n_pos and tmpl[d_new] == tmpl[d_new - 1]:
            d_new -= 1
        k_prior = first
        calls[first:first + new.size] = new
    return best_calls, best_nll


@NJIT
def polish_kernel(y: np.ndarray, flows: np.ndarray, eps: float, lam: float, droop: float,
                  start: np.ndarray, comp: np.ndarray, log_len: np.ndarray, floor: float,
                  shot: float, ref: float, n_try: int, z_min: float, rounds: int,
                  beta: float) -> np.ndarray:  # pragma: no cover - compiled
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
    p_tab, l0, l1 = prior_table(comp)
    prior_from(calls, flows, p_tab, 0, n, full, allow, p_pos)
    nll = terms_tab(y, signal, calls, flows, allow, l0, l1, floor, shot, ref, log_len, 0, n,
                    0.0, cum, beta)
    lb = least_term(floor)
    # the candidates' template and run table, kept equal to the current calls' below ``dirty``
    # so that a candidate rewrites only what it changes (:func:`run_rows_from`)
    b_tmpl, t_tmpl = np.zeros(width, dtype=np.int64), np.zeros(width, dtype=np.int64)
    n_b = template_into(calls, flows, b_tmpl)
    t_tmpl[:n_b] = b_tmpl[:n_b]
    t_run = np.zeros((width + 1, 4), dtype=np.int64)
    run_table_into(t_tmpl, n_b, t_run)
    dirty = n_b + 1
    cs = np.zeros(n + 1, dtype=np.int64)  # cs[k]: template position of flow k's run
    cs[1:] = np.cumsum(calls)
    z, light = np.empty(n), np.empty(n)
    lip, pre, g = np.empty(n + 1), np.zeros((SPANS.size, n + 1)), np.empty((SPANS.size, n))
    k_new = 0  # the flows from here on have new light since the last round
    for _ in range(rounds):
        for k in range(k_new, n):  # each flow's mean: its signal, empty flows' light added
            light[k] = signal[k] + beta if calls[k] == 0 else signal[k]
            mp = max(light[k], 0.0)
            z[k] = abs(y[k] - light[k]) / math.sqrt(floor + shot * mp + ref * mp * mp)
        slopes_from(y, light, floor, shot, ref, k_new, g)
        order = _largest_first(z, z_min, n_try)
        prefix_bounds(g, pre, lip, k_new)
        c_max = calls.max()  # the current template's longest run
        kept = -1
        for i in range(min(n_try, order.size)):
            k = order[i]
            if z[k] < z_min:
                break
            for d in (-1, 1):
                h = calls[k] + d
                if h < 0 or h > top:
                    continue
                n_pos = _candidate_template(b_tmpl, n_b, cs[k], calls[k], h, flows[k],
                                            dirty, t_tmpl)
                dirty = min(dirty, run_rows_from(t_tmpl, n_pos, t_run, min(dirty, cs[k])))
                k0 = first_reaching(reach, cs[k] + min(calls[k], h))
                # the most bases a strand adds in a flow, on either template: a run and the
                # next (carried); a run emptied can merge its neighbours, one made its left one
                step = 2 * (c_max + h if h > 0 else 2 * c_max)
                kc = _score_from(y, flows, eps, lam, droop, t_run, p_tab, l0, l1, log_len,
                                 floor, shot, ref, k0, nll, lb, base, trial, allow, t_allow,
                                 t_pos, cum, t_cum, top, k, cs[k], calls[k], h, step, lip,
                                 pre, beta)
                if kc >= 0:
                    _keep(base, trial, kc, n, allow, t_allow, p_pos, t_pos, cum, t_cum)
                    nll = cum[n]
                    kept = k
                    n_b = n_pos
                    b_tmpl[:n_b] = t_tmpl[:n_b]
                    dirty = n_b + 1
                    cs[1:] = np.cumsum(calls)
                    k_new = kc
                    break
            if kept >= 0:
                break
        if kept < 0:
            break
    return calls.copy()


@NJIT_NORC
def _score_from(y, flows, eps, lam, droop, run, p_tab, l0, l1, log_len, floor, shot, ref, k0,
                nll, lb, base, trial, allow, t_allow, t_pos, cum, t_cum, top, k_run, d0, h_old,
                h, step, lip, pre, beta):  # pragma: no cover
    """Score a candidate template (its ``run`` table) into ``trial`` from the checkpoint before
    flow ``k0``, a checkpoint's worth of flows at a time; returns that checkpoint's flow when
    the candidate beats ``nll`` by more than 1e-9 (and calls no run beyond ``top``), else −1,
    as soon as it cannot: the sum so far plus ``lb`` per flow left is already worse, or the sum
    so far plus the current calls' terms left, less the most the flows left can differ (the
    run of flow ``k_run`` at template position ``d0`` made ``h`` long from ``h_old``; ``step``
    the most bases a strand adds in a flow): by the strands still at or before a run resized
    (:func:`leak_left`, with ``lip``), or, once the flow programs agree again, by the strands
    the two models place apart (:func:`apart`, with ``pre``)."""
    n = y.size
    state, scale, buf, ck_dist, ck_int, ck_scale, _, _, _, reach = base
    t_state, t_scale, t_buf, t_ck_dist, t_ck_int, t_ck_scale, t_signal, t_a, t_calls, \
        t_reach = trial
    kc = model_restore(k0, t_state, t_scale, t_buf, ck_dist, ck_int, ck_scale)
    if kc > 0:
        t_reach[kc - 1] = reach[kc - 1]
    mask = allow[kc] if kc > 0 else (1 << p_tab.shape[0]) - 1
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
        mask = prior_from(t_calls, flows, p_tab, k, ke, mask, t_allow, t_pos)
        total = terms_tab(y, t_signal, t_calls, flows, t_allow, l0, l1, floor, shot, ref,
                          log_len, k, ke, total, t_cum, beta)
        left = (n - ke) * lb if ke < n else 0.0
        slack = 1e-6 * (abs(total) + abs(nll) + abs(left) + 1.0)  # far above rounding error
        if total + left - slack >= nll - 1e-9:
            return -1
        if ke > k_run and ke < n:
            rest = nll - cum[ke]  # the current calls' terms of the flows left
            slack = 1e-6 * (abs(total) + abs(nll) + abs(rest) + 1.0)
            if h_old > 0 and h > 0:  # a run resized: the rest moves by ≤ lip·(strands before it)
                m = leak_left(t_state, t_scale, t_buf, d0)
                if m <= LEAK_SPAN and total + rest - lip[ke] * m - slack >= nll - 1e-9:
                    return -1
            c = ke // CHECK_EVERY
            if (mask == allow[ke] and ck_int[c, 2] >= d0 + h_old
                    and t_state[2] == ck_int[c, 2] + h - h_old):
                # both flow programs past the change and in step: the same calls and priors
                # from here, each flow's light apart by at most e
                e = step * (apart(ck_dist[c], ck_int[c, 0], ck_int[c, 1], t_buf[t_state[4]],
                                  t_state[0], t_state[1], d0 + h_old, d0 + h)
                            + 2.0 * TINY * run.shape[0] * (n - ke))  # strands dropped
                for i in range(SPANS.size):
                    if e <= SPANS[i]:
                        # the flows left's slopes: a difference of prefix sums, widened by
                        # its rounding (relative to the whole prefix, not the tail)
                        tail = pre[i, n] - pre[i, ke] + 4.0 * n * 2.0**-53 * pre[i, n]
                        if total + rest - e * tail - slack >= nll - 1e-9:
                            return -1
                        break
        k = ke
    return kc if total < nll - 1e-9 else -1


@NJIT
def _candidate_template(b_tmpl: np.ndarray, n_b: int, d0: int, h_old: int, h: int, base: int,
                        dirty: int, out: np.ndarray) -> int:  # pragma: no cover - compiled
    """The template of the current calls (``b_tmpl[:n_b]``) with the run of ``h_old`` bases
    ``base`` at position ``d0`` made ``h`` long, written into ``out`` from position
    ``min(dirty, d0)`` on (below it ``out`` already holds the current template); returns its
    length."""
    for p in range(min(dirty, d0), d0):
        out[p] = b_tmpl[p]
    for p in range(d0, d0 + h):
        out[p] = base
    shift = h - h_old
    for p in range(d0 + h, n_b + shift):
        out[p] = b_tmpl[p - shift]
    return n_b + shift


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
def _largest_first(z: np.ndarray, z_min: float, m: int) -> np.ndarray:  # pragma: no cover
    """The first ``m`` of ``np.argsort(-z)``, among the ``z ≥ z_min``: kept sorted by
    insertion while they are all distinct (then the order is the sort's), else the whole sort
    (ties keep its order)."""
    top = np.empty(max(m, 0), dtype=np.int64)
    if m <= 0:
        return top
    cnt = 0
    for k in range(z.size):
        v = z[k]
        if not v >= z_min or (cnt == m and v < z[top[m - 1]]):
            continue
        i = min(cnt, m - 1)  # where it goes; a full list drops its last
        while i > 0 and z[top[i - 1]] < v:
            if i < m:
                top[i] = top[i - 1]
            i -= 1
        if (i > 0 and z[top[i - 1]] == v) or (cnt == m and i == m - 1 and z[top[i]] == v):
            return _sorted_prefix(z, z_min, m)
        top[i] = k
        cnt = min(cnt + 1, m)
    return top[:cnt]


@NJIT
def _sorted_prefix(z: np.ndarray, z_min: float, m: int) -> np.ndarray:  # pragma: no cover
    """:func:`_largest_first` when two of the ``z ≥ z_min`` tie: the whole sort."""
    return np.argsort(-z)[:min(m, int(np.sum(z >= z_min)))]
