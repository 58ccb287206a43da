"""An EMVA 1288 data set as a fit's target: the photon-transfer series, measured and replayed.

The twin is read through the data set's own protocol (its exposures and photon levels:
:func:`chiptwin.characterize.replay.replay`), and the two photon-transfer series are compared
statistic by statistic, each with its standard error (the pair statistics' own,
:mod:`chiptwin.characterize.estimators`):

- **bright mean and variance** at every point **below saturation** (before the bright
  variance's maximum, EMVA 1288's saturation): there the twin's model is the camera's. At and
  beyond it the statistics are set by how the camera clips (its converter's top code, blooming,
  a soft full well), which the twin models as a hard clip: those points are left out, so the
  saturation bounds ``full_well_e`` from below only (an interval open at the top says so);
- **dark mean and variance** at every point (darkness does not saturate: the long exposures
  beyond saturation measure the dark current best);
- the **means are compared after an offset**: a real camera's dark level (its black level, a
  few to tens of DN) is not in the twin's CMS frame, so one offset common to every mean (bright
  and dark) is fitted as a nuisance parameter, in closed form at each candidate
  (:func:`chiptwin.study.calibrate_data.residuals`); it costs one degree of freedom.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from chiptwin.study.calibrate_data import Measured

#: The statistics compared, in the residual vector's order.
BLOCKS = ("bright mean", "bright var", "dark mean", "dark var")
#: (series, attribute) of each block.
_COLUMNS = (("bright", "mean"), ("bright", "var"), ("dark", "mean"), ("dark", "var"))


def used_points(t: Any) -> NDArray[np.bool_]:
    """Photon-transfer points whose bright pair is compared: those before the bright variance's
    maximum (EMVA 1288's saturation), with a standard error > 0."""
    var = t.column("bright", "var")
    below = np.arange(var.size) < int(np.argmax(var))
    return below & (t.column("bright", "var_se") > 0) & (t.column("bright", "mean_se") > 0)


def _masks(t: Any) -> list[NDArray[np.bool_]]:
    bright = used_points(t)
    dark = np.ones(bright.size, dtype=bool)
    return [bright, bright, dark, dark]


def emva_measured(m: Any) -> Measured:
    """The measured vector of a data set (``Measurement``): the four blocks of :data:`BLOCKS`,
    the means sharing the offset; x is the photons per pixel."""
    t = m.temporal
    values, se, block, offset, x = [], [], [], [], []
    for b, ((series, attr), mask) in enumerate(zip(_COLUMNS, _masks(t), strict=True)):
        values.append(t.column(series, attr)[mask])
        se.append(t.column(series, f"{attr}_se")[mask])
        block.append(np.full(mask.sum(), b))
        offset.append(np.full(mask.sum(), attr == "mean"))
        x.append(np.asarray(t.mu_p, dtype=float)[mask])
    se_all = np.concatenate(se)
    # a dark statistic of zero spread (a camera clipping its dark at 0) would weigh infinitely:
    # its error floor is a quarter of the smallest non-zero one of its block
    return Measured(np.concatenate(values), _floor(se_all, np.concatenate(block)),
                    np.concatenate(block), BLOCKS, np.concatenate(offset), np.concatenate(x),
                    "photons per pixel μ_p (a dark pair: its bright pair's)")


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
                 masks: list[NDArray[np.bool_]]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The twin's photon-transfer series through the data set's protocol, as the measured
    vector's values and standard errors (the same points: ``masks``, :func:`_masks` of the
    measured series)."""
    from chiptwin.characterize.replay import replay

    # Gaussian counts: a Poisson sampler's rejection loop takes another number of uniforms when
    # its mean moves and every later draw shifts (on set 001, 4,096 pixels, moving the QE by 1e-5
    # moved the bright variances' χ² by 15; with the Gaussian count by 0.1)
    sim = replay(scenario, plan, rng, spatial=False, max_pixels=max_pixels,
                 shot_noise="gaussian").temporal
    values, se = [], []
    for (series, attr), mask in zip(_COLUMNS, masks, strict=True):
        values.append(sim.column(series, attr)[mask])
        se.append(sim.column(series, f"{attr}_se")[mask])
    return np.concatenate(values), np.concatenate(se)
