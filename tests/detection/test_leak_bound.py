"""The bounds the hill climb drops candidates on (``chiptwin.detection._bounds``): a run
lengthened or shortened by one base changes the light of the flows after ``k`` by no more, in
sum, than the share of the strands still at or before that run at flow ``k`` (``leak_left``);
any change, once both flow programs are past it, each later flow's light by no more than the
most bases a strand adds in a flow times the strands the two models place apart (``apart``);
and each flow's term of the negative log-likelihood by no more than the slope bound
(``slopes_from``, ``prefix_bounds``) times its light moved. Checked on reads drawn from the
twin's phasing model (Eltoukhy & El Gamal, ICASSP 2006) at 454-like and at four times 454's
phasing, against the exact flowgrams of both call sets. Also the sweep's shortcuts: the prior
table and ``likeliest`` against the functions they stand for."""

from __future__ import annotations

import numpy as np
import pytest

from chiptwin.detection import _bounds as bd
from chiptwin.detection import _read_kernels as rk
from chiptwin.detection import reads
from chiptwin.kinetics import _phasing_kernels as pk
from chiptwin.kinetics import phasing
from tests.detection.test_caller_equivalence import _phased_read


def _terms(y, signal, calls, noise, p_pos, log_len):
    cum = np.zeros(y.size + 1)
    rk.terms_from(y, signal, calls, noise.floor, noise.shot, noise.ref, p_pos, log_len, 0,
                  y.size, 0.0, cum, 0.0)
    return np.diff(cum)


def _current_calls(rng, n, par, sigma):
    """A read drawn from the phasing model, its rounded calls re-derived as the model's flow
    program (the hill climb's current calls), their light, and the slope bounds over it:
    (y, flows, noise, prior, calls, light, pre, lip)."""
    flows = phasing.flow_indices("TACG", n)
    y, noise = _phased_read(rng, n, *par, sigma)
    start = np.clip(np.rint(y), 0, reads.MAX_CALL).astype(np.int64)
    prior = reads.Prior.of(start, flows)
    args = (*par, prior.comp, prior.log_len, noise.floor, noise.shot, noise.ref, 0.0)
    _, s_cur, calls = rk._score(y, flows, start, *args)
    lip, pre, g = np.empty(n + 1), np.zeros((bd.SPANS.size, n + 1)), np.empty((bd.SPANS.size, n))
    bd.slopes_from(y, s_cur, noise.floor, noise.shot, noise.ref, 0, g)
    bd.prefix_bounds(g, pre, lip, 0)
    return y, flows, noise, prior, calls, s_cur, pre, lip


@pytest.mark.parametrize(("par", "sigma", "seed"), [
    ((0.002, 0.01, 0.001), 0.05, 0), ((0.008, 0.04, 0.002), 0.1, 1),
    ((0.004, 0.02, 0.0), 0.3, 2)])
