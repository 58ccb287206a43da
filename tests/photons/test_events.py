"""Photon streams: exact arrival times (events) against the Poisson-process laws and binned counts.

Statistical tests use fixed seeds (deterministic) and state their tolerance: z-scores below 5
(≈ 6e-7 two-sided) for moments, p-values above 1e-3 for KS and chi-square tests. (Over 60 seeds
the window-count z-scores had standard deviation 0.9–1.13, as they should.)
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy import stats
from scipy.optimize import brentq

from chiptwin.kinetics import PulseTrain
from chiptwin.kinetics.cascade import cascade_pyrosequencing
from chiptwin.photons import (
    PhotonEvents,
    _kernels,
    arrival_times,
    binned,
    counts_from_events,
    detected_electrons,
    expected_counts,
    saturation_time,
    saturation_time_from_rate,
)
from chiptwin.twin.stages import EventPixels

SOURCE = PulseTrain(  # a fast flash, a slow decay, a late onset and a constant glow
    site=[0, 0, 1, 1], onset_s=[0.0, 2.5, 0.0, 1.0], amplitude_per_s=[4000.0, 9000.0, 50.0, 400.0],
    decay_per_s=[0.3, 20.0, 0.0, 0.05], n_sites=2)
WEIGHTS = np.array([[0.9, 0.05], [0.1, 0.6]])  # two pixels, cross-talk both ways


def rescaled_intervals(source, weights, events: PhotonEvents, p: int) -> np.ndarray:
    """Λ_p(t_i) − Λ_p(t_{i−1}) with the source's own exact window integral."""
    edges = np.concatenate([[events.t_start_s], events.pixel(p)])
    return (weights @ source.photons(edges))[p]


# --- the kernel against a slow obvious reference ----------------------------------------------


def reference_inverse(target, area, hra, hrb):
    """Plain bisection on F(s) = target to 1e-15."""
    lo, hi = 0.0, 1.0
    while hi - lo > 1e-15:
        s = 0.5 * (lo + hi)
        f = area * (3 * s**2 - 2 * s**3) + hra * (s - 2 * s**2 + s**3) + hrb * (s**3 - s**2)
        lo, hi = (s, hi) if f < target else (lo, s)
    return 0.5 * (lo + hi)


def test_cell_inversion_matches_bisection():
    rng = np.random.default_rng(11)
    for _ in range(300):
        area = rng.uniform(0.1, 100.0)
        hra, hrb = rng.uniform(0.0, 3.0 * area, 2)  # the monotone (Fritsch–Carlson) box
        u = rng.uniform()
        got = _kernels.invert_cell(u * area, 0.0, area, hra, hrb)
        assert got == pytest.approx(reference_inverse(u * area, area, hra, hrb), abs=1e-13)


# --- the Poisson-process laws ---------------------------------------------------------------


def test_time_rescaled_intervals_are_exp1():
    """Time-rescaling theorem: Λ(t_i) − Λ(t_{i−1}) are iid Exp(1). KS on ≈ 14 000 and 3 700."""
    events = arrival_times(SOURCE, 0.0, 12.0, np.random.default_rng(2024), WEIGHTS)
    assert events.cdf_rel_error <= 1.1e-9
    for p in range(2):
        tau = rescaled_intervals(SOURCE, WEIGHTS, events, p)
        assert tau.size > 3000
        assert stats.kstest(tau, "expon").pvalue > 1e-3
        assert np.all(np.diff(events.pixel(p)) >= 0)
        assert events.pixel(p).min() >= 0.0 and events.pixel(p).max() <= 12.0


def test_time_rescaled_intervals_of_a_cascade_source_are_exp1():
    src = cascade_pyrosequencing([1e-21], "TA", "TA", 2, 6.0, 0.5)  # ≈ 1e4 photons per base
    events = arrival_times(src, 0.0, 12.0, np.random.default_rng(7))
    tau = rescaled_intervals(src, np.eye(1), events, 0)
    assert tau.size > 5000
    assert stats.kstest(tau, "expon").pvalue > 1e-3


@pytest.fixture(scope="module")
def many_pixels():
    """500 independent copies of the two pixels (same rates): 500 draws in one call."""
    weights = np.tile(WEIGHTS, (500, 1))
    edges = np.array([0.0, 0.05, 0.4, 2.5, 2.6, 4.0])
    return weights, edges


