"""The evaluation of EMVA 1288 Release 4.0 Linear, from the standard's formulas.

The linear camera model: ``μ_y = μ_y.dark + K·η·μ_p`` and
``σ²_y = K²σ²_d + σ²_q + K(μ_y − μ_y.dark)``, with ``σ²_q = 1/12 DN²``. From the photon-transfer
series (exposure time varied at constant irradiance):

* **saturation**: the exposure of the *global* maximum of the temporal variance ``σ²_y``
  (the standard's definition; the ``emva1288`` package takes the first local maximum seen from
  the top; docs/background/sources.md A5);
* **system gain** ``K``: slope of ``σ²_y − σ²_y.dark`` against ``μ_y − μ_y.dark``, and
  **responsivity** ``R = Kη``: slope of ``μ_y − μ_y.dark`` against ``μ_p``, both regressions
  through the origin (the model has no offset once the dark values are subtracted; the reference
  implementation does the same) over the standard's range, from the first point to 70 % of
  ``μ_y.sat − μ_y.dark``; ``η = R/K``;
* **temporal dark noise**: ``σ²_y.dark`` regressed on the exposure time and taken at zero
  exposure (the exposure-independent part; the reference implementation does the same),
  ``σ_d = √(σ²_y.dark − σ²_q)/K``. Below ``σ²_y.dark = 0.24 DN²`` quantisation dominates and the
  standard gives only the upper limit ``σ_d ≤ √(0.24 − 1/12)/K = 0.40/K``; the bench also flags the
  quantisation regime when ``σ_y.dark < 0.5 DN``, where the measured K and σ_d are biased;
* **dark current** ``μ_I``: slope of ``μ_y.dark`` against the exposure time over K (and, as a
  check, slope of ``σ²_y.dark`` over K²); its **doubling temperature** ``T_d`` from
  ``μ_I(T) = μ_I(T₀)·2^((T − T₀)/T_d)`` fitted to the temperature series (log₂ regression);
* **saturation capacity** ``μ_e.sat = η·μ_p.sat``, **SNR_max** ``= √μ_e.sat``;
* **absolute sensitivity threshold** (SNR = 1, Release 4's exact root):
  ``μ_p.min = (√(σ²_y.dark/K² + 1/4) + 1/2)/η``; **dynamic range** ``DR = μ_p.sat/μ_p.min``;
* **linearity**: ``μ_y − μ_y.dark`` against ``μ_p`` fitted with weights 1/y (relative
  deviations) between 5 % and 95 % of saturation; ``δ = 100 (y − fit)/fit`` %,
  ``LE = (max δ − min δ)/2``;
* **DSNU/PRNU** from the spatial stacks: ``s²_y = s²_y.measured − σ²_y.stack/L``;
  ``DSNU₁₂₈₈ = s_y.dark/K`` (e⁻), ``PRNU₁₂₈₈ = √(s²_y.50 − s²_y.dark)/(μ_y.50 − μ_y.dark)`` (%),
  and Release 4's split into column, row and pixel parts.

Standard errors are propagated from the number of values behind every statistic
(:mod:`chiptwin.characterize.estimators`): regressions use the sandwich covariance of the
ordinary least-squares fit with each point's own variance.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from chiptwin.characterize.estimators import spatial_stats

if TYPE_CHECKING:
    from chiptwin.characterize.series import SpatialSeries, TemperatureSeries, TemporalSeries

#: Quantisation noise of one conversion, the standard's σ²_q. Unit: DN².
SIGMA2_Q: float = 1.0 / 12.0
#: Below this σ²_y.dark the standard reports only an upper limit of σ_d. Unit: DN².
QUANTISATION_FLOOR_DN2: float = 0.24
#: Below this σ_y.dark the bench flags the quantisation regime (EMVA 1288 Release 4.0 Linear: below
#: ≈ 0.5 DN K and σ_d are biased). Unit: DN.
QUANTISATION_REGIME_DN: float = 0.5
#: Fit range of K and R: up to this share of μ_y.sat − μ_y.dark (the standard's 70 %).
SENSITIVITY_TOP: float = 0.70
#: Fit range of the linearity: this share of saturation (the standard's 5 % … 95 %).
LINEARITY_RANGE: tuple[float, float] = (0.05, 0.95)


@dataclass(frozen=True)
class Figure:
    """One datasheet figure: its value with what is known of its error.

    ``value`` None: not measurable (``note`` says why). ``upper_limit``: the value is a bound.
    ``resolution``: a grid step that bounds the value besides its statistical error.
    """

    value: float | None
    std_error: float | None = None
    upper_limit: bool = False
    resolution: float | None = None
    note: str = ""


# --- regressions ------------------------------------------------------------------------------

def ols(x: ArrayLike, y: ArrayLike, var_y: ArrayLike) -> tuple[NDArray, NDArray]:
    """Straight line ``y = a + b·x`` by ordinary least squares; covariance from each point's
    variance (sandwich ``(XᵀX)⁻¹ Xᵀ diag(var) X (XᵀX)⁻¹``). Returns ``([a, b], cov)``."""
    xa = np.asarray(x, np.float64)
    design = np.column_stack([np.ones_like(xa), xa])
    inv = np.linalg.inv(design.T @ design)
    coef = inv @ design.T @ np.asarray(y, np.float64)
    cov = inv @ (design.T * np.asarray(var_y, np.float64)) @ design @ inv
    return coef, cov


def origin_slope(x: ArrayLike, y: ArrayLike, var_y: ArrayLike) -> tuple[float, float]:
    """Least-squares slope of ``y = b·x`` through the origin, ``Σxy/Σx²``, and its standard error
    ``√(Σx²·var_y)/Σx²``."""
    xa, ya = np.asarray(x, np.float64), np.asarray(y, np.float64)
    sxx = float(np.sum(xa * xa))
    return float(np.sum(xa * ya) / sxx), float(np.sqrt(np.sum(xa * xa * var_y)) / sxx)


# --- photon transfer ---------------------------------------------------------------------------

def signal(t: TemporalSeries) -> tuple[NDArray, NDArray]:
    """``μ_y − μ_y.dark`` and its variance per point. Unit: DN, DN²."""
    y = t.column("bright", "mean") - t.column("dark", "mean")
    var = t.column("bright", "mean_se") ** 2 + t.column("dark", "mean_se") ** 2
    return y, var


def _noise(t: TemporalSeries) -> tuple[NDArray, NDArray]:
    """``σ²_y − σ²_y.dark`` and its variance per point. Unit: DN², DN⁴."""
    y = t.column("bright", "var") - t.column("dark", "var")
    var = t.column("bright", "var_se") ** 2 + t.column("dark", "var_se") ** 2
    return y, var


def saturation_index(t: TemporalSeries) -> int:
    """Index of the global maximum of the temporal variance σ²_y: saturation."""
    return int(np.argmax(t.column("bright", "var")))


def saturation_dn(t: TemporalSeries) -> float:
    """``μ_y.sat − μ_y.dark`` at saturation. Unit: DN."""
    return float(signal(t)[0][saturation_index(t)])


def sensitivity_range(t: TemporalSeries, i_sat: int) -> slice:
    """The points of the K and R regressions: first to the last with
    ``μ_y − μ_y.dark ≤ 70 %`` of its saturation value, up to saturation (past it the dark signal
    keeps growing under a clipped output, and ``μ_y − μ_y.dark`` falls back into the range)."""
    y, _ = signal(t)
    below = np.flatnonzero(y[: i_sat + 1] <= SENSITIVITY_TOP * y[i_sat])
    return slice(0, int(below.max()) + 1 if below.size else 1)


def system_gain(t: TemporalSeries, i_sat: int) -> tuple[float, float]:
    """K, the photon-transfer slope, and its standard error. Unit: DN/e⁻."""
    sl = sensitivity_range(t, i_sat)
    x, _ = signal(t)
    y, var = _noise(t)
    return origin_slope(x[sl], y[sl], var[sl])


def responsivity(t: TemporalSeries, i_sat: int) -> tuple[float, float]:
    """R = K·η, the sensitivity slope, and its standard error. Unit: DN/photon."""
    sl = sensitivity_range(t, i_sat)
    y, var = signal(t)
    return origin_slope(t.mu_p[sl], y[sl], var[sl])


def half_saturation_exposure(t: TemporalSeries) -> float:
    """Exposure time at which ``μ_y − μ_y.dark`` is half its saturation value (linear
    interpolation along the series): the spatial series' exposure. Unit: s."""
    i_sat = saturation_index(t)
    y, _ = signal(t)
    target = 0.5 * y[i_sat]
    ys, ts = y[: i_sat + 1], t.t_exp_s[: i_sat + 1]
    order = np.argsort(ys, kind="stable")
    return float(np.interp(target, ys[order], ts[order]))


