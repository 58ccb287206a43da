"""The ladder's and ``benchmarks/bench_auto.py``'s estimator of a level's error: the ratio of
the means with a delta-method Student-t interval (:mod:`chiptwin.fidelity.compare`), checked by
Monte Carlo on synthetic cases whose truth is known."""

from __future__ import annotations

import math

import numpy as np
import pytest

from chiptwin.fidelity.compare import (
    Difference,
    mean_difference,
    ratio_of_means,
    ratio_of_means_arrays,
    worst,
)

#: Monte Carlo cases per coverage check: the empirical coverage of a 95 % interval then has a
#: binomial standard error √(0.95·0.05/4000) = 0.0034; the checks allow ±0.015 (4.4 σ) for the
#: delta method's own small-sample error at the n used (Casella & Berger 2002, §5.5.4: the
#: interval is first-order, its coverage error O(1/n)).
CASES = 4000


def _snr_draws(rng, n, cv, shape):
    """Reference-SNR-like draws: positive, mean 100, coefficient of variation ``cv`` (gamma)."""
    k = 1 / cv**2
    return rng.gamma(k, 100 / k, size=(n, *shape))


@pytest.mark.parametrize("cv, n, paired", [(0.3, 30, False), (0.1, 10, False),
                                           (0.3, 10, True)])
def test_ratio_of_means_interval_covers_the_truth_at_its_level(cv, n, paired):
    """A level whose SNR is the reference's times 1.005 in law: independent draws (levels that
    draw differently) or the same draws with a small extra noise (common random numbers). The
    95 % interval covers the true +0.5 % in 95 % ± 1.5 % of the cases."""
    rng = np.random.default_rng(7)
    y = _snr_draws(rng, n, cv, (CASES,))
    if paired:
        x = 1.005 * y * (1 + 0.002 * rng.standard_normal(y.shape))
    else:
        x = 1.005 * _snr_draws(rng, n, cv, (CASES,))
    value, half = ratio_of_means_arrays(x, y)
    covered = np.mean(np.abs(value - 0.005) <= half)
    assert covered == pytest.approx(0.95, abs=0.015)


def test_the_mean_of_per_seed_ratios_is_biased_by_the_squared_cv():
    """Two levels with the SAME law (true difference 0) drawn independently: the mean of the
    per-seed ratios x_i/y_i − 1, the old estimator, comes out near CV² (E[1/y] ≈ (1 + CV²)/E[y],
    second-order delta method; 1/Gamma's exact mean gives CV²/(1 − CV²) = 0.0989 at CV 0.3),
    and its nominal 95 % interval (1.96·sd/√n) misses 0 far more often than 5 %; the ratio of
    means is unbiased to O(CV²/n) and covers 0 at its level."""
    rng = np.random.default_rng(3)
    cv, n = 0.3, 30
    x, y = _snr_draws(rng, n, cv, (CASES,)), _snr_draws(rng, n, cv, (CASES,))
    per_seed = x / y - 1
    old = per_seed.mean(axis=0)
    old_half = 1.96 * per_seed.std(axis=0, ddof=1) / math.sqrt(n)
    assert old.mean() == pytest.approx(cv**2 / (1 - cv**2), rel=0.1)
    assert np.mean(np.abs(old) <= old_half) < 0.85
    value, half = ratio_of_means_arrays(x, y)
    assert abs(value.mean()) < 0.01  # O(CV²/n) = 0.003
    assert np.mean(np.abs(value) <= half) == pytest.approx(0.95, abs=0.015)