@pytest.mark.parametrize("edges_given", [True, False])
def test_window_counts_have_poisson_mean_and_variance(many_pixels, edges_given):
    weights, edges = many_pixels
    events = arrival_times(SOURCE, edges[0], edges[-1], np.random.default_rng(5), weights,
                           t_edges_s=edges if edges_given else None)
    counts = counts_from_events(events, edges).reshape(500, 2, -1)
    mu = (WEIGHTS @ SOURCE.photons(edges))
    n = counts.shape[0]
    z_mean = (counts.mean(axis=0) - mu) / np.sqrt(mu / n)
    # var of the sample variance of a Poisson(μ): (μ + 2μ²(n/(n−1))) / n ≈ (μ + 2μ²) / n
    z_var = (counts.var(axis=0, ddof=1) - mu) / np.sqrt((mu + 2 * mu**2) / n)
    assert np.abs(z_mean).max() < 5
    assert np.abs(z_var).max() < 5


def test_events_in_windows_are_distributed_as_binned_counts(many_pixels):
    """Chi-square two-sample test per window (counts histogram, sparse tails pooled) between
    aggregated events and binned Poisson draws."""
    weights, edges = many_pixels
    ev = counts_from_events(arrival_times(SOURCE, edges[0], edges[-1],
                                          np.random.default_rng(8), weights), edges)
    bn = binned(SOURCE, edges, np.random.default_rng(9), weights)
    assert bn.dtype == np.int64 and bn.shape == ev.shape
    for p in range(2):
        for w in range(edges.size - 1):
            a, b = ev[p::2, w], bn[p::2, w]
            lo, hi = np.percentile(np.concatenate([a, b]), [2, 98]).astype(int)
            bins = np.arange(lo, hi + 2)
            if bins.size < 3:
                continue
            ha = np.histogram(np.clip(a, lo, hi), bins)[0]
            hb = np.histogram(np.clip(b, lo, hi), bins)[0]
            keep = (ha + hb) > 0
            assert stats.chi2_contingency(np.stack([ha[keep], hb[keep]]))[1] > 1e-3


def test_same_seed_same_times_and_expected_counts():
    a = arrival_times(SOURCE, 0.0, 3.0, np.random.default_rng(1), WEIGHTS)
    b = arrival_times(SOURCE, 0.0, 3.0, np.random.default_rng(1), WEIGHTS)
    np.testing.assert_array_equal(a.times_s, b.times_s)
    np.testing.assert_allclose(a.expected, expected_counts(SOURCE, [0.0, 3.0], WEIGHTS)[:, 0],
                               rtol=1e-12)


def test_zero_light_and_empty_window():
    dark = PulseTrain(site=[0], onset_s=[5.0], amplitude_per_s=[1e3], decay_per_s=[1.0],
                      n_sites=1)
    events = arrival_times(dark, 0.0, 4.0, np.random.default_rng(0))
    assert events.times_s.size == 0 and events.expected[0] == 0.0
    assert arrival_times(dark, 3.0, 3.0, np.random.default_rng(0)).times_s.size == 0
    np.testing.assert_array_equal(events.counts([0.0, 2.0, 4.0]), [[0, 0]])


def test_too_many_photons_points_to_binned():
    bright = PulseTrain(site=[0], onset_s=[0.0], amplitude_per_s=[1e12], decay_per_s=[0.0],
                        n_sites=1)
    with pytest.raises(ValueError, match=r"1e\+12 expected photons.*use the binned level"):
        arrival_times(bright, 0.0, 1.0, np.random.default_rng(0))
    counts = binned(bright, [0.0, 1.0], np.random.default_rng(0))
    assert abs(counts[0, 0] - 1e12) < 6 * 1e6  # Poisson(1e12): σ = 1e6


# --- electrons: QE thinning, dark current, full well ---------------------------------------------


