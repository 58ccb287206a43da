"""The measured side of a fit as one vector, and a candidate's residuals against it.

A candidate's simulation gives a value and its own standard error for every measured value
(common random numbers: the same streams for every candidate, so the simulated values carry a
noise that is the same at every candidate, not a new draw each time). Its residual is

    r_i = (sim_i + δ·offset_i − meas_i) / (s_b · √(se_meas,i² + se_sim,i²))

- the simulated statistic's own standard error is in the variance: a fit to a twin read through
  few pixels or few runs is told how noisy its side is, and the intervals include it;
- ``δ`` is a nuisance offset shared by the elements marked ``offset`` (an EMVA 1288 data set's
  means: a real camera's black level, which the twin's CMS frame does not have), profiled in
  closed form: the weighted mean of ``meas − sim`` over those elements at each candidate;
- ``s_b`` scales the errors of block ``b`` (one statistic: ``bright var``, ``snr_power``): 1
  until the fit has found its optimum, then the block's Birge ratio (:func:`block_scales`).
- ``wls`` (no standard errors): ``se_meas = 1`` and ``se_sim = 0``; the scale is then always
  estimated from the residuals.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class Measured:
    """The measured values of a fit, one vector, and how to read it.

    Attributes
    ----------
    values : (n,) the measured values
    se : (n,) their standard errors; ones for ``wls``
    block : (n,) index into ``block_names`` (one statistic each; units differ between blocks)
    block_names : the statistics, e.g. ("bright mean", "bright var", "dark mean", "dark var")
    offset : (n,) bool, the elements that share the nuisance offset (none: all False)
    x : (n,) each element's abscissa for plots (x value, time, photons per pixel)
    x_label : its name and unit
    weighted : the standard errors are measured (χ²), not ones (least squares)
    """

    values: NDArray[np.float64]
    se: NDArray[np.float64]
    block: NDArray[np.int64]
    block_names: tuple[str, ...]
    offset: NDArray[np.bool_]
    x: NDArray[np.float64]
    x_label: str
    weighted: bool = True

    @property
    def n(self) -> int:
        return int(self.values.size)

    @property
    def nuisance(self) -> int:
        """Nuisance parameters fitted beside the keys (the offset, if any element takes it)."""
        return int(self.offset.any())


def residuals(m: Measured, sim: NDArray[np.float64], sim_se: NDArray[np.float64],
              scales: NDArray[np.float64] | None = None) -> tuple[NDArray[np.float64], float]:
    """The residual vector of one candidate and its profiled offset (module docstring).

    ``scales``: one factor per block (default ones)."""
    s = np.ones(len(m.block_names)) if scales is None else np.asarray(scales)
    var = m.se**2 + (sim_se**2 if m.weighted else 0.0)
    sigma = np.sqrt(var) * s[m.block]
    delta = 0.0
    if m.offset.any():
        w = 1.0 / sigma[m.offset] ** 2
        delta = float(np.sum(w * (m.values[m.offset] - sim[m.offset])) / np.sum(w))
    return (sim + delta * m.offset - m.values) / sigma, delta


def block_chi2(m: Measured, r: NDArray[np.float64]) -> NDArray[np.float64]:
    """Σ r² within each block."""
    return np.bincount(m.block, weights=r**2, minlength=len(m.block_names))


def block_scales(m: Measured, r: NDArray[np.float64], n_params: int) -> NDArray[np.float64]:
    """Each block's Birge ratio ``√(χ²_b/ν_b)`` at the optimum (``r`` unscaled), its share of
    the degrees of freedom ``ν_b = n_b·(n − p)/n``.

    χ² (measured standard errors): ``max(1, ratio)``: a block that scatters more than its
    standard errors say (a camera's frame-to-frame offset drift, its nonlinearity, which the
    twin does not model) has its errors scaled up until it does not (the Particle Data Group's
    scale factor); one that scatters less keeps its stated errors. Least squares: the ratio
    itself, the errors' scale estimated from the residuals."""
    n_b = np.bincount(m.block, minlength=len(m.block_names)).astype(float)
    dof = max(m.n - n_params, 1)
    nu = np.maximum(n_b * dof / m.n, 1e-12)
    ratio = np.sqrt(block_chi2(m, r) / nu)
    ratio = np.where(n_b > 0, ratio, 1.0)
    if m.weighted:
        return np.maximum(ratio, 1.0)
    return np.where(ratio > 0, ratio, 1.0)
