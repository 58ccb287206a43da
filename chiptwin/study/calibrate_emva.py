"""An EMVA 1288 data set as a fit's target: the photon-transfer series, measured and replayed.

The twin is read through the data set's own protocol (its exposures and photon levels:
:func:`chiptwin.characterize.replay.replay`), and both series go through **the same
statistics**, computed by one function (:func:`statistics`) on each side, each with its
standard error (the pair statistics' own, :mod:`chiptwin.characterize.estimators`, propagated
as :mod:`chiptwin.characterize.evaluate` propagates them):

- **system gain K** and **responsivity R = Kη**: the standard's regressions through the origin
  (``σ²_y − σ²_y.dark`` against ``μ_y − μ_y.dark``; ``μ_y − μ_y.dark`` against ``μ_p``) over the
  standard's range, the first point to the last at ≤ 70 % of ``μ_y.sat − μ_y.dark``
  (:func:`chiptwin.characterize.evaluate.sensitivity_range`), the camera's range for both
  sides (the same points). Not the bright pairs point by point: a real camera's response
  bends (set 001: ``μ_y − μ_y.dark`` from +1.5 % above the standard's line at its second point
  to −0.9 % at saturation, ``σ²/μ`` from +2.5 % over its dim points to −0.5 % at 70 %), so no
  line fits the points and a line's slope depends on how they are weighted. The standard weighs
  them by their signal² (least squares through the origin: the top of the range rules); a χ²
  over the points weighs each by its standard error (nearly equally in relative terms: the
  dimmest, most bent points count as much) and sets the variance against ``μ_p``, not against
  the measured mean. On set 001 that put K 1.5–1.6 % above the closed form's (5 of its standard
  errors) and η 1.4–1.9 % below, over every point below saturation or over the standard's range
  only, the means offset or dark-subtracted (further still without the Birge scaling of the
  means). The standard's own estimates, twin against camera, make the fitted K and η the
  datasheet's;
- **dark mean and variance** at every point (darkness does not bend or saturate; the
  standard's dark figures are straight lines on the exposure time through these points, which
  a χ² over them, their errors nearly equal, weighs as the standard does): the read noise, the
  dark current. The **dark means are compared after an offset**: a real camera's dark level
  (its black level, a few to tens of DN, which moves from image to image) is not the twin's
  reset code, so one offset common to the dark means is fitted as a nuisance parameter, in
  closed form at each candidate (:func:`chiptwin.study.calibrate_data.residuals`); it costs
  one degree of freedom;
- **the variance at saturation**: the bright variance at the camera's saturation point (the
  exposure of its variance's maximum, the standard's saturation, which μ_e.sat and the closed
  form's full well come from). The twin's variance there falls once its full well, or its
  converter's top code, clips the upper tail of its pixels' charge; that bounds ``full_well_e``
  from below. A full well a little above the charge that takes the mean pixel to the top code
  (``(2^bits − ½ − black level)/K``) changes nothing the protocol reads: the interval is then
  open at the top, and says so.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from chiptwin.study.calibrate_data import Measured

#: The statistics compared, in the residual vector's order.
BLOCKS = ("gain K", "responsivity R", "dark mean", "dark var", "var at saturation")


@dataclass(frozen=True)
class Compared:
    """Which points of the photon-transfer series the statistics use, taken from the measured
    series and used for both sides.

    Attributes
    ----------
    top : the standard's range for K and R is the points ``[0, top)``
    saturation : index of the measured series' saturation (its bright variance's maximum)
    n : points in the series
    """

    top: int
    saturation: int
    n: int

    @property
    def sizes(self) -> tuple[int, ...]:
        """Elements of each block of :data:`BLOCKS`."""
        return (1, 1, self.n, self.n, 1)


def comparison(t: Any) -> Compared:
    """The points of a measured ``TemporalSeries`` the fit compares (:class:`Compared`)."""
    from chiptwin.characterize.evaluate import saturation_index, sensitivity_range

    i_sat = saturation_index(t)
    return Compared(int(sensitivity_range(t, i_sat).stop), i_sat, int(np.asarray(t.mu_p).size))


def used_points(t: Any) -> NDArray[np.bool_]:
    """Photon-transfer points whose bright pair enters the fit through K and R: the standard's
    range (first point to 70 % of saturation)."""
    c = comparison(t)
    return np.arange(c.n) < c.top


def statistics(t: Any, c: Compared) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The compared statistics of a ``TemporalSeries`` (measured or the twin's) in
    :data:`BLOCKS`' order, and their standard errors."""
    from chiptwin.characterize.evaluate import origin_slope

    def col(series: str, attr: str) -> NDArray[np.float64]:
        return np.asarray(t.column(series, attr), dtype=float)

    sl = slice(0, c.top)
    signal = (col("bright", "mean") - col("dark", "mean"))[sl]
    signal_var = (col("bright", "mean_se") ** 2 + col("dark", "mean_se") ** 2)[sl]
    noise = (col("bright", "var") - col("dark", "var"))[sl]
    noise_var = (col("bright", "var_se") ** 2 + col("dark", "var_se") ** 2)[sl]
    gain, gain_se = origin_slope(signal, noise, noise_var)
    resp, resp_se = origin_slope(np.asarray(t.mu_p, dtype=float)[sl], signal, signal_var)
    i = c.saturation
    values = np.concatenate([[gain, resp], col("dark", "mean"), col("dark", "var"),
                             [col("bright", "var")[i]]])
    se = np.concatenate([[gain_se, resp_se], col("dark", "mean_se"), col("dark", "var_se"),
                         [col("bright", "var_se")[i]]])
    return values, se


