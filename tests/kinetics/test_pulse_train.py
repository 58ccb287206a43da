"""PulseTrain: the exact window integral against a slow obvious reference, mpmath and quadrature."""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import integrate

from chiptwin.kinetics import LightSource, PulseTrain, superpose

# --- slow, obvious references ---------------------------------------------------------------


def reference_rate(train: PulseTrain, t_s) -> np.ndarray:
    """Loop over pulses, numpy over times."""
    t = np.asarray(t_s, dtype=float)
    out = np.zeros((train.n_sites, t.size))
    for s, t0, a, k in zip(train.site, train.onset_s, train.amplitude_per_s, train.decay_per_s,
                           strict=True):
        out[s] += np.where(t >= t0, a * np.exp(-k * np.clip(t - t0, 0, None)), 0.0)
    return out


def reference_photons_mp(train: PulseTrain, edges, dps: int = 60) -> np.ndarray:
    """The integral in 60 digits: A/k (e^{-k(a-t0)} - e^{-k(b-t0)}), or A (b - a) at k = 0."""
    mpmath.mp.dps = dps
    out = np.zeros((train.n_sites, len(edges) - 1))
    for s, t0, a, k in zip(train.site, train.onset_s, train.amplitude_per_s, train.decay_per_s,
                           strict=True):
        t0m, am, km = mpmath.mpf(float(t0)), mpmath.mpf(float(a)), mpmath.mpf(float(k))
        for i in range(len(edges) - 1):
            lo = max(mpmath.mpf(float(edges[i])), t0m)
            hi = max(mpmath.mpf(float(edges[i + 1])), t0m)
            if km == 0:
                value = am * (hi - lo)
            else:
                value = am / km * (mpmath.exp(-km * (lo - t0m)) - mpmath.exp(-km * (hi - t0m)))
            out[s, i] += float(value)
    return out


def one_pulse(k, t0=0.0, a=1.0, n_sites=1, site=0) -> PulseTrain:
    return PulseTrain(site=[site], onset_s=[t0], amplitude_per_s=[a], decay_per_s=[k],
                      n_sites=n_sites)


# --- equivalence with the references -------------------------------------------------------


def test_photons_match_scipy_quad():
    """Window integrals vs scipy.integrate.quad of the rate (rel 1e-10), mixed pulses and sites."""
    train = PulseTrain(site=[0, 0, 1, 2], onset_s=[0.0, 5.0, 2.5, 1.0],
                       amplitude_per_s=[3.0, 1.5, 2e8, 7.0], decay_per_s=[0.05, 1.0, 0.1, 0.0],
                       n_sites=3)
    edges = np.array([-3.0, 0.0, 0.7, 2.5, 4.0, 5.0, 9.0, 30.0, 100.0])
    got = train.photons(edges)
    for s in range(3):
        for i in range(edges.size - 1):
            points = [p for p in train.onset_s if edges[i] < p < edges[i + 1]]
            want = integrate.quad(lambda t, s=s: train.rate([t])[s, 0], edges[i], edges[i + 1],
                                  points=points or None, epsabs=0, epsrel=1e-13, limit=200)[0]
            assert got[s, i] == pytest.approx(want, rel=1e-10, abs=1e-300)


def test_rate_matches_reference():
    rng = np.random.default_rng(1)
    train = PulseTrain(site=rng.integers(0, 4, 30), onset_s=rng.uniform(-5, 50, 30),
                       amplitude_per_s=rng.uniform(0, 1e9, 30),
                       decay_per_s=rng.choice([0.0, 0.05, 1.0, 1e3], 30), n_sites=5)
    t = rng.uniform(-10, 100, 200)
    np.testing.assert_allclose(train.rate(t), reference_rate(train, t), rtol=1e-13, atol=0)
    assert (train.rate(t)[4] == 0).all()  # a site without pulses is dark


@pytest.mark.parametrize("k", [1e-3, 0.05, 1.0, 30.0, 1e3, 1e6])
def test_photons_match_mpmath_across_decay_rates(k):
    """k from 1e-3 to 1e6 s⁻¹, windows from 1 ms to 1e4 s: every window to rel 1e-12."""
    train = one_pulse(k, t0=3.0, a=5.3e8)
    edges = np.concatenate([[0.0, 3.0, 3.001, 3.1, 4.0, 13.0], 13.0 + np.cumsum([50, 1e4, 1e4])])
    got = train.photons(edges)
    want = reference_photons_mp(train, edges)
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=0)