def test_leak_and_slope_bound_the_change_of_the_rest(par, sigma, seed):
    rng = np.random.default_rng(seed)
    n = 240
    y, flows, noise, prior, calls, s_cur, pre, lip = _current_calls(rng, n, par, sigma)
    p_pos = reads.Prior(prior.comp, prior.log_len).p_pos(calls, flows)
    t_cur = _terms(y, s_cur, calls, noise, p_pos, prior.log_len)
    checked, tight = 0, 0
    for k in rng.permutation(np.flatnonzero(calls > 0))[:25]:
        for d in (-1, 1):
            h = calls[k] + d
            if not 1 <= h <= reads.MAX_CALL:
                continue
            cand = calls.copy()
            cand[k] = h
            tmpl = rk.template_of(cand, flows)
            s_new, _, ideal = pk.phase_flows(tmpl, flows, *par)
            assert np.array_equal(ideal, cand)  # a run resized: the flow program is the same
            t_new = _terms(y, s_new, cand, noise, p_pos, prior.log_len)
            d0 = int(calls[:k].sum())
            bufs = pk.model_buffers(n, tmpl.size + 2)
            pk.model_restore(0, *bufs[:6])
            run = pk.run_table(tmpl)
            for ke in range((k // pk.CHECK_EVERY + 1) * pk.CHECK_EVERY, n, pk.CHECK_EVERY):
                pk.model_advance(run, flows, *par, ke - pk.CHECK_EVERY if ke > pk.CHECK_EVERY
                                 * (k // pk.CHECK_EVERY + 1) else 0, ke, *bufs)
                m = bd.leak_left(bufs[0], bufs[1], bufs[2], d0)
                moved = np.abs(s_new[ke:] - s_cur[ke:]).sum()
                assert moved <= m * (1 + 1e-9) + 1e-12
                if m <= bd.LEAK_SPAN:
                    change = t_new[ke:].sum() - t_cur[ke:].sum()
                    assert change >= -lip[ke] * m - 1e-9
                    checked += 1
                    tight += moved > 0.1 * m > 0
    assert checked > 100
    # not a loose stand-in: on many windows the light still moved is a tenth of the bound or more
    assert tight > 0.1 * checked


def test_likeliest_is_call_of_and_the_table_is_context_prior():
    """The sweep's shortcut (``likeliest``: one length's log-posterior exact, the others bounded
    above) returns ``call_of``'s length on every flow, whatever the guess, ties and near ties
    included; the prior table and the terms read from it are ``context_prior``'s and
    ``terms_from``'s, bit for bit."""
    rng = np.random.default_rng(11)
    log_len = np.log(np.r_[1.0, rng.dirichlet(np.ones(reads.MAX_CALL))])
    row = np.zeros(log_len.size)
    top = log_len.size - 1
    agree = 0
    for i in range(20000):
        floor = 10.0 ** rng.uniform(-4, -0.5)
        shot, ref = rng.uniform(0, 0.02), rng.uniform(0, 0.005)
        a, b = rng.uniform(0.05, 1.0), rng.uniform(-0.2, 2.0)
        # the value: on a length, half-way between two (a tie), or anywhere
        h0 = rng.integers(0, top + 1)
        y = [a * h0 + b, a * (h0 + 0.5) + b, rng.uniform(-1, 10)][i % 3]
        p = rng.uniform(rk.P_POS_MIN, 1 - rk.P_POS_MIN)
        beta = (0.0, 0.09, rng.uniform(0, 0.3))[i % 3]  # the empty-flow light
        want = rk.call_of(y, a, b, floor, shot, ref, p, log_len, row, beta)
        for guess in (want, int(rng.integers(0, top + 1))):
            got = rk.likeliest(y, a, b, floor, shot, ref, p, np.log(1 - p), np.log(p), log_len,
                               guess, row, beta)
            agree += got == want
    assert agree == 40000
    n = 500
    flows = phasing.flow_indices("TACG", n)
    calls = rng.integers(0, 3, n) * (rng.uniform(size=n) < 0.5)
    comp = rng.dirichlet(np.ones(4))
    p_tab, l0, l1 = rk.prior_table(comp)
    allow, p_pos = np.zeros(n, dtype=np.int64), np.zeros(n)
    rk.prior_from(calls, flows, p_tab, 0, n, 15, allow, p_pos)
    assert np.array_equal(p_pos, rk.context_prior(calls, flows, comp, 4))
    y, signal = rng.uniform(-0.5, 4, n), rng.uniform(0, 4, n)
    cum_a, cum_b = np.zeros(n + 1), np.zeros(n + 1)
    for beta in (0.0, 0.088):
        rk.terms_from(y, signal, calls, 0.01, 0.01, 0.001, p_pos, log_len, 0, n, 0.0, cum_a,
                      beta)
        rk.terms_tab(y, signal, calls, flows, allow, l0, l1, 0.01, 0.01, 0.001, log_len, 0, n,
                     0.0, cum_b, beta)
        assert np.array_equal(cum_a, cum_b)



def _state_at(tmpl, flows, par, k):
    """A model of ``tmpl`` advanced to flow ``k``: (lo, hi, pos, distribution)."""
    bufs = pk.model_buffers(flows.size, tmpl.size + 2)
    pk.model_restore(0, *bufs[:6])
    pk.model_advance(pk.run_table(tmpl), flows, *par, 0, k, *bufs)
    state, buf = bufs[0], bufs[2]
    return state[0], state[1], state[2], buf[state[4]].copy()


@pytest.mark.parametrize(("par", "sigma", "seed"), [
    ((0.002, 0.01, 0.001), 0.05, 3), ((0.008, 0.04, 0.002), 0.1, 4)])
def test_apart_bounds_every_later_flows_light(par, sigma, seed):
    """Any candidate (a run made, emptied or resized): once both flow programs are past the
    change and call alike, every later flow's light differs by at most ``step`` times
    ``apart`` (plus the strands dropped), and the terms of the flows left by at most that
    times ``prefix_bounds``' sums: the bound the hill climb drops candidates on."""
    rng = np.random.default_rng(seed)
    n = 200
    y, flows, noise, prior, calls, s_cur, pre, lip = _current_calls(rng, n, par, sigma)
    tmpl = rk.template_of(calls, flows)
    c_max = calls.max()
    checked, bounded, near = 0, 0, 0
    for k in rng.permutation(n)[:40]:
        for d in (-1, 1):
            h = calls[k] + d
            if not 0 <= h <= reads.MAX_CALL:
                continue
            cand = calls.copy()
            cand[k] = h
            t_new = rk.template_of(cand, flows)
            s_new, _, ideal = pk.phase_flows(t_new, flows, *par)
            d0 = int(calls[:k].sum())
            step = 2 * (c_max + h if h > 0 else 2 * c_max)
            assert step >= 2 * max(np.diff(np.flatnonzero(np.diff(np.r_[-1, t_new, -1]))))
            p_cur = reads.Prior(prior.comp, prior.log_len)
            for j0 in range((k // pk.CHECK_EVERY + 1) * pk.CHECK_EVERY, n, pk.CHECK_EVERY):
                if not np.array_equal(ideal[j0:], calls[j0:]):
                    continue
                lo_c, hi_c, pos_c, cur = _state_at(tmpl, flows, par, j0)
                lo_n, hi_n, pos_n, new = _state_at(t_new, flows, par, j0)
                if pos_c < d0 + calls[k] or pos_n != pos_c + d:
                    continue
                t = bd.apart(cur, lo_c, hi_c, new, lo_n, hi_n, d0 + calls[k], d0 + h)
                e = step * (t + 2.0 * pk.TINY * (t_new.size + 3) * (n - j0))
                moved = np.abs(s_new[j0:] - s_cur[j0:]).max()
                assert moved <= e
                checked += 1
                near += moved > 0.25 * t > 0  # a light apart by as much as a quarter of it
                i = np.searchsorted(bd.SPANS, e)
                if i < bd.SPANS.size:
                    pp = p_cur.p_pos(calls, flows)
                    assert np.array_equal(p_cur.p_pos(ideal, flows)[j0:], pp[j0:])
                    t_c = _terms(y, s_cur, calls, noise, pp, prior.log_len)
                    t_n = _terms(y, s_new, ideal, noise, pp, prior.log_len)
                    assert t_n[j0:].sum() - t_c[j0:].sum() >= -e * (pre[i, n] - pre[i, j0]) - 1e-9
                    bounded += 1
    assert checked > 50 and bounded > 10
    assert near > 0.1 * checked  # apart is no loose stand-in for the strands moved


def test_the_largest_residuals_come_in_the_sorts_order():
    """The hill climb's flows to try: the first ``m`` of ``argsort(-z)`` among ``z ≥ z_min``,
    by insertion — with ties, NaN and infinities (then the whole sort decides, as it did), and
    none at all for ``m = 0``."""
    rng = np.random.default_rng(9)
    for i in range(3000):
        n = int(rng.integers(0, 60))
        z = rng.uniform(0, 10, n)
        if i % 3 == 0:
            z = np.round(z, 1)  # ties
        if i % 7 == 0 and n:
            z[rng.integers(0, n)] = [np.nan, np.inf][i % 2]
        m, z_min = int(rng.integers(0, 30)), float(rng.uniform(0, 6))
        idx = np.flatnonzero(z >= z_min)
        sub = np.sort(z[idx])
        tied = np.any(sub[1:] == sub[:-1])
        want = (np.argsort(-z, kind="quicksort")[:idx.size] if tied
                else idx[np.argsort(-z[idx])])[:m]
        got = rk._largest_first(z, z_min, m)
        if tied:  # ties keep the sort's order: the same values, in the same order
            assert np.array_equal(z[got], z[want])
        else:
            assert np.array_equal(got, want)
