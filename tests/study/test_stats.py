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


def test_zero_of_n_reports_the_rule_of_three_bound_never_zero():
    """0 failures in n: the one-sided 95 % upper bound is 1 − 0.05^(1/n) ≈ 3/n."""
    est = rate_estimate(0, 3000, runs=100, confidence=0.95)
    assert est.value == 0.0 and est.upper == pytest.approx(1 - 0.05 ** (1 / 3000), rel=1e-9)
    assert est.upper == pytest.approx(3 / 3000, rel=0.01) and est.upper > 0
    assert est.n == 100 and est.trials == 3000 and "Clopper" in est.method


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
    e = rate_estimate(0, 3600, 100, 0.95)  # upper ≈ 8.3e-4
    assert decide(e, "<=", 1e-3) == "pass"
    assert decide(e, "<=", 5e-4) == "undecided"
    assert decide(rate_estimate(50, 100, 10, 0.95), "<=", 0.1) == "fail"
    assert decide(rate_estimate(100, 100, 50, 0.95), ">=", 0.99) == "undecided"
    assert decide(rate_estimate(1000, 1000, 500, 0.95), ">=", 0.99) == "pass"


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