def test_grouped_pulses_match_mpmath():
    """Many pulses per (site, decay) group, onsets inside windows, on edges, duplicated, before the
    first edge and after the last: the grouped kernel equals the per-pulse sum (rel 1e-12)."""
    rng = np.random.default_rng(3)
    n = 60
    onset = np.concatenate([rng.uniform(-20, 130, n - 6), [0.0, 10.0, 10.0, 55.5, 200.0, -1e3]])
    train = PulseTrain(site=rng.integers(0, 3, n), onset_s=onset,
                       amplitude_per_s=rng.uniform(0, 1e9, n),
                       decay_per_s=rng.choice([0.0, 0.05, 1.0, 40.0], n), n_sites=4)
    edges = np.concatenate([[-5.0, 0.0], np.arange(1.0, 121.0, 2.5), [121.0, 121.0, 150.0]])
    got = train.photons(edges)
    np.testing.assert_allclose(got, reference_photons_mp(train, edges), rtol=1e-12, atol=0)
    assert (got[3] == 0).all()


def test_pyrosequencing_like_train_over_many_windows():
    """100 flows × 8 sites against 10 000 one-second frames (rel 1e-12 vs the 60-digit value for a
    sample of windows; the whole matrix against the float per-pulse formula at rel 1e-11)."""
    flows = np.arange(100)
    site = np.repeat(np.arange(8), 100)
    train = PulseTrain(site=site, onset_s=np.tile(flows * 60.0 + 0.25, 8),
                       amplitude_per_s=np.tile((flows % 4 + 1) * 5.3e8, 8),
                       decay_per_s=np.full(800, 0.05), n_sites=8)
    edges = np.arange(10_001.0)
    got = train.photons(edges)
    a, k, t0 = train.amplitude_per_s, train.decay_per_s, train.onset_s
    lo = np.maximum(edges[None, :-1], t0[:, None])
    hi = np.maximum(edges[None, 1:], t0[:, None])
    per_pulse = a[:, None] / k[:, None] * np.exp(-k[:, None] * (lo - t0[:, None])) * -np.expm1(
        -k[:, None] * (hi - lo))
    want = np.zeros_like(got)
    np.add.at(want, site, per_pulse)
    np.testing.assert_allclose(got, want, rtol=1e-11, atol=0)
    sample = np.array([0, 1, 59, 60, 61, 3000, 5999, 6000, 9999])
    for i in sample:
        np.testing.assert_allclose(got[:, i], reference_photons_mp(train, edges[i:i + 2])[:, 0],
                                   rtol=1e-12)


def test_late_windows_keep_relative_precision():
    """A window 600 decay times after onset: the difference-of-cumulatives form would return 0."""
    train = one_pulse(0.05, a=1.0)
    edges = np.array([12_000.0, 12_001.0, 22_000.0])
    got = train.photons(edges)
    want = reference_photons_mp(train, edges)
    assert got[0, 0] > 0
    np.testing.assert_allclose(got, want, rtol=1e-12)


def test_hard_cases_are_finite():
    """Zero light, k = 0 over 1e4 s, huge k, underflowing exponentials: no NaN or inf."""
    train = PulseTrain(site=[0, 1, 2, 3], onset_s=[0.0, 0.0, 1e-9, 5e3],
                       amplitude_per_s=[0.0, 2.0, 1e300, 1.0], decay_per_s=[1e6, 0.0, 1e300, 1e-3],
                       n_sites=4)
    edges = np.array([0.0, 1e-12, 1.0, 1e4, 2e4, 1e8])
    got = train.photons(edges)
    assert np.isfinite(got).all() and (got >= 0).all()
    assert (got[0] == 0).all()
    np.testing.assert_allclose(got[1], 2.0 * np.diff(edges), rtol=1e-15)
    assert got[2, 1] == pytest.approx(1.0, rel=1e-12)  # A/k = 1, all inside the second window
    assert np.isfinite(train.rate([0.0, 1e-9, 1e8])).all()
    np.testing.assert_allclose(got, reference_photons_mp(train, edges), rtol=1e-12)


