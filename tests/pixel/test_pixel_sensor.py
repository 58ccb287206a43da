"""Unit and validation tests of chiptwin.pixel.sensor: dark current, kTC, conversion gain, fixed
pattern, and the ``expected`` level against many ``binned`` draws.

Statistical tolerances are 5 standard errors of the estimator, computed from the sample size:
a mean of n draws has standard error √(var/n); a variance, √((m4 − var²)/n) from the sample's own
fourth central moment.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import poisson

from chiptwin.constants import Q_E
from chiptwin.pixel import (
    clipped_poisson_moments,
    conversion_gain_uV_per_e,
    dark_current_e_per_s,
    expected_frame,
    fixed_pattern_maps,
    ktc_noise_e,
    mean_electrons,
    sample_frame,
)


def _var_se(x: np.ndarray, axis: int = 0) -> np.ndarray:
    """Standard error of the sample variance: √((m4 − m2²)/n)."""
    d = x - x.mean(axis=axis)
    m2, m4 = (d**2).mean(axis=axis), (d**4).mean(axis=axis)
    return np.sqrt(np.maximum(m4 - m2**2, 0.0) / x.shape[axis])


# --- dark current -------------------------------------------------------------------------------


def test_dark_current_value_at_reference_temperature():
    """1 nA/cm² on 100 × 100 µm = 1e-13 A = 1e-13/q e⁻/s (unit arithmetic, exact)."""
    assert dark_current_e_per_s(1.0, 1e4, 25.0) == pytest.approx(1e-13 / Q_E, rel=1e-12)


@pytest.mark.parametrize("steps", [-2, -1, 1, 2, 3])
def test_dark_current_doubles_every_7_C(steps):
    """Validation: dark current doubles every 5–8 °C, default 7 °C (Theuwissen, Harvest
    Imaging); i(T0 + n·7 °C) = 2^n · i(T0) to 1e-12 relative."""
    base = dark_current_e_per_s(0.5, 1e4, 25.0)
    assert dark_current_e_per_s(0.5, 1e4, 25.0 + 7.0 * steps) == pytest.approx(
        base * 2.0**steps, rel=1e-12
    )


def test_dark_current_doubling_step_is_a_parameter():
    """A 5 °C doubling step: +5 °C doubles, +10 °C quadruples (Theuwissen, Harvest Imaging: 5–8
    °C)."""
    base = dark_current_e_per_s(1.0, 100.0, 30.0, ref_temp_C=30.0, doubling_C=5.0)
    assert dark_current_e_per_s(1.0, 100.0, 40.0, 30.0, 5.0) == pytest.approx(4 * base)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"j_nA_per_cm2": -1.0}, "j_nA_per_cm2"),
        ({"area_um2": 0.0}, "area_um2"),
        ({"temp_C": -300.0}, "temp_C"),
        ({"doubling_C": 0.0}, "doubling_C"),
        ({"j_nA_per_cm2": float("nan")}, "j_nA_per_cm2"),
    ],
)
def test_dark_current_rejects_bad_arguments(kwargs, name):
    args = {"j_nA_per_cm2": 1.0, "area_um2": 1e4, "temp_C": 25.0} | kwargs
    with pytest.raises(ValueError, match=name):
        dark_current_e_per_s(**args)


# --- kTC and conversion gain --------------------------------------------------------------------


@pytest.mark.parametrize(("c_fF", "published_e"), [(10.0, 40.0), (100.0, 127.0), (1000.0, 402.0)])
def test_ktc_noise_matches_reference(c_fF, published_e):
    """Validation: √(kTC)/q = 40 e⁻ at 10 fF, 127 e⁻ at 100 fF, 402 e⁻ at 1 pF, 300 K
    (sources.md P5). Tolerance: the published figures are rounded to whole electrons,
    ±0.5 e⁻."""
    assert abs(ktc_noise_e(c_fF, 300.0) - published_e) <= 0.5


def test_ktc_noise_scales_as_sqrt_tc():
    assert ktc_noise_e(40.0, 300.0) == pytest.approx(2 * ktc_noise_e(10.0, 300.0), rel=1e-12)
    assert ktc_noise_e(10.0, 75.0) == pytest.approx(0.5 * ktc_noise_e(10.0, 300.0), rel=1e-12)


def test_conversion_gain_of_1pF_diode():
    """Validation: ≈ 1 pF for the 100 µm n-well diode → ≈ 0.16 µV/e⁻ (sources.md P6);
    q/C exact."""
    assert conversion_gain_uV_per_e(1000.0) == pytest.approx(0.1602176634, rel=1e-12)
    assert conversion_gain_uV_per_e(10.0) == pytest.approx(16.02176634, rel=1e-12)


@pytest.mark.parametrize("c", [0.0, -1.0, float("inf")])
def test_capacitance_must_be_positive(c):
    with pytest.raises(ValueError, match="capacitance_fF"):
        ktc_noise_e(c)
    with pytest.raises(ValueError, match="capacitance_fF"):
        conversion_gain_uV_per_e(c)


# --- fixed pattern ------------------------------------------------------------------------------


@pytest.mark.parametrize(("prnu", "dsnu"), [(0.01, 0.1), (0.3, 2.0), (0.0, 0.0)])
def test_fixed_pattern_maps_have_mean_exactly_one(prnu, dsnu):
    """Mean 1 to 1e-12 (Pyxel 3.0.2's PRNU map does not; sources.md A2); dark map ≥ 0."""
    gain, dark = fixed_pattern_maps(np.random.default_rng(3), 50_000, prnu, dsnu)
    assert gain.shape == dark.shape == (50_000,)
    assert abs(gain.mean() - 1.0) < 1e-12 and abs(dark.mean() - 1.0) < 1e-12
    assert gain.min() >= 0.0 and dark.min() >= 0.0


@pytest.mark.parametrize(("prnu", "dsnu"), [(0.01, 0.1), (0.05, 0.5)])
def test_fixed_pattern_maps_have_the_requested_spread(prnu, dsnu):
    """Sample CV within 5 standard errors of the requested fraction (se from the sample's m4)."""
    n = 200_000
    gain, dark = fixed_pattern_maps(np.random.default_rng(4), n, prnu, dsnu)
    for m, frac in ((gain, prnu), (dark, dsnu)):
        assert abs(m.var() - frac**2) < 5 * _var_se(m)


def test_fixed_pattern_maps_reproducible_from_the_generator():
    a = fixed_pattern_maps(np.random.default_rng(9), 100, 0.02, 0.2)
    b = fixed_pattern_maps(np.random.default_rng(9), 100, 0.02, 0.2)
    c = fixed_pattern_maps(np.random.default_rng(10), 100, 0.02, 0.2)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    assert not np.array_equal(a[0], c[0])


def test_fixed_pattern_maps_reject_bad_arguments():
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="n_pixels"):
        fixed_pattern_maps(rng, 0, 0.01, 0.1)
    with pytest.raises(ValueError, match="prnu_frac"):
        fixed_pattern_maps(rng, 10, -0.01, 0.1)
    with pytest.raises(ValueError, match="dsnu_frac"):
        fixed_pattern_maps(rng, 10, 0.01, float("nan"))