def dark_variance(t: TemporalSeries) -> Figure:
    """σ²_y.dark at zero exposure: intercept of its regression on the exposure time. Unit: DN²."""
    var_dark = t.column("dark", "var")
    if np.unique(t.t_exp_s).size <= 2:
        return Figure(float(var_dark[0]), float(t.dark[0].var_se))
    coef, cov = ols(t.t_exp_s, var_dark, t.column("dark", "var_se") ** 2)
    return Figure(float(coef[0]), float(np.sqrt(cov[0, 0])))


def dark_offset(t: TemporalSeries) -> Figure:
    """μ_y.dark at zero exposure: intercept of the dark mean on the exposure time. Unit: DN."""
    coef, cov = ols(t.t_exp_s, t.column("dark", "mean"), t.column("dark", "mean_se") ** 2)
    return Figure(float(coef[0]), float(np.sqrt(cov[0, 0])))


def dark_current(t: TemporalSeries, gain: float, gain_se: float) -> tuple[Figure, Figure]:
    """μ_I from the dark mean (slope / K) and from the dark variance (slope / K²). Unit: e⁻/s."""
    mean_coef, mean_cov = ols(t.t_exp_s, t.column("dark", "mean"),
                              t.column("dark", "mean_se") ** 2)
    var_coef, var_cov = ols(t.t_exp_s, t.column("dark", "var"), t.column("dark", "var_se") ** 2)
    by_mean = mean_coef[1] / gain
    by_var = var_coef[1] / gain**2
    se_mean = abs(by_mean) * np.hypot(np.sqrt(mean_cov[1, 1]) / abs(mean_coef[1] or 1.0),
                                      gain_se / gain)
    se_var = np.hypot(np.sqrt(var_cov[1, 1]) / gain**2, 2.0 * abs(by_var) * gain_se / gain)
    return Figure(float(by_mean), float(se_mean)), Figure(float(by_var), float(se_var))


