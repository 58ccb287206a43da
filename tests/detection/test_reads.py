"""The base callers: posterior against numpy, the flow order's prior, dephasing, and quality
calibration by Monte Carlo."""

from __future__ import annotations

import numpy as np
import pytest

from chiptwin.config.consistency import CALLER_MAX_HOMOPOLYMER
from chiptwin.detection import read_stats, reads
from chiptwin.detection._read_kernels import context_prior
from chiptwin.kinetics import phasing, templates


def test_caller_limit_matches_the_consistency_rule():
    assert reads.MAX_CALL == CALLER_MAX_HOMOPOLYMER


@pytest.mark.parametrize("beta", [0.0, 0.088])
def test_posterior_matches_numpy(beta):
    """The posterior kernel against a NumPy oracle, with and without the empty-flow light
    (the mean of a length 0 is the leak plus ``beta``)."""
    rng = np.random.default_rng(2)
    y, a, b = rng.uniform(-0.2, 5, 50), rng.uniform(0.3, 1, 50), rng.uniform(0, 0.3, 50)
    noise = reads.FlowNoise(0.01, 0.004, 0.001)
    p_pos = rng.uniform(0.01, 0.99, 50)
    log_len = np.log(np.r_[1.0, np.full(reads.MAX_CALL, 1.0 / reads.MAX_CALL)])
    post = reads.posterior(y, a, b, noise, p_pos, log_len, beta=beta)
    h = np.arange(reads.MAX_CALL + 1)
    mean = a[:, None] * h + b[:, None] + np.where(h == 0, beta, 0.0)
    var = noise.var(mean)
    prior = np.where(h == 0, np.log(1 - p_pos)[:, None], np.log(p_pos)[:, None] + log_len)
    ll = -0.5 * (y[:, None] - mean) ** 2 / var - 0.5 * np.log(var) + prior
    ref = np.exp(ll - ll.max(axis=1, keepdims=True))
    assert np.allclose(post, ref / ref.sum(axis=1, keepdims=True), atol=1e-12)


def test_context_prior_follows_the_flow_order():
    """After a T, flows A, C, G: A takes 1/3, C (A passed) 1/2, G 1; T again is forbidden."""
    flows = phasing.flow_indices("TACG", 5)
    p = context_prior(np.array([1, 0, 0, 0, 0]), flows, np.full(4, 0.25), 4)
    assert np.allclose(p[1:4], [1 / 3, 1 / 2, 1 - 0.1], atol=1e-12)  # capped at 1 − P_POS_MIN
    assert p[4] == pytest.approx(0.1)  # T after T: the floor


def _read(rng, n_flows, eps, lam, droop, sigma):
    t = "TCAG" + templates.draw_template(n_flows, 0.5, 0.3, 6, rng)
    s, _, ideal = phasing.phased_signal(t, "TACG", n_flows, eps, lam, droop)
    noise = reads.FlowNoise(sigma**2, (sigma / 2) ** 2)
    return s + rng.normal(0, 1, n_flows) * np.sqrt(noise.var(s)), ideal, noise


def test_dephase_reads_through_phasing_where_rounding_fails():
    rng = np.random.default_rng(3)
    flows = phasing.flow_indices("TACG", 300)
    y, ideal, noise = _read(rng, 300, 0.002, 0.01, 0.001, 0.03)
    read = reads.call_dephased(y, flows, noise)
    truth = read_stats.called_truth(ideal, read.n_called)
    rounded = reads.call_rounded(y, flows, noise)
    assert np.abs(read.calls - truth).sum() <= 2
    assert np.abs(rounded.calls - ideal).sum() >= 20
    assert (read.eps, read.lam, read.droop) == pytest.approx((0.002, 0.01, 0.001), abs=0.0011)


def test_the_empty_flows_own_light_is_not_read_as_carry_forward():
    """Reads of the twin's phasing model (ε 0.2 %, λ 1 %, droop 0.1 %, 300 flows, 0-mer sd 0.03)
    whose empty flows carry a further 0.09 of a 1-mer (the 454 FLX profiles' 0-mers sit at
    0.088): with the empty-flow term the caller finds λ 1 % on every read and ε, droop on most,
    β within 0.03 of 0.09, and calls no worse than without it; without the term λ reads 1.5 %
    on most reads (the light taken for carry-forward). Measured over seeds 4–8: λ 1 % on 5 of 5
    with the term, 1.5 % on 3 of 5 without; errors 16 with, 23 without."""
    found, without, errors = [], [], [0, 0]
    for seed in range(4, 9):
        rng = np.random.default_rng(seed)
        flows = phasing.flow_indices("TACG", 300)
        y, ideal, noise = _read(rng, 300, 0.002, 0.01, 0.001, 0.03)
        y = y + np.where(ideal == 0, 0.09, 0.0)
        for i, light in enumerate((True, False)):
            read = reads.call_dephased(y, flows, noise, empty_light=light)
            truth = read_stats.called_truth(ideal, read.n_called)
            errors[i] += int(np.abs(read.calls - truth).sum())
            (found if light else without).append(read)
    assert all(r.lam == 0.01 for r in found)
    assert sum(r.eps == 0.002 and r.droop == 0.001 for r in found) >= 4
    assert all(abs(r.empty_light - 0.09) <= 0.03 for r in found)
    assert sum(r.lam >= 0.015 for r in without) >= 3
    assert errors[0] <= errors[1]


