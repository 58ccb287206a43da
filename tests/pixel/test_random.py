"""The kernels' random draws (chiptwin.pixel._random): NumPy's streams and samplers bit for bit,
and the Ahrens–Dieter Poisson sampler in law.

Law tests: Pearson's chi-square against ``scipy.stats.poisson`` over bins of expected count ≥ 20
(tails merged), at a significance of 1e-4 per case (fixed seeds, so the verdicts are
deterministic); and the first three moments within 5 standard errors. That the chi-square test
has the power to see an error of the size that matters is shown on the Gaussian approximation
``max(0, rint(λ + √λ·z))``, which it must reject.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats
from scipy.special import gammaln

from chiptwin.pixel import _random

BIT_GENERATORS = [np.random.PCG64, np.random.SFC64]
POISSON, POISSON_FAST, NORMAL, DOUBLE = 0, 1, 2, 3


def _draw(source, kind: int, lam: np.ndarray) -> np.ndarray:
    out = np.empty(lam.size)
    _random.fill(source, kind, lam, out)
    return out


# --- NumPy's streams and samplers, bit for bit ---------------------------------------------------


@pytest.mark.parametrize("bit_generator", BIT_GENERATORS, ids=lambda b: b.__name__)
def test_inline_streams_are_numpys_and_leave_its_state(bit_generator):
    """Doubles, normals (10⁶: the ziggurat's tail and wedges are taken ≈ 7,000 times) and Poisson
    counts over means 0…10⁷ from a state advanced inline equal the Generator's own draws from
    the same seed, and the state written back continues NumPy's sequence."""
    mine = np.random.Generator(bit_generator(np.random.SeedSequence(17)))
    numpys = np.random.Generator(bit_generator(np.random.SeedSequence(17)))
    source = _random.state_of(mine)
    lam = np.concatenate([
        np.array([0.0, 1e-3, 0.5, 5.0, 9.999999, 10.0, 10.5, 100.0, 1e4, 1e7]).repeat(200),
        np.random.default_rng(3).uniform(0.0, 30.0, 200_000),
        np.random.default_rng(4).uniform(0.0, 5e4, 100_000),
    ])
    assert np.array_equal(_draw(source, DOUBLE, np.zeros(100_000)), numpys.random(100_000))
    assert np.array_equal(_draw(source, NORMAL, np.zeros(1_000_000)),
                          numpys.standard_normal(1_000_000))
    assert np.array_equal(_draw(source, POISSON, lam), numpys.poisson(lam))
    _random.put_state(mine, source)
    assert mine.random() == numpys.random()
    assert mine.standard_normal() == numpys.standard_normal()


def test_a_generator_source_draws_numpys_counts():
    """The same samplers on a Generator (numba's interface: any bit generator) give
    Generator.poisson's counts and leave the same state (numba 0.68's own Generator.poisson
    accepts zero counts NumPy rejects at means ≥ 10)."""
    lam = np.concatenate([np.array([0.0, 1e-3, 0.5, 5.0, 9.999999, 10.0, 10.5, 1e4, 1e7]),
                          np.random.default_rng(5).uniform(0.0, 3e4, 100_000)])
    a = np.random.Generator(np.random.Philox(6))
    b = np.random.Generator(np.random.Philox(6))
    assert _random.state_of(a) is None
    assert np.array_equal(_draw(a, POISSON, lam), b.poisson(lam))
    assert a.random() == b.random()


def test_loggam_matches_scipy():
    x = np.concatenate([np.arange(1.0, 50.0), np.geomspace(50.0, 1e9, 200), [0.5, 3.7]])
    got = np.array([_random.loggam(v) for v in x])
    assert np.allclose(got, gammaln(x), rtol=1e-12, atol=1e-12)


# --- Ahrens & Dieter in law ---------------------------------------------------------------------


def chi_square_p(counts: np.ndarray, lam: float, min_expected: float = 20.0) -> float:
    """p-value of Pearson's chi-square of integer ``counts`` against Poisson(``lam``): bins of
    one count each where the expectation is ≥ ``min_expected``, the two tails merged."""
    n = counts.size
    lo = int(stats.poisson.ppf(1e-9, lam))
    hi = int(stats.poisson.isf(1e-9, lam)) + 1
    k = np.arange(lo, hi)
    expected = n * stats.poisson.pmf(k, lam)
    keep = np.flatnonzero(expected >= min_expected)
    first, last = k[keep[0]], k[keep[-1]]
    edges = np.arange(first, last + 2)
    observed = np.histogram(counts, bins=edges)[0].astype(float)
    exp_mid = n * stats.poisson.pmf(edges[:-1], lam)
    below = (counts < first).sum(), n * stats.poisson.cdf(first - 1, lam)
    above = (counts > last).sum(), n * stats.poisson.sf(last, lam)
    obs = np.concatenate([[below[0]], observed, [above[0]]])
    exp = np.concatenate([[below[1]], exp_mid, [above[1]]])
    chi2 = float(((obs - exp) ** 2 / exp).sum())
    return float(stats.chi2.sf(chi2, obs.size - 1))


@pytest.mark.parametrize("lam", [10.0, 10.5, 17.3, 100.0, 1000.0, 3.7e4, 1e6])
def test_ahrens_dieter_has_the_poisson_law(lam):
    """200,000 draws: chi-square p ≥ 1e-4, mean and variance within 5 standard errors
    (Poisson: var/n for the mean, (μ₄ − σ⁴)/n = (λ + 2λ²)/n for the variance), the skewness
    1/√λ within 5 of its standard errors (≈ √(6/n))."""
    n = 200_000
    source = _random.state_of(np.random.default_rng(int(lam * 10)))
    x = _draw(source, POISSON_FAST, np.full(n, lam))
    assert np.array_equal(x, np.floor(x)) and x.min() >= 0
    assert chi_square_p(x, lam) >= 1e-4
    assert abs(x.mean() - lam) <= 5 * np.sqrt(lam / n)
    assert abs(x.var() - lam) <= 5 * np.sqrt((lam + 2 * lam**2) / n)
    assert abs(stats.skew(x) - 1 / np.sqrt(lam)) <= 5 * np.sqrt(6 / n)


def test_ahrens_dieter_takes_every_branch_at_small_means():
    """At μ = 10–12 the normal falls below zero or its count below ⌊μ − 1.1484⌋ often enough that
    steps Q, E and H (procedure F, below and above 10) all run; pooled over a mixed array the
    counts still follow the mixture law (chi-square per mean)."""
    lams = np.array([10.0, 10.9, 11.5, 12.0])
    n = 100_000
    source = _random.state_of(np.random.default_rng(2))
    x = _draw(source, POISSON_FAST, np.repeat(lams, n)).reshape(lams.size, n)
    for lam, row in zip(lams, x, strict=True):
        assert chi_square_p(row, lam) >= 1e-4
        assert (row < 5).any()  # the deep lower tail (procedure F below 10) is reached


def test_the_chi_square_test_sees_a_wrong_law():
    """The test's power: the Gaussian approximation (total-variation distance ≈ 0.04 at λ = 10,
    ≈ 0.02 at λ = 30) is rejected at the same n, and so is Poisson(λ·(1 + 1 %))."""
    n = 200_000
    rng = np.random.default_rng(9)
    for lam in (10.0, 30.0):
        approx = np.maximum(0.0, np.rint(lam + np.sqrt(lam) * rng.standard_normal(n)))
        assert chi_square_p(approx, lam) < 1e-4
    assert chi_square_p(rng.poisson(1000.0 * 1.01, n).astype(float), 1000.0) < 1e-4


def test_fast_sampler_is_numpys_below_ten():
    """Below a mean of 10 poisson_fast is NumPy's multiplication method, draw for draw."""
    lam = np.random.default_rng(1).uniform(0.0, 9.999, 100_000)
    a = _random.state_of(np.random.default_rng(4))
    b = np.random.default_rng(4)
    assert np.array_equal(_draw(a, POISSON_FAST, lam), b.poisson(lam))