# --- mean electrons and the binned frame ----------------------------------------------------------


def test_mean_electrons_table():
    got = mean_electrons([0.0, 100.0, 100.0], 0.5, [1.0, 1.0, 1.1], [3.0, 3.0, 0.0])
    assert np.allclose(got, [3.0, 53.0, 55.0], rtol=0, atol=1e-12)


@pytest.mark.parametrize(
    ("args", "name"),
    [
        (([-1.0], 0.5, 1.0, 0.0), "photons"),
        (([1.0], 1.5, 1.0, 0.0), "qe"),
        (([1.0], 0.5, -1.0, 0.0), "gain_map"),
        (([1.0], 0.5, 1.0, [np.nan]), "dark_e"),
    ],
)
def test_mean_electrons_rejects_bad_arguments(args, name):
    with pytest.raises(ValueError, match=name):
        mean_electrons(*args)


def _frame(rng, photons, **kw):
    args = {"qe": 0.5, "gain_map": 1.0, "dark_e": 0.0, "full_well_e": 1e6, "ktc_e": 0.0}
    args |= {"read_noise_e": 0.0, "n_samples": 1, "true_cds": True} | kw
    return sample_frame(rng, photons, **args)


def test_sample_frame_shapes_and_noiseless_reset():
    reset, signal = _frame(np.random.default_rng(1), np.full((3, 4), 10.0), n_samples=5)
    assert reset.shape == signal.shape == (5, 3, 4)
    assert np.all(reset == 0.0)  # no kTC, no read noise: the reset level is exact
    assert np.all(signal == np.round(signal)) and np.all(signal[0] == signal[4])


def test_sample_frame_clips_at_full_well():
    _, signal = _frame(np.random.default_rng(2), np.full(1000, 1e5), full_well_e=2000.5)
    assert signal.max() == 2000.5


def test_sample_frame_without_charge_is_pure_noise():
    reset, signal = _frame(np.random.default_rng(2), np.zeros(100), qe=0.9)
    assert np.all(signal == 0.0) and np.all(reset == 0.0)