def test_qualities_are_calibrated_monte_carlo():
    """Bases binned by stated quality show the stated error rate, within the 99 % Clopper–
    Pearson interval of the observed rate, from Q10 to Q30: 150 drawn reads of 200 flows,
    454-like noise (0-mer sd 0.08; Balzer et al. 2010 measured 0.074), ε 0.2 %, λ 1 %,
    droop 0.1 %."""
    rng = np.random.default_rng(11)
    flows = phasing.flow_indices("TACG", 200)
    wrong, p_err = [], []
    for _ in range(150):
        y, ideal, noise = _read(rng, 200, 0.002, 0.01, 0.001, 0.08)
        read = reads.call_dephased(y, flows, noise)
        wrong.append(read_stats.base_truth(read.calls,
                                           read_stats.called_truth(ideal, read.n_called)))
        p_err.append(read.base_error())
    w, p = np.concatenate(wrong), np.concatenate(p_err)
    table = read_stats.calibration_table(w, p, reads.phred(p), confidence=0.99)
    rows = [r for r in table if 10 <= r["q_lo"] < 30]
    assert len(rows) == 4 and sum(r["bases"] for r in rows) >= 200
    assert sum(r["errors"] for r in table) > 20  # errors happen: the test can fail
    for r in rows:
        assert r["ci_low"] <= r["stated_error"] <= r["ci_high"], r


def test_read_lengths_and_errors_tables():
    true_n = np.array([1, 0, 2, 0, 1, 3, 0, 1])
    calls = np.array([1, 0, 2, 1, 1, 2, 0, 1])  # an insertion at flow 3, a deletion at 5
    assert read_stats.flow_errors(calls, true_n).tolist() == [0, 0, 0, 1, 0, 1, 0, 0]
    assert read_stats.length_at_accuracy(calls, true_n, 0.01) == 3
    assert read_stats.length_at_accuracy(calls, true_n, 0.25) == 8
    assert read_stats.length_at_quality(np.array([0.0, 0.0, 0.02, 0.5]), 0.01) == 3
    assert read_stats.length_at_quality(np.array([0.05, 0.0, 0.0]), 0.01) == 0
    assert read_stats.base_truth(calls, true_n).tolist() == [
        False, False, False, True, False, False, True, False]
    hp = {r["length"]: r for r in read_stats.homopolymer_errors(calls[None, :], true_n)}
    assert hp[0]["over_calls"] == 1 and hp[3]["under_calls"] == 1 and hp[1]["flows"] == 3
    assert read_stats.called_truth(true_n, 4).tolist() == [1, 0, 2, 0, 0, 0, 0, 0]


def test_noisy_reads_stay_within_the_callers_range():
    """At a 1-mer SNR near 2 the hill climb's trial templates merge runs (a base moved next to
    a run of its own kind): calls stay within MAX_CALL and every called base has a quality
    (a study at 0.003 fmol once failed on a 24-mer here)."""
    rng = np.random.default_rng(4)
    flows = phasing.flow_indices("TACG", 120)
    for _ in range(2):
        y, _, noise = _read(rng, 120, 0.002, 0.01, 0.001, 0.5)
        read = reads.call_dephased(y, flows, noise)
        assert read.calls.max() <= reads.MAX_CALL
        assert read.base_error().size == read.calls.sum()


@pytest.mark.parametrize("n", [1, 5, 8, 16, 17, 40])
def test_local_inflation_is_the_clipped_window_mean_at_every_read_length(n):
    """Each flow's factor is the mean of z² over the flows within RESIDUAL_HALF_WINDOW of it,
    clipped to the read (a direct loop as the oracle); reads shorter than the 17-flow window
    once got 17 factors (NumPy's convolve mode="same") and the dephasing caller crashed."""
    rng = np.random.default_rng(n)
    y, signal = rng.uniform(0, 3, n), rng.uniform(0.1, 3, n)
    noise = reads.FlowNoise(0.01, 0.004, 0.001)
    z2 = (y - signal) ** 2 / noise.var(signal)
    h = reads.RESIDUAL_HALF_WINDOW
    oracle = [max(1.0, z2[max(0, i - h):i + h + 1].mean()) for i in range(n)]
    got = reads.local_inflation(y, signal, noise)
    assert got.shape == (n,)
    np.testing.assert_allclose(got, oracle, rtol=1e-12)


def test_dephasing_caller_reads_eight_flows():
    """The dephasing caller on a read of 8 flows (a shortened run): a call and a posterior for
    each flow, the last TAIL_FLOWS left uncalled as on any read."""
    flows = phasing.flow_indices("TACG", 8)
    y = np.array([1.0, 0.02, 1.01, 0.0, 0.97, 0.05, 2.02, 0.01])
    read = reads.call_dephased(y, flows, reads.FlowNoise(0.004, 0.002, 0.0))
    assert read.calls.shape == (8,) and read.posterior.shape == (8, reads.MAX_CALL + 1)
    np.testing.assert_allclose(read.posterior.sum(axis=1), 1.0, rtol=1e-12)
    assert read.n_called == max(8 - reads.TAIL_FLOWS, 0)
