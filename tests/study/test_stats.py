"""Intervals: exact against an independent oracle, coverage checked by Monte Carlo."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from chiptwin.detection.stats import (
    clopper_pearson,
    decide,
    loss_db_interval,
    mean_estimate,
    rate_estimate,
)


@pytest.mark.parametrize("k, n", [(0, 1), (0, 30), (3, 30), (15, 30), (30, 30), (1, 3600)])
def test_clopper_pearson_matches_scipy_binomtest(k, n):
    """Oracle: scipy.stats.binomtest(...).proportion_ci(method="exact") (Clopper & Pearson 1934)."""
    ci = stats.binomtest(k, n).proportion_ci(confidence_level=0.95, method="exact")
    lo, hi = clopper_pearson(k, n, 0.95)
    assert lo == pytest.approx(ci.low, abs=1e-12) and hi == pytest.approx(ci.high, abs=1e-12)


def _runs(k: list[int], n: int) -> tuple[np.ndarray, np.ndarray]:
    return np.array(k), np.full(len(k), n)


def test_zero_of_n_reports_the_rule_of_three_bound_never_zero():
    """0 failures in n: the one-sided 95 % upper bound is 1 − 0.05^(1/n) ≈ 3/n, over one run
    or 100 (no variance to measure at k = 0: Korn & Graubard's n* = n)."""
    est = rate_estimate(*_runs([0], 3000), confidence=0.95)
    assert est.value == 0.0 and est.upper == pytest.approx(1 - 0.05 ** (1 / 3000), rel=1e-9)
    assert est.upper == pytest.approx(3 / 3000, rel=0.01) and est.upper > 0
    assert est.n == 1 and est.trials == 3000 and "Clopper" in est.method
    est = rate_estimate(*_runs([0] * 100, 30), confidence=0.95)
    assert est.upper == pytest.approx(1 - 0.05 ** (1 / 3000), rel=1e-9)
    assert est.n == 100 and est.trials == 3000 and est.design_effect == 1.0


def _korn_graubard_oracle(k, n, tail):
    """The bounds at ``tail`` written from the paper's recipe another way: the ratio
    estimator's variance from the sample covariance of (k, n) (S_k² − 2p S_kn + p² S_n²)/(N n̄²);
    the degrees-of-freedom factor only where the design effect is above 1 (else the binomial
    variance, no estimated one)."""
    N, p = len(k), k.sum() / n.sum()
    c = np.cov(np.vstack([k, n]).astype(float))
    var = (c[0, 0] - 2 * p * c[0, 1] + p * p * c[1, 1]) / (N * n.mean() ** 2)
    deff = var / (p * (1 - p) / n.sum())
    n_eff = float(n.sum())
    if deff > 1:
        ratio = stats.t.ppf(1 - tail, n.sum() - 1) / stats.t.ppf(1 - tail, N - 1)
        n_eff = n.sum() / deff * ratio**2
    lo = stats.beta.ppf(tail, p * n_eff, n_eff - p * n_eff + 1)
    hi = stats.beta.ppf(1 - tail, p * n_eff + 1, n_eff - p * n_eff)
    return lo, hi, max(deff, 1.0)


@pytest.mark.parametrize("k", [[0, 0, 0, 12], [3, 1, 0, 2, 5], [1, 1, 1, 1], [30, 2, 0, 0, 9]])
def test_korn_graubard_matches_the_papers_recipe(k):
    """Oracle: Korn & Graubard (1998) computed from the covariance of (k, n), not residuals,
    two-sided (each tail 2.5 %) and one-sided (5 %: the bounds decisions use); each pattern
    repeated over 12 runs (at least 10: the design effect is measured)."""
    k, n = np.tile(k, 3), np.tile([36, 36, 36, 40, 30][: len(k)], 3)
    est = rate_estimate(k, n, 0.95)
    lo, hi, deff = _korn_graubard_oracle(k, n, 0.025)
    lower, upper, _ = _korn_graubard_oracle(k, n, 0.05)
    assert est.design_effect == pytest.approx(deff, rel=1e-9)
    assert (est.lo, est.hi) == pytest.approx((lo, hi), rel=1e-9)
    assert (est.lower, est.upper) == pytest.approx((lower, upper), rel=1e-9)


def test_unclustered_or_few_runs_keep_clopper_pearson():
    """Fewer than 10 runs, no clustering measured (design effect ≤ 1), or one trial a run: the
    plain Clopper–Pearson bounds, so a few runs with one error keep a usable bound
    (Korn–Graubard's degrees-of-freedom factor over 2 runs once made it 0.9997 against 0.142)."""
    est = rate_estimate(np.array([1, 0]), np.array([20, 20]), 0.9833)
    assert est.upper == pytest.approx(clopper_pearson(1, 40, 0.9833, sided="one")[1], rel=1e-12)
    assert "2 runs < 10" in est.method
    spread = rate_estimate(np.array([1] * 10 + [0] * 10), np.full(20, 20), 0.95)
    assert spread.design_effect == 1.0 and spread.upper == pytest.approx(
        clopper_pearson(10, 400, 0.95, sided="one")[1], rel=1e-12)
    valid = rate_estimate(np.array([1] * 19 + [0]), np.ones(20), 0.95)
    assert (valid.lower, valid.upper) == pytest.approx(
        clopper_pearson(19, 20, 0.95, sided="one"), rel=1e-12)
    assert valid.method == "Clopper-Pearson exact (one trial a run)"


def test_errors_in_one_run_widen_the_interval_that_spread_errors_do_not():
    """The same 36 errors in 432 bases: all in three of 12 runs is a design effect of 10.7 and
    a wider interval; 3 in each run measures none (taken as 1)."""
    clumped = rate_estimate(*_runs([12, 0, 0, 0] * 3, 36), 0.95)
    spread = rate_estimate(*_runs([3, 3, 3, 3] * 3, 36), 0.95)
    assert spread.design_effect == 1.0 and clumped.design_effect > 10
    assert clumped.hi > spread.hi and clumped.lo < spread.lo


@pytest.mark.parametrize("p, icc, runs, expected_deff", [(0.02, 0.10, 90, 4.5),
                                                          (0.05, 0.05, 30, 2.75)])
def test_clustered_rate_coverage_is_95_percent_by_monte_carlo(p, icc, runs, expected_deff):
    """Base errors that clump within runs (beta-binomial: each run's rate drawn from a Beta of
    mean p and intra-run correlation icc, 36 bases a run, design effect 1 + 35·icc): the
    Korn–Graubard interval, and its one-sided upper bound, cover p in 95 ± 3 % of 1,500
    repeats, the pooled Clopper–Pearson interval far less (68 % and 78 % measured) — why runs are
    clusters."""
    rng = np.random.default_rng(1998)
    a, b = p * (1 - icc) / icc, (1 - p) * (1 - icc) / icc
    kg = cp = kg_upper = 0
    for _ in range(1500):
        k = rng.binomial(36, rng.beta(a, b, runs))
        est = rate_estimate(k, np.full(runs, 36), 0.95)
        kg += est.lo <= p <= est.hi
        kg_upper += p <= est.upper
        lo, hi = clopper_pearson(int(k.sum()), 36 * runs, 0.95)
        cp += lo <= p <= hi
    assert 0.92 <= kg / 1500 <= 0.98 and 0.92 <= kg_upper / 1500 <= 0.98
    assert cp / 1500 < 0.85


def test_clopper_pearson_coverage_is_95_percent_by_monte_carlo():
    """The one-sided 95 % upper bound covers a known Bernoulli rate in 95 ± 3 % of 2,000
    repeats (exact intervals are conservative: coverage ≥ 95 % up to discreteness)."""
    rng = np.random.default_rng(1934)
    p, n = 0.08, 150
    ks = rng.binomial(n, p, size=2000)
    upper = np.array([clopper_pearson(int(k), n, 0.95, sided="one")[1] for k in ks])
    two = np.array([clopper_pearson(int(k), n, 0.95) for k in ks])
    assert 0.92 <= np.mean(upper >= p) <= 0.98
    assert 0.92 <= np.mean((two[:, 0] <= p) & (p <= two[:, 1])) <= 0.98


def test_t_interval_coverage_is_95_percent_by_monte_carlo():
    rng = np.random.default_rng(1908)
    x = rng.normal(3.0, 2.0, size=(2000, 8))
    cover = [(e.lo <= 3.0 <= e.hi) for e in (mean_estimate(row, 0.95) for row in x)]
    assert 0.92 <= np.mean(cover) <= 0.98


def test_loss_interval_coverage_by_monte_carlo():
    """10·log10(μ_ref/μ) for two independent normal samples: the delta-method interval covers
    the true loss in 95 ± 3 % of repeats."""
    rng = np.random.default_rng(7)
    truth = 10 * math.log10(100.0 / 80.0)
    cover = []
    for _ in range(2000):
        e = loss_db_interval(rng.normal(80.0, 4.0, 20), rng.normal(100.0, 5.0, 20), 0.95)
        cover.append(e.lo <= truth <= e.hi)
    assert 0.92 <= np.mean(cover) <= 0.98


def test_one_run_has_no_interval_and_decides_nothing():
    e = mean_estimate(np.array([1.0]), 0.95)
    assert math.isinf(e.lo) and math.isinf(e.hi)
    assert decide(e, "<=", 10.0) == "undecided"


def test_decisions_use_the_bound_on_each_side():
    e = rate_estimate(*_runs([0] * 100, 36), 0.95)  # upper ≈ 8.3e-4
    assert decide(e, "<=", 1e-3) == "pass"
    assert decide(e, "<=", 5e-4) == "undecided"
    assert decide(rate_estimate(*_runs([5] * 10, 10), 0.95), "<=", 0.1) == "fail"
    assert decide(rate_estimate(*_runs([2] * 50, 2), 0.95), ">=", 0.99) == "undecided"
    assert decide(rate_estimate(*_runs([2] * 500, 2), 0.95), ">=", 0.99) == "pass"


def test_loss_of_a_noiseless_side_is_infinite_or_zero_and_undecided():
    """A point whose power SNR is infinite (no noise) made log10(0) raise; now the loss is −inf
    against a finite reference (+inf the other way, 0 both noiseless) with no interval, so no
    requirement is decided on it."""
    from chiptwin.detection.stats import loss_db_interval

    inf = np.inf
    better = loss_db_interval(np.array([inf, inf]), np.array([10.0, 11.0]), 0.9)
    worse = loss_db_interval(np.array([10.0, 11.0]), np.array([inf, inf]), 0.9)
    both = loss_db_interval(np.array([inf, inf]), np.array([inf, inf]), 0.9)
    assert (better.value, worse.value, both.value) == (-inf, inf, 0.0)
    assert all((e.lo, e.hi) == (-inf, inf) for e in (better, worse, both))
