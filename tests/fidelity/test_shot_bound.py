"""``auto``'s charge for the ``gaussian`` shot level: what the rounded normal
``max(0, rint(λ + √λ·z))`` (the run's kernel draws exactly this law: the χ² test in
``tests/test_fidelity.py``) changes in the moments the figures read, checked by Monte Carlo
against Poisson draws, on single counts and on a window total minus its dark reference."""

from __future__ import annotations

import math

import numpy as np
import pytest

from chiptwin.fidelity import gaussian_tv
from chiptwin.twin.levels import gaussian_moment_bounds, gaussian_moment_errors


def _rounded_normal(rng, lam, size):
    return np.maximum(0.0, np.rint(lam + np.sqrt(lam) * rng.standard_normal(size)))


@pytest.mark.parametrize("lam", [0.5, 3.0, 30.0])
def test_moment_errors_are_the_sampled_ones(lam):
    """1,000,000 counts of each law: the rounded normal's mean and variance minus Poisson's
    agree with :func:`gaussian_moment_errors` within 4 standard errors of the difference (the
    mean's √(2λ/n); the variance's √(2·(μ₄ − σ⁴)/n) ≈ λ√(4/n), normal-theory)."""
    n = 1_000_000
    rng = np.random.default_rng(2)
    g, p = _rounded_normal(rng, lam, n), rng.poisson(lam, n).astype(float)
    dm, dv = gaussian_moment_errors(lam)
    assert g.mean() - p.mean() == pytest.approx(dm, abs=4 * math.sqrt(2 * lam / n))
    assert g.var() - p.var() == pytest.approx(dv, abs=4 * lam * math.sqrt(4 / n) + 1e-3)


def test_moment_bounds_are_the_known_extremes():
    """At λ ≥ 30 the mean is Poisson's to 1e-7 and the variance exceeds it by Sheppard's
    1/12; over every λ the mean's error peaks near 0.081 e⁻ (λ ≈ 0.5), the variance's near
    0.173 e⁻² (λ ≈ 1.6)."""
    dm, dv = gaussian_moment_bounds(30.0)
    assert dm < 1e-7 and dv == pytest.approx(1 / 12, rel=1e-3)
    dm0, dv0 = gaussian_moment_bounds(0.05)
    assert 0.08 < dm0 < 0.085 and 0.17 < dv0 < 0.18
    # past 100 e⁻ the limits themselves, from that mean alone (a bright scene's dimmest site)
    for lam in (100.0, 25683.0):
        dm, dv = gaussian_moment_bounds(lam)
        # the mean's error is 0 to float64's rounding of a ≈ 500-term sum of ≈ 100 e⁻ (7e-12
        # with NumPy 2.4's dot, 1e-13 before); the variance's sums cancel to ~4e-8
        assert dm < 1e-10 and dv == pytest.approx(1 / 12, abs=1e-6)
        assert (dm, dv) == (abs(gaussian_moment_errors(lam)[0]),
                            max(abs(gaussian_moment_errors(lam)[1]), 1 / 12))


@pytest.mark.parametrize("lam_dark, lam_light", [(0.5, 1.5), (20.0, 1000.0)])
def test_window_total_moves_within_the_charge_and_far_below_tv(lam_dark, lam_light):
    """A window total of F = 40 pixel-frames minus F/16 × its 16 dark-reference frames, drawn
    200,000 times at each level: the difference of the means (± 4 standard errors) lies within
    the charge ``2F·sup|E − λ|``, and its variance difference within ``2F²·sup|Var − λ|``. At
    1,000 e⁻ a frame the total-variation distance, once charged as the relative signal error,
    is ≥ 20× what the mean actually moves (its upper 4-σ limit)."""
    f, n_dark, trials = 40, 16, 200_000
    rng = np.random.default_rng(9)

    def totals(draw):
        light = draw(lam_dark + lam_light, (trials, f)).sum(axis=1)
        return light - f / n_dark * draw(lam_dark, (trials, n_dark)).sum(axis=1)

    g = totals(lambda lam, size: _rounded_normal(rng, lam, size))
    p = totals(lambda lam, size: rng.poisson(lam, size).astype(float))
    dm, dv = gaussian_moment_bounds(lam_dark)
    se = math.sqrt((g.var() + p.var()) / trials)
    measured = abs(g.mean() - p.mean())
    assert measured - 4 * se <= 2 * f * dm
    se_var = math.sqrt(2 / trials) * (g.var() + p.var())
    assert abs(g.var() - p.var()) - 4 * se_var <= 2 * f**2 * dv
    signal = f * lam_light
    if lam_light >= 1000:
        assert gaussian_tv(lam_dark + lam_light) * signal >= 20 * (measured + 4 * se)
    else:  # the clip's lift is real at these means, and the charge covers it
        assert measured > 4 * se