def test_two_seeds_give_the_student_t_half_width_not_the_normal_one():
    """At n = 2 the t quantile is 12.71 (1 degree of freedom), 6.5× the 1.96 the old figure
    used."""
    x, y = np.array([[101.0], [103.0]]), np.array([[100.0], [100.0]])
    d = ratio_of_means(x, y)[0]
    assert d.value == pytest.approx(0.02)
    assert d.half == pytest.approx(12.706 * math.sqrt(2) / math.sqrt(2) / 100, rel=1e-3)
    # one seed's spread sd(x − R·y)/ȳ = 0.0141: (1.96 · 0.0141 / 0.001)² = 768 seeds, a few
    # more for the t quantile at that count
    assert not d.resolved(1e-3) and 768 < d.seeds_to_resolve(1e-3) < 800 * 1.1
    one = ratio_of_means(x[:1], y[:1])[0]
    assert one.half == math.inf and one.seeds_to_resolve(1e-3) is None


def test_seeds_to_resolve_is_the_count_whose_interval_is_that_narrow():
    """The count promised gives, drawn afresh, a half-width at the resolution (within its own
    sampling spread)."""
    rng = np.random.default_rng(5)
    y = _snr_draws(rng, 8, 0.2, (1,))
    x = _snr_draws(rng, 8, 0.2, (1,))
    need = ratio_of_means(x, y)[0].seeds_to_resolve(0.02)
    big_y, big_x = _snr_draws(rng, need, 0.2, (200,)), _snr_draws(rng, need, 0.2, (200,))
    _, half = ratio_of_means_arrays(big_x, big_y)
    assert np.median(half) == pytest.approx(0.02, rel=0.5)


def test_bounded_by_decides_only_outside_the_interval():
    assert Difference(0.004, 0.001, 10, "").bounded_by(0.006) == "holds"
    assert Difference(-0.009, 0.001, 10, "").bounded_by(0.006) == "exceeds"
    d = Difference(0.005, 0.003, 10, "")
    assert d.bounded_by(0.006) == "unresolved" and d.seeds_to_decide(0.006) > 10
    # a calibrated estimate inside a narrow interval: it is the error, measured again
    near = Difference(0.0012, 0.0003, 80, "")
    assert near.bounded_by(0.0011) == "agrees" and near.seeds_to_decide(0.0011) == 80
    assert near.bounded_by(0.0011, resolution=0.0002) == "unresolved"
    # to decide, the half-width must reach 0.1 % (the gap here is only 0.0001): 3²× the seeds
    assert Difference(0.0012, 0.003, 10, "").seeds_to_decide(0.0011) == pytest.approx(
        90, rel=0.3)


def test_paired_mean_and_worst_site():
    d = mean_difference(np.array([1.0, 1.2, 0.8, 1.0]))
    assert d.value == pytest.approx(1.0) and d.half == pytest.approx(3.182 * 0.1633 / 2, 1e-3)
    sites = ratio_of_means(np.array([[1.0, 2.0], [1.0, 2.2]]), np.array([[1.0, 2.0]] * 2))
    assert worst(sites) is sites[1]


def test_the_worst_of_k_sites_holds_at_its_level_with_bonferroni():
    """Ten sites, each level's law the reference's (truth 0 everywhere), 8 seeds: with each
    site's 95 % interval some site misses 0 in about 1 − 0.95¹⁰ = 40 % of the cases (the worst
    site "exceeds" by chance); with the Bonferroni member level 1 − 0.05/10 the family misses in
    at most 5 % (+1.5 % for the Monte Carlo and the delta method at n = 8)."""
    from chiptwin.fidelity.compare import family_confidence

    rng = np.random.default_rng(13)
    k, n = 10, 8
    x, y = _snr_draws(rng, n, 0.2, (CASES, k)), _snr_draws(rng, n, 0.2, (CASES, k))
    value, half = ratio_of_means_arrays(x, y)
    assert np.mean(np.any(np.abs(value) > half, axis=1)) == pytest.approx(0.40, abs=0.05)
    value, half = ratio_of_means_arrays(x, y, family_confidence(k))
    assert np.mean(np.any(np.abs(value) > half, axis=1)) <= 0.065
    sites = ratio_of_means(x[:, 0], y[:, 0], family=True)
    assert sites[0].confidence == pytest.approx(1 - 0.05 / k)