def test_windows_before_onset_and_partial_windows():
    train = one_pulse(0.5, t0=10.0, a=4.0)
    got = train.photons([0.0, 5.0, 9.0, 11.0, 11.0, 12.0])
    assert got[0, 0] == 0 and got[0, 1] == 0
    assert got[0, 2] == pytest.approx(4.0 / 0.5 * -math.expm1(-0.5), rel=1e-14)
    assert got[0, 3] == 0  # a zero-width window


def test_pulse_train_is_a_light_source():
    assert isinstance(one_pulse(0.1), LightSource)


def test_total_photons():
    train = PulseTrain(site=[0, 0, 1, 2], onset_s=[0, 1, 0, 0], amplitude_per_s=[1.0, 2.0, 3.0, 0],
                       decay_per_s=[0.5, 0.25, 0.0, 0.0], n_sites=4)
    np.testing.assert_allclose(train.total_photons(), [10.0, np.inf, 0.0, 0.0])


@settings(max_examples=200, deadline=None)
@given(
    k=st.floats(0.0, 1e4),
    onsets=st.lists(st.floats(-100, 100), min_size=1, max_size=5),
    a=st.floats(0.0, 1e12),
    cuts=st.lists(st.floats(-200, 1e4), min_size=3, max_size=3),
)
def test_window_integral_is_additive(k, onsets, a, cuts):
    """Property: photons over [a, c] = photons over [a, b] + [b, c], all ≥ 0, for a group of
    pulses sharing one site and decay rate."""
    lo, mid, hi = sorted(cuts)
    m = len(onsets)
    train = PulseTrain(site=[0] * m, onset_s=onsets, amplitude_per_s=[a] * m,
                       decay_per_s=[k] * m, n_sites=1)
    parts = train.photons([lo, mid, hi])[0]
    whole = train.photons([lo, hi])[0, 0]
    assert (parts >= 0).all()
    assert parts.sum() == pytest.approx(whole, rel=1e-12, abs=1e-300)


def test_superpose_adds_light():
    a, b = one_pulse(0.1, a=2.0, n_sites=2), one_pulse(0.0, a=1.0, n_sites=2, site=1)
    both = superpose(a, b)
    edges = [0.0, 1.0, 2.0]
    np.testing.assert_allclose(both.photons(edges), a.photons(edges) + b.photons(edges))
    with pytest.raises(ValueError, match="n_sites differ"):
        superpose(a, one_pulse(0.1))


def test_arrays_are_read_only_copies():
    onset = np.array([0.0])
    train = PulseTrain(site=[0], onset_s=onset, amplitude_per_s=[1.0], decay_per_s=[0.0],
                       n_sites=1)
    onset[0] = 5.0
    assert train.onset_s[0] == 0.0
    with pytest.raises(ValueError):
        train.onset_s[0] = 1.0


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"site": [2]}, r"site = 2 .*\[0, 2\)"),
        ({"site": [0.5]}, r"site has dtype float64"),
        ({"amplitude_per_s": [-1.0]}, r"amplitude_per_s = -1.0 .*>= 0"),
        ({"decay_per_s": [np.inf]}, r"decay_per_s = inf .*finite"),
        ({"onset_s": [0.0, 1.0]}, r"onset_s has shape \(2,\)"),
        ({"n_sites": -1}, r"n_sites = -1"),
        ({"n_sites": 1.5}, r"n_sites = 1.5"),
    ],
)
def test_bad_construction(kwargs, match):
    base = {"site": [0], "onset_s": [0.0], "amplitude_per_s": [1.0], "decay_per_s": [0.1],
            "n_sites": 2}
    with pytest.raises(ValueError, match=match):
        PulseTrain(**{**base, **kwargs})


@pytest.mark.parametrize(
    ("edges", "match"),
    [
        ([1.0], r"t_edges_s has shape \(1,\)"),
        ([0.0, 2.0, 1.0], r"non-decreasing: t_edges_s\[2\] = 1.0 < t_edges_s\[1\] = 2.0"),
        ([0.0, np.nan], r"t_edges_s = nan"),
    ],
)
def test_bad_edges(edges, match):
    with pytest.raises(ValueError, match=match):
        one_pulse(0.1).photons(edges)