def test_true_cds_cancels_the_shared_ktc_draw_exactly():
    """True CDS, no read noise: signal − reset is the collected charge, an integer, to 1e-9 e⁻,
    though each sample carries 402 e⁻ rms of kTC; without true CDS it is not."""
    ph = np.full(10_000, 200.0)
    reset, signal = _frame(np.random.default_rng(5), ph, ktc_e=402.0)
    d = (signal - reset)[0]
    assert reset.std() > 300.0
    assert np.abs(d - np.round(d)).max() < 1e-9 and d.min() >= 0.0
    reset, signal = _frame(np.random.default_rng(5), ph, ktc_e=402.0, true_cds=False)
    assert (signal - reset).std() > 500.0


@pytest.mark.parametrize("true_cds", [True, False])
def test_ktc_in_cds_difference(true_cds):
    """No true CDS keeps 2σ_kTC² in signal − reset; true CDS cancels it (sources.md P5:
    kTC is removed by sampling right after reset). 1 pF, 402 e⁻; tolerance 5 se of the variance."""
    ktc = ktc_noise_e(1000.0)
    reset, signal = _frame(
        np.random.default_rng(6),
        np.full(200_000, 2000.0),
        ktc_e=ktc,
        read_noise_e=20.0,
        true_cds=true_cds,
    )
    d = (signal - reset)[0]
    expected = 1000.0 + 2 * 20.0**2 + (0.0 if true_cds else 2 * ktc**2)
    assert abs(d.var() - expected) < 5 * _var_se(d)


# --- the expected level against many binned draws ---------------------------------------------

_CASES = {
    "mult regime": dict(photons=8.0, dark=1.5),
    "ptrs regime": dict(photons=3000.0, dark=40.0),
    "at full well": dict(photons=2000.0, dark=0.0),
    "saturated": dict(photons=3000.0, dark=0.0),
    "dark only": dict(photons=0.0, dark=7.0),
}


@pytest.mark.parametrize("case", sorted(_CASES))
@pytest.mark.parametrize(("m", "true_cds"), [(1, True), (4, True), (3, False)])
def test_expected_frame_agrees_with_sample_frame(case, m, true_cds):
    """expected_frame's mean and variance of mean(signal) − mean(reset) agree with 100 000 draws
    of sample_frame within 5 standard errors (full well 1000.5 e⁻, kTC 40 e⁻, read 12 e⁻)."""
    c = _CASES[case]
    n = 100_000
    kw = dict(
        qe=0.5,
        gain_map=1.0,
        dark_e=c["dark"],
        full_well_e=1000.5,
        ktc_e=40.0,
        read_noise_e=12.0,
        n_samples=m,
        true_cds=true_cds,
    )
    reset, signal = sample_frame(np.random.default_rng(7), np.full(n, c["photons"]), **kw)
    d = signal.mean(axis=0) - reset.mean(axis=0)
    mean, var = expected_frame(np.array([c["photons"]]), **kw)
    assert abs(d.mean() - mean[0]) < 5 * np.sqrt(var[0] / n)
    assert abs(d.var() - var[0]) < 5 * _var_se(d)


@pytest.mark.parametrize("lam", [0.0, 0.3, 9.0, 10.0, 500.0, 999.0, 1000.0, 1003.0, 5000.0])
@pytest.mark.parametrize("cap", [1000.0, 1000.5])
def test_clipped_poisson_moments_against_direct_sum(lam, cap):
    """Closed form against Σ min(k, cap)·p(k) over k ≤ 20 000 (tail < 1e-300), to 1e-9."""
    k = np.arange(20_001)
    p = poisson.pmf(k, lam) if lam > 0 else (k == 0).astype(float)
    v = np.minimum(k, cap)
    mean = (p * v).sum()
    var = (p * (v - mean) ** 2).sum()
    got_mean, got_var = clipped_poisson_moments(lam, cap)
    assert got_mean == pytest.approx(mean, rel=1e-9, abs=1e-12)
    assert got_var == pytest.approx(var, rel=1e-9, abs=1e-9)


@pytest.mark.parametrize(
    ("kw", "name"),
    [
        ({"full_well_e": 0.0}, "full_well_e"),
        ({"ktc_e": -1.0}, "ktc_e"),
        ({"read_noise_e": float("inf")}, "read_noise_e"),
        ({"n_samples": 0}, "n_samples"),
        ({"n_samples": 2.0}, "n_samples"),
    ],
)
def test_sample_and_expected_frame_reject_bad_arguments(kw, name):
    args = (
        dict(
            photons=[1.0],
            qe=0.5,
            gain_map=1.0,
            dark_e=0.0,
            full_well_e=10.0,
            ktc_e=0.0,
            read_noise_e=1.0,
            n_samples=1,
            true_cds=True,
        )
        | kw
    )
    with pytest.raises(ValueError, match=name):
        sample_frame(np.random.default_rng(0), **args)
    with pytest.raises(ValueError, match=name):
        expected_frame(**args)