def emva_measured(m: Any) -> Measured:
    """The measured vector of a data set (``Measurement``): the statistics of :data:`BLOCKS`,
    the dark means sharing the offset; x is the photons per pixel (a dark pair's: its bright
    pair's; K and R: the top of their range; the variance at saturation: the saturation's)."""
    t = m.temporal
    c = comparison(t)
    values, se = statistics(t, c)
    block = np.concatenate([np.full(k, b) for b, k in enumerate(c.sizes)])
    offset = block == BLOCKS.index("dark mean")
    mu_p = np.asarray(t.mu_p, dtype=float)
    x = np.concatenate([[mu_p[c.top - 1]] * 2, mu_p, mu_p, [mu_p[c.saturation]]])
    # a dark statistic of zero spread (a camera clipping its dark at 0) would weigh infinitely:
    # its error floor is a quarter of the smallest non-zero one of its block
    return Measured(values, _floor(se, block), block, BLOCKS, offset, x, "photons per pixel μ_p")


def _floor(se: NDArray[np.float64], block: NDArray[np.int64]) -> NDArray[np.float64]:
    out = se.copy()
    for b in np.unique(block):
        sel = block == b
        positive = se[sel][se[sel] > 0]
        floor = 0.25 * positive.min() if positive.size else 1.0
        out[sel] = np.maximum(se[sel], floor)
    return out


def replay_plan(m: Any) -> Any:
    """The data set's protocol, for the twin to be read through."""
    from chiptwin.characterize.replay import ReplayPlan

    return ReplayPlan.from_measurement(m)


def replay_stats(scenario: Any, plan: Any, rng: np.random.Generator, max_pixels: int | None,
                 compared: Compared) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The twin's statistics through the data set's protocol, as the measured vector's values
    and standard errors (the same points: ``compared``, :func:`comparison` of the measured
    series)."""
    from chiptwin.characterize.replay import replay

    # Gaussian counts: a Poisson sampler's rejection loop takes another number of uniforms when
    # its mean moves and every later draw shifts (on set 001, 4,096 pixels, moving the QE by 1e-5
    # moved the bright variances' χ² by 15; with the Gaussian count by 0.1)
    sim = replay(scenario, plan, rng, spatial=False, max_pixels=max_pixels,
                 shot_noise="gaussian").temporal
    return statistics(sim, compared)
