"""The evaluation's formulas on series whose answers are known exactly (no bench, no noise), and
the estimators on small tables: each EMVA 1288 Release 4 formula against its definition."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from chiptwin.characterize import evaluate as ev
from chiptwin.characterize.estimators import (
    PairStats,
    StackAccumulator,
    pair_stats,
    spatial_stats,
)
from chiptwin.characterize.measure import SpatialSeries, TemperatureSeries, TemporalSeries
from chiptwin.characterize.protocol import Protocol

K, QE, SIGMA_D, DARK = 0.05, 0.4, 12.0, 200.0  # DN/e⁻, 1, e⁻, e⁻/s


def _pair(mean: float, var: float, n: int = 10_000) -> PairStats:
    return PairStats(mean, var, np.sqrt(var / (2 * n)), var * np.sqrt(2 / n), n)


def linear_camera(n: int = 60, sat_e: float = 20_000.0, nonlinear: float = 0.0) -> TemporalSeries:
    """The standard's linear model, exactly: μ_y = K(ημ_p + μ_I t) (+ a quadratic term),
    σ²_y = K²σ_d² + 1/12 + K²(ημ_p + μ_I t); above ``sat_e`` the output clips and the variance
    collapses to the read noise."""
    t = np.arange(1, n + 1) / n
    mu_p = 1.25 * sat_e / QE * t
    bright, dark = [], []
    for ti, p in zip(t, mu_p, strict=True):
        e = QE * p + DARK * ti
        full = e >= sat_e
        e_c = min(e, sat_e)
        shot = 0.0 if full else e
        mean = K * e_c * (1 + nonlinear * e_c / sat_e)
        bright.append(_pair(mean, K**2 * (SIGMA_D**2 + shot) + 1 / 12))
        dark.append(_pair(K * DARK * ti, K**2 * (SIGMA_D**2 + DARK * ti) + 1 / 12))
    return TemporalSeries(t, mu_p, tuple(bright), tuple(dark), 10_000, 1.0, 100.0, 0.01)


def test_linear_camera_recovered_exactly():
    """K, R = Kη, η, σ_d, μ_I (mean and variance methods) from the exact model, to rounding."""
    t = linear_camera()
    i_sat = ev.saturation_index(t)
    gain, _ = ev.system_gain(t, i_sat)
    resp, _ = ev.responsivity(t, i_sat)
    assert gain == pytest.approx(K, rel=1e-12)
    assert resp / gain == pytest.approx(QE, rel=1e-12)
    _, sigma_d = ev.temporal_dark_noise(ev.dark_variance(t), gain, 0.0)
    assert sigma_d.value == pytest.approx(SIGMA_D, rel=1e-12) and not sigma_d.upper_limit
    by_mean, by_var = ev.dark_current(t, gain, 0.0)
    assert by_mean.value == pytest.approx(DARK, rel=1e-10)
    assert by_var.value == pytest.approx(DARK, rel=1e-10)


def test_fit_ranges_follow_the_standard():
    """K and R: from the first point to the last at ≤ 70 % of μ_y.sat − μ_y.dark; linearity:
    5 %…95 %; saturation: the global maximum of σ²_y."""
    t = linear_camera()
    i_sat = ev.saturation_index(t)
    var = t.column("bright", "var")
    assert var[i_sat] == var.max() and var[i_sat + 1] < var[i_sat]
    y = t.column("bright", "mean") - t.column("dark", "mean")
    sl = ev.sensitivity_range(t, i_sat)
    assert y[sl.stop - 1] <= 0.7 * y[i_sat] < y[sl.stop]
    lin = ev.linearity(t, i_sat).fit_range
    assert y[lin.start - 1] < 0.05 * y[i_sat] <= y[lin.start]
    assert y[lin.stop - 1] <= 0.95 * y[i_sat] < y[lin.stop]


def test_saturation_is_the_global_maximum_not_a_local_one():
    """A noise dip before the true peak (a local maximum, as the reference implementation's
    backwards scan can stop at) does not move the saturation point."""
    t = linear_camera()
    i_sat = ev.saturation_index(t)
    bright = list(t.bright)
    bright[i_sat - 5] = _pair(bright[i_sat - 5].mean, bright[i_sat - 4].var * 1.001)
    dipped = TemporalSeries(t.t_exp_s, t.mu_p, tuple(bright), t.dark, t.n_values, 1.0, 0.0, 0.0)
    assert ev.saturation_index(dipped) == i_sat


def test_linearity_error_of_a_perfect_and_a_bent_response():
    """LE = (max δ − min δ)/2 of the 1/y-weighted line: 0 for the linear camera; for a response
    bent by 2 % at saturation, the half-spread of the relative deviations of that very line."""
    t = linear_camera()
    assert ev.linearity(t, ev.saturation_index(t)).le == pytest.approx(0.0, abs=1e-10)
    bent = linear_camera(nonlinear=0.02)
    lin = ev.linearity(bent, ev.saturation_index(bent))
    y = bent.column("bright", "mean") - bent.column("dark", "mean")
    sl = lin.fit_range
    slope, offset = np.polyfit(bent.mu_p[sl], y[sl], 1, w=1 / y[sl])
    dev = 100 * (y[sl] - (offset + slope * bent.mu_p[sl])) / (offset + slope * bent.mu_p[sl])
    assert lin.le == pytest.approx((dev.max() - dev.min()) / 2, rel=1e-9)
    assert 0.1 < lin.le < 2.0


def test_quantisation_floor_gives_an_upper_limit():
    """σ²_y.dark < 0.24 DN²: σ_d ≤ √(0.24 − 1/12)/K = 0.40/K (the standard's bound)."""
    sigma_y, sigma_d = ev.temporal_dark_noise(ev.Figure(0.1, 0.001), 0.002, 0.0)
    assert sigma_y.value == pytest.approx(np.sqrt(0.1))
    assert sigma_d.upper_limit and sigma_d.value == pytest.approx(0.3958 / 0.002, rel=1e-3)


def test_sensitivity_threshold_solves_snr_equal_one():
    """μ_p.min is the root of SNR(μ_p) = ημ_p / √(σ²_y.dark/K² + ημ_p) = 1 (Release 4's exact
    form, not 3.1's σ_y.dark/K + 1/2 approximation)."""
    sigma_y = 2.0
    p_min = ev.sensitivity_threshold(QE, sigma_y, K)

    def snr(p: float) -> float:
        return QE * p / np.sqrt(sigma_y**2 / K**2 + QE * p) - 1

    assert p_min == pytest.approx(brentq(snr, 1.0, 1e6), rel=1e-10)


def test_regressions_against_numpy():
    """OLS coefficients equal numpy's; the sandwich covariance with equal variances is the
    textbook σ²(XᵀX)⁻¹; the origin slope is Σxy/Σx²."""
    rng = np.random.default_rng(1)
    x = np.linspace(0, 1, 30)
    y = 2 + 3 * x + rng.normal(0, 0.1, x.size)
    coef, cov = ev.ols(x, y, np.full(x.size, 0.01))
    assert coef[::-1] == pytest.approx(np.polyfit(x, y, 1), rel=1e-12)
    design = np.column_stack([np.ones_like(x), x])
    assert cov == pytest.approx(0.01 * np.linalg.inv(design.T @ design), rel=1e-12)
    slope, se = ev.origin_slope(x, 3 * x, np.full(x.size, 0.04))
    assert slope == pytest.approx(3.0) and se == pytest.approx(0.2 / np.sqrt(np.sum(x * x)))


def test_doubling_temperature_exact():
    """μ_I(T) = μ_I(25 °C)·2^((T − 25)/6.5) at six temperatures → T_d = 6.5 °C."""
    temps = 25.0 + np.array([-10.0, -5, 0, 5, 10, 15])
    t_exp = np.linspace(1, 6, 6)
    rows = tuple(tuple(_pair(K * DARK * 2 ** ((tc - 25) / 6.5) * te, 1.0) for te in t_exp)
                 for tc in temps)
    fig = ev.doubling_temperature(TemperatureSeries(temps, t_exp, rows), K)
    assert fig.value == pytest.approx(6.5, rel=1e-9)


def test_nonuniformity_split_into_column_row_pixel():
    """A pure column pattern (σ = 2 DN) plus a pure pixel pattern (σ = 1 DN), no temporal noise:
    the column part carries the 2 DN, the row part none, DSNU₁₂₈₈ both (√5 DN), in e⁻ via K."""
    rng = np.random.default_rng(4)
    rows, cols = 64, 80
    col = rng.normal(0, 2, cols)
    col -= col.mean()
    img = 100 + col[None, :] + rng.normal(0, 1, (rows, cols))
    zero = np.zeros((rows, cols))
    sp = SpatialSeries(1.0, 1e4, 16, img + 50, zero, img, zero)
    f = ev.nonuniformity(sp, K, 0.0)
    assert f["dsnu_dn"].value == pytest.approx(np.sqrt(img.var(ddof=1)))
    assert f["dsnu"].value == pytest.approx(f["dsnu_dn"].value / K)
    assert f["dsnu_col"].value * K == pytest.approx(col.std(), rel=0.1)
    assert f["dsnu_row"].value is None or f["dsnu_row"].value * K < 0.3
    assert f["prnu"].value is None  # bright = dark + constant: no photo-response spread


def test_pair_stats_removes_fixed_pattern_and_drift():
    """σ²_y = var(A − B)/2: a pattern common to both images and a shift of B's mean vanish."""
    rng = np.random.default_rng(2)
    pattern = rng.normal(0, 50, 100_000)
    a = pattern + rng.normal(0, 3, pattern.size)
    b = pattern + 7.0 + rng.normal(0, 3, pattern.size)
    p = pair_stats(a, b)
    assert p.var == pytest.approx(9.0, rel=5 * np.sqrt(2 / pattern.size) * 2)
    assert p.mean == pytest.approx((a.mean() + b.mean()) / 2)


def test_stack_accumulator_and_spatial_stats():
    """The running sums give numpy's mean image and ddof-1 variance; s²_y removes σ²_stack/L."""
    rng = np.random.default_rng(3)
    fpn = rng.normal(1000, 5, (32, 32))
    frames = fpn + rng.normal(0, 2, (16, 32, 32))
    acc = StackAccumulator()
    for f in frames:
        acc.add(f)
    mean, var = acc.result()
    assert mean == pytest.approx(frames.mean(axis=0), rel=1e-12)
    assert var == pytest.approx(frames.var(axis=0, ddof=1), rel=1e-9)
    s = spatial_stats(mean, var, 16)
    assert s.s2 == pytest.approx(mean.var(ddof=1) - var.mean() / 16)
    assert abs(s.s2 - fpn.var(ddof=1)) < 5 * s.s2_se


@pytest.mark.parametrize("field, value", [("n_points", 49), ("spatial_frames", 8),
                                          ("overdrive", 1.0), ("dark_exposures", 1),
                                          ("temperature_offsets_C", (0.0,))])
def test_protocol_refuses_less_than_the_standard(field, value):
    with pytest.raises(ValueError, match=field):
        Protocol(**{field: value})


def test_sensitivity_threshold_sigma_matches_its_spread():
    """μ_p.min = (√(σ_y² + K²/4) + K/2)/R: K's error nearly cancels. An ideal linear camera made
    with numpy (K 0.05 DN/e⁻, η 0.5, 30 e⁻ read noise, 4,096 pixels, 50 points), 60 seeds: the
    stated σ of μ_p.min is its spread within 30 % (it was 2.7× the spread, K's error counted
    in η and in σ_y/K both; 9× on the bench's adc10 chip)."""
    import types

    from chiptwin.characterize.datasheet import _saturation_figures

    k, eta, sd, npix, sat_e = 0.05, 0.5, 30.0, 4096, 20000.0
    t = np.arange(1, 51) / 50
    mu_p = 1.25 * sat_e / eta * t

    def img(rng, e):
        return np.round(k * (np.minimum(rng.poisson(e, npix), sat_e)
                             + rng.normal(0, sd, npix)) + 100)

    values, stated = [], []
    for rep in range(60):
        rng = np.random.default_rng(rep)
        bright = tuple(pair_stats(img(rng, eta * m), img(rng, eta * m)) for m in mu_p)
        dark = tuple(pair_stats(img(rng, 0.0), img(rng, 0.0)) for _ in mu_p)
        ts = TemporalSeries(t, mu_p, bright, dark, npix, 0.0, 0.0, 0.0)
        i = ev.saturation_index(ts)
        gain, gain_se = ev.system_gain(ts, i)
        resp, resp_se = ev.responsivity(ts, i)
        sigma_y, _ = ev.temporal_dark_noise(ev.dark_variance(ts), gain, gain_se)
        m = types.SimpleNamespace(temporal=ts, camera=types.SimpleNamespace(pixel_area_um2=1.0))
        f = _saturation_figures(m, i, sigma_y, gain, gain_se, resp, resp_se)
        values.append(f["absolute_sensitivity_threshold"].value)
        stated.append(f["absolute_sensitivity_threshold"].std_error)
    ratio = np.std(values, ddof=1) / np.mean(stated)
    assert 0.7 < ratio < 1.3, ratio