def temporal_dark_noise(var0: Figure, gain: float, gain_se: float) -> tuple[Figure, Figure]:
    """σ_y.dark (DN) and σ_d (e⁻), with the standard's floor of 0.24 DN² (an upper limit)."""
    s2 = var0.value if var0.value is not None else 0.0
    sigma_y = Figure(float(np.sqrt(max(s2, 0.0))),
                     float(var0.std_error / (2.0 * np.sqrt(s2))) if s2 > 0 else None)
    if s2 < QUANTISATION_FLOOR_DN2:
        bound = np.sqrt(QUANTISATION_FLOOR_DN2 - SIGMA2_Q) / gain
        return sigma_y, Figure(float(bound), None, upper_limit=True,
                               note=f"σ²_y.dark = {s2:.3g} DN² < 0.24 DN²: quantisation noise "
                                    "dominates; the standard gives only σ_d ≤ 0.40/K")
    sigma_d = np.sqrt(s2 - SIGMA2_Q) / gain
    se = np.hypot(var0.std_error / (2.0 * gain * np.sqrt(s2 - SIGMA2_Q)), sigma_d * gain_se / gain)
    return sigma_y, Figure(float(sigma_d), float(se))


def sensitivity_threshold(qe: float, sigma_y_dark: float, gain: float) -> float:
    """μ_p.min, the photons per pixel that give SNR = 1 (Release 4's exact root of the SNR
    equation): ``(√(σ²_y.dark/K² + 1/4) + 1/2)/η``, σ_y.dark floored at √0.24 DN.
    Unit: photons/pixel."""
    s2 = max(sigma_y_dark**2, QUANTISATION_FLOOR_DN2)
    return float((np.sqrt(s2 / gain**2 + 0.25) + 0.5) / qe)


@dataclass(frozen=True)
class Linearity:
    """The linearity fit: ``fit = offset + slope·μ_p`` over ``range``, δ per point (%)."""

    slope: float
    offset: float
    deviation_pct: NDArray[np.float64]
    fit_range: slice

    @property
    def le_min(self) -> float:
        return float(self.deviation_pct[self.fit_range].min())

    @property
    def le_max(self) -> float:
        return float(self.deviation_pct[self.fit_range].max())

    @property
    def le(self) -> float:
        """``LE = (max δ − min δ)/2``. Unit: %."""
        return 0.5 * (self.le_max - self.le_min)


def linearity(t: TemporalSeries, i_sat: int) -> Linearity:
    """Weighted (1/y) straight line of ``μ_y − μ_y.dark`` on ``μ_p`` between 5 % and 95 % of
    saturation, on the rising part of the series (up to saturation), and the relative deviation
    of every point from it."""
    y, _ = signal(t)
    lo, hi = LINEARITY_RANGE[0] * y[i_sat], LINEARITY_RANGE[1] * y[i_sat]
    rising = y[: i_sat + 1]
    first, last = int(np.flatnonzero(rising >= lo).min()), int(np.flatnonzero(rising <= hi).max())
    sl = slice(first, last + 1)
    slope, offset = np.polyfit(t.mu_p[sl], y[sl], 1, w=1.0 / y[sl])
    fit = offset + slope * t.mu_p
    return Linearity(float(slope), float(offset), 100.0 * (y - fit) / fit, sl)


# --- spatial nonuniformity ---------------------------------------------------------------------