def test_thinning_and_dark_current_keep_poisson_means():
    glow = PulseTrain(site=[0], onset_s=[0.0], amplitude_per_s=[2000.0], decay_per_s=[0.0],
                      n_sites=1)
    weights = np.ones((400, 1))
    events = arrival_times(glow, 0.0, 1.0, np.random.default_rng(3), weights)
    e = detected_electrons(events, np.random.default_rng(4), qe=0.4, dark_e_per_s=300.0)
    n = np.diff(e.offsets)
    mu = 0.4 * 2000.0 + 300.0
    assert abs(n.mean() - mu) < 5 * np.sqrt(mu / n.size)
    assert abs(n.var(ddof=1) - mu) < 5 * np.sqrt((mu + 2 * mu**2) / n.size)
    np.testing.assert_allclose(e.expected, mu)


def test_saturation_time_is_gamma_distributed():
    """Constant light r, QE q, dark D: electrons arrive at λ = q r + D, so the well of N e⁻ fills
    at a Gamma(N, λ) time: mean N / λ, variance N / λ²."""
    glow = PulseTrain(site=[0], onset_s=[0.0], amplitude_per_s=[5000.0], decay_per_s=[0.0],
                      n_sites=1)
    events = arrival_times(glow, 0.0, 1.0, np.random.default_rng(12), np.ones((600, 1)))
    t_sat = saturation_time(events, 1000.0, np.random.default_rng(13), qe=0.5,
                            dark_e_per_s=500.0, initial_e=0.0)
    lam = 0.5 * 5000.0 + 500.0
    mean, sd = 1000.0 / lam, np.sqrt(1000.0) / lam
    assert np.isfinite(t_sat).all()
    assert abs(t_sat.mean() - mean) < 5 * sd / np.sqrt(t_sat.size)
    assert t_sat.std(ddof=1) == pytest.approx(sd, rel=0.15)
    full = saturation_time(events, 1000.0, np.random.default_rng(13), initial_e=1000.0)
    assert (full == 0.0).all()
    never = saturation_time(events, 1e7, np.random.default_rng(13))
    assert np.isinf(never).all()


def test_counts_from_plain_times_and_bad_input():
    np.testing.assert_array_equal(counts_from_events([0.1, 0.2, 1.0, 1.5], [0.0, 1.0, 2.0]),
                                  [2, 2])
    with pytest.raises(ValueError, match="sorted times"):
        counts_from_events([0.3, 0.1], [0.0, 1.0])
    with pytest.raises(ValueError, match=r"weights has shape \(2, 3\): must be \(n_pixels, 2\)"):
        arrival_times(SOURCE, 0.0, 1.0, np.random.default_rng(0), np.ones((2, 3)))
    with pytest.raises(ValueError, match=r"t_stop_s = -1.0 is out of range"):
        arrival_times(SOURCE, 0.0, -1.0, np.random.default_rng(0))
    with pytest.raises(ValueError, match=r"qe = 1.5 is out of range"):
        saturation_time(arrival_times(SOURCE, 0.0, 0.1, np.random.default_rng(0)), 10.0,
                        np.random.default_rng(0), qe=1.5)


def test_saturation_time_from_rate_has_the_event_based_distribution():
    """Λ⁻¹(Gamma(N, 1)) vs the N-th detected event of arrival_times, on a decaying flash plus
    dark current: two-sample KS, p > 1e-3; and the Gamma law for constant light."""
    weights = np.tile(WEIGHTS[:1], (400, 1))
    events = arrival_times(SOURCE, 0.0, 6.0, np.random.default_rng(21), weights)
    by_events = saturation_time(events, 3000.0, np.random.default_rng(22), qe=0.6,
                                dark_e_per_s=100.0)
    direct = saturation_time_from_rate(SOURCE, 0.0, 6.0, 3000.0, np.random.default_rng(23),
                                       weights, qe=0.6, dark_e_per_s=100.0)
    assert np.isfinite(by_events).all() and np.isfinite(direct).all()
    assert stats.ks_2samp(by_events, direct).pvalue > 1e-3
    glow = PulseTrain(site=[0], onset_s=[0.0], amplitude_per_s=[1e12], decay_per_s=[0.0],
                      n_sites=1)  # 1e12 photons/s: far beyond arrival_times' max_events
    t_sat = saturation_time_from_rate(glow, 0.0, 1.0, 6e6, np.random.default_rng(24),
                                      np.ones((500, 1)), qe=0.4, initial_e=[1e6] * 250 + [0] * 250)
    lam = 0.4e12
    for sl, n in ((slice(0, 250), 5e6), (slice(250, 500), 6e6)):
        mean, sd = n / lam, np.sqrt(n) / lam
        assert abs(t_sat[sl].mean() - mean) < 5 * sd / np.sqrt(250)
    never = saturation_time_from_rate(glow, 0.0, 1e-6, 6e6, np.random.default_rng(0))
    assert np.isinf(never).all()