def _split(avg: NDArray, var_stack: float, n_images: int, s2: float) -> dict[str, float | None]:
    """Release 4's column, row and pixel parts of a spatial variance s²_y (images M × N)."""
    m, n = avg.shape
    denom = m * n - m - n
    if m < 2 or n < 2 or denom <= 0:
        return {"col": None, "row": None, "pixel": None}
    mu = avg.mean()
    cav = np.mean((avg.mean(axis=0) - mu) ** 2) - var_stack / (n_images * m)
    rav = np.mean((avg.mean(axis=1) - mu) ** 2) - var_stack / (n_images * n)
    return {"col": float((m * n - m) / denom * cav - n / denom * (s2 - rav)),
            "row": float((m * n - n) / denom * rav - m / denom * (s2 - cav)),
            "pixel": float(m * n / denom * (s2 - cav - rav))}


def nonuniformity(sp: SpatialSeries, gain: float, gain_se: float) -> dict[str, Figure]:
    """DSNU₁₂₈₈ (e⁻ and DN) and PRNU₁₂₈₈ (%), totals with standard errors, and their column, row
    and pixel parts."""
    dark = spatial_stats(sp.dark_mean, sp.dark_var, sp.n_images)
    lit = spatial_stats(sp.bright_mean, sp.bright_var, sp.n_images)
    signal = lit.mean - dark.mean
    out = {"dsnu": _root(dark.s2, dark.s2_se, gain, gain_se),
           "dsnu_dn": _root(dark.s2, dark.s2_se, 1.0, 0.0),
           "prnu": _root(lit.s2 - dark.s2, float(np.hypot(lit.s2_se, dark.s2_se)),
                         signal / 100.0, 0.0)}
    parts_dark = _split(sp.dark_mean, dark.var_stack, sp.n_images, dark.s2)
    parts_lit = _split(sp.bright_mean, lit.var_stack, sp.n_images, lit.s2)
    for part, d2 in parts_dark.items():
        out[f"dsnu_{part}"] = _root(d2, None, gain, None)
        l2 = parts_lit[part]
        both = None if d2 is None or l2 is None else l2 - d2
        out[f"prnu_{part}"] = _root(both, None, signal / 100.0, None)
    return out


def _root(s2: float | None, s2_se: float | None, scale: float, scale_se: float | None) -> Figure:
    """``√s²/scale`` with its standard error; None when the variance is not positive."""
    if s2 is None:
        return Figure(None, note="the image has a single row or column")
    if s2 <= 0:
        bound = None if s2_se is None else float(np.sqrt(2.0 * s2_se) / scale)
        return Figure(None, bound, note="not resolved: the fixed-pattern variance is below the "
                      "temporal noise left in the averaged stack" + (
                          f"; 2σ bound {bound:.3g}" if bound is not None else ""))
    value = float(np.sqrt(s2) / scale)
    if s2_se is None:
        return Figure(value)
    rel = np.hypot(s2_se / (2.0 * s2), (scale_se or 0.0) / scale)
    weak = s2 < 2.0 * s2_se
    return Figure(value, float(value * rel), note="not significant: the fixed-pattern variance "
                  "is within 2σ of zero" if weak else "")


# --- dark current against temperature -----------------------------------------------------------

def dark_current_by_temperature(ts: TemperatureSeries, gain: float) -> tuple[NDArray, NDArray]:
    """μ_I at each temperature (slope of the dark mean on exposure time over K) and its standard
    error. Unit: e⁻/s."""
    values, ses = [], []
    for row in ts.dark:
        means = np.array([p.mean for p in row])
        var = np.array([p.mean_se for p in row]) ** 2
        coef, cov = ols(ts.t_exp_s, means, var)
        values.append(coef[1] / gain)
        ses.append(np.sqrt(cov[1, 1]) / gain)
    return np.array(values), np.array(ses)


def doubling_temperature(ts: TemperatureSeries, gain: float) -> Figure:
    """T_d from a weighted regression of log₂ μ_I on the temperature: ``T_d = 1/slope``. Unit: °C.

    Not measurable (None) when a dark current is not positive by two standard errors.
    """
    mu, se = dark_current_by_temperature(ts, gain)
    if np.any(mu <= 2.0 * se):
        return Figure(None, note="dark current not resolved at every temperature of the series")
    y, w = np.log2(mu), (mu * np.log(2.0) / se) ** 2  # weights: 1/var(log2 μ_I)
    design = np.column_stack([np.ones_like(ts.temperature_C), ts.temperature_C])
    cov = np.linalg.inv(design.T @ (design * w[:, None]))
    slope = float((cov @ design.T @ (w * y))[1])
    if slope <= 0:
        return Figure(None, note="the dark current does not grow with temperature")
    return Figure(1.0 / slope, float(np.sqrt(cov[1, 1]) / slope**2))