def test_event_pixels_fill_time_is_the_root_of_the_exact_integral():
    """``EventPixels._invert`` (Newton inside a bisection bracket) against ``scipy``'s brentq on
    the same exact Λ, to 1e-12 s: targets from 1e-9 of the window's electrons to all of them,
    a window that opens before any light (rate 0 there: the bisection fallback) and one
    inside a decaying flash (Newton's case); Λ crosses the target at the returned time."""
    late = PulseTrain(site=[0, 1, 1], onset_s=[1.0, 1.5, 2.2], amplitude_per_s=[5000.0, 800.0,
                      3e4], decay_per_s=[0.5, 3.0, 40.0], n_sites=2)
    sensor = SimpleNamespace(qe=0.6, gain_map=np.array([1.0, 0.9]), dark_e_per_s=np.zeros(2),
                             full_well_e=1e4)
    ev = EventPixels(late, WEIGHTS, np.arange(2), sensor, np.random.default_rng(0))
    for t0, t1 in ((0.0, 3.0), (2.3, 2.4)):
        total = ev.electrons_until(t0, np.full(2, t1))
        for frac in (1e-9, 0.25, 0.5, 0.999999, 1.0):
            got = ev._invert(t0, t1, frac * total, total)
            for p in range(2):
                def excess(t, p=p, t0=t0, frac=frac, total=total):
                    return ev.electrons_until(t0, np.full(2, t))[p] - frac * total[p]

                root = brentq(excess, t0, t1, xtol=1e-15, rtol=4 * np.finfo(float).eps)
                assert got[p] == pytest.approx(root, abs=1e-12), (t0, frac, p)
                assert excess(got[p] - 1e-11) < 0 <= excess(min(got[p] + 1e-11, t1)) + 1e-9


@pytest.mark.parametrize("well", [300.0, 100.0])
def test_event_pixels_fill_times_have_the_law_of_drawing_every_arrival(well):
    """The ``events`` level's filling time, ``Λ⁻¹(Λ(T)·B)`` with ``B ~ Beta(W, N − W + 1)`` given
    the window's count N, against the W-th of N electrons drawn arrival by arrival
    (``arrival_times`` thinned by QE and merged with dark current) on the same counts: a
    decaying flash plus dark current, 4,000 pixels, Λ(T) ≈ 300 e⁻; a 300-electron well fills in
    about half the windows (the same ones on both sides), a 100-electron one in all, a third of
    the way through the light; two-sample KS, p > 1e-3 (a Beta(W + 5, ·) fails it)."""
    n = 4000
    weights = np.tile(WEIGHTS[:1], (n, 1))
    sensor = SimpleNamespace(qe=0.6, gain_map=np.ones(n), dark_e_per_s=np.full(n, 40.0),
                             full_well_e=well)
    drawn = detected_electrons(arrival_times(SOURCE, 0.0, 0.14, np.random.default_rng(31),
                                             weights), np.random.default_rng(32), qe=0.6,
                               dark_e_per_s=40.0)
    by_events = saturation_time(drawn, well, np.random.default_rng(33))
    ev = EventPixels(SOURCE, weights, np.arange(n), sensor, np.random.default_rng(34))
    ev.fill(0.0, 0.14, np.diff(drawn.offsets).astype(float))
    by_order = ev.saturation_s[0]
    assert np.array_equal(np.isinf(by_events), np.isinf(by_order))
    filled = np.isfinite(by_events)
    assert (1000 < filled.sum() < 3000) if well == 300.0 else filled.all()
    assert stats.ks_2samp(by_events[filled], by_order[filled]).pvalue > 1e-3
    assert np.all((by_order[filled] > 0.0) & (by_order[filled] < 0.14))
