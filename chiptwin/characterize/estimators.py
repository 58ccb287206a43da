"""The test bench's estimators: temporal statistics of a frame pair, spatial statistics of a stack.

These are the sample statistics of EMVA 1288 Release 4.0 Linear, written once and
used by the characterisation and by the pixel tests (``tests/pixel/test_pixel_noise_model.py``):

* **Pair** (photon transfer): from two images ``A``, ``B`` of one exposure, the mean
  ``μ_y = (⟨A⟩ + ⟨B⟩)/2`` and the temporal variance ``σ²_y = ⟨((A − ⟨A⟩) − (B − ⟨B⟩))²⟩ / 2``,
  which removes the fixed pattern (the same in both images) and a drift of the mean between them.
* **Stack** (DSNU/PRNU): from ``L`` images of one exposure, the averaged image ``⟨y⟩``, its
  spatial variance ``s²_y.measured`` (ddof 1) and the mean temporal variance ``σ²_y.stack`` of
  the pixels (ddof 1 over the L images); the fixed-pattern variance is
  ``s²_y = s²_y.measured − σ²_y.stack / L`` (the averaged image still carries 1/L of the
  temporal noise).

Standard errors come from the number of values, not from repetition: a sample variance of ``n``
values with fourth central moment ``m4`` has standard error ``√((m4 − σ⁴)/n)``
(:func:`var_se`), which for Gaussian noise is ``σ²·√(2/n)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray


def var_se(x: ArrayLike) -> float:
    """Standard error of the sample variance of ``x`` from its own fourth moment. Unit: x².

    ``√((m4 − m2²)/n)`` with ``m2``, ``m4`` the second and fourth central sample moments.
    """
    a = np.asarray(x, dtype=np.float64).ravel()
    d = a - a.mean()
    m2, m4 = (d**2).mean(), (d**4).mean()
    return float(np.sqrt(max(m4 - m2 * m2, 0.0) / a.size))


@dataclass(frozen=True)
class PairStats:
    """Temporal statistics of one exposure from a pair of images.

    Attributes
    ----------
    mean : float
        ``μ_y``, the mean of both images. Unit: DN.
    var : float
        ``σ²_y``, the temporal variance. Unit: DN².
    mean_se : float
        Standard error of ``mean`` from the temporal noise alone (the fixed pattern is the same
        at every exposure of one chip): ``√(σ²_y / 2n)``. Unit: DN.
    var_se : float
        Standard error of ``var`` from the data's fourth moment (:func:`var_se`). Unit: DN².
    n : int
        Values per image.
    """

    mean: float
    var: float
    mean_se: float
    var_se: float
    n: int


def pair_stats(a: ArrayLike, b: ArrayLike) -> PairStats:
    """Mean and temporal variance of one exposure from two images of it (EMVA 1288 R4).

    Parameters
    ----------
    a, b : array_like, same shape
        The two images. Unit: DN.

    Returns
    -------
    PairStats
        ``σ²_y = var(A − B)/2`` (population variance of the difference, i.e. the standard's
        ``1/(2NM) Σ((y_A − μ_A) − (y_B − μ_B))²``) and its standard error.
    """
    a64, b64 = np.asarray(a, np.float64).ravel(), np.asarray(b, np.float64).ravel()
    if a64.shape != b64.shape or a64.size < 2:
        raise ValueError(f"pair_stats: images of {a64.size} and {b64.size} values; need equal ≥ 2")
    diff = a64 - b64
    var = float(diff.var() / 2.0)
    n = a64.size
    return PairStats(
        mean=float((a64.mean() + b64.mean()) / 2.0),
        var=var,
        mean_se=float(np.sqrt(max(var, 0.0) / (2.0 * n))),
        var_se=var_se(diff) / 2.0,
        n=n,
    )


class StackAccumulator:
    """Running per-pixel sums of a stack of L images, for the spatial (DSNU/PRNU) statistics.

    Memory is two images however large L is. Values are shifted by the first image before they
    are summed, so the per-pixel variance does not cancel catastrophically against the mean.
    """

    def __init__(self) -> None:
        self.count = 0
        self._shift: NDArray[np.float64] | None = None
        self._sum: NDArray[np.float64] | None = None
        self._sum_sq: NDArray[np.float64] | None = None

    def add(self, image: ArrayLike) -> None:
        """Add one image (any shape; every image the same)."""
        img = np.asarray(image, dtype=np.float64)
        if self._shift is None:
            self._shift = img.copy()
            self._sum = np.zeros_like(img)
            self._sum_sq = np.zeros_like(img)
        elif img.shape != self._shift.shape:
            raise ValueError(f"image of shape {img.shape}: the stack's is {self._shift.shape}")
        d = img - self._shift
        self._sum += d
        self._sum_sq += d * d
        self.count += 1

    def result(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The averaged image ``⟨y⟩`` and the per-pixel temporal variance (ddof 1).

        Unit: DN, DN².
        """
        if self.count < 2 or self._sum is None:
            raise ValueError(f"a stack needs ≥ 2 images; it has {self.count}")
        n = self.count
        mean_d = self._sum / n
        var = (self._sum_sq - n * mean_d * mean_d) / (n - 1)
        return self._shift + mean_d, np.maximum(var, 0.0)


@dataclass(frozen=True)
class SpatialStats:
    """Spatial statistics of an averaged stack of L images (EMVA 1288 R4, nonuniformity).

    Attributes
    ----------
    mean : float
        ``μ_y``, mean of the averaged image. Unit: DN.
    s2_measured : float
        ``s²_y.measured``, spatial variance of the averaged image (ddof 1). Unit: DN².
    var_stack : float
        ``σ²_y.stack``, the pixels' mean temporal variance over the L images. Unit: DN².
    s2 : float
        ``s²_y = s²_y.measured − σ²_y.stack / L``: the fixed-pattern variance. Unit: DN².
    s2_se : float
        Its standard error from the temporal noise alone, i.e. as a measurement of this chip's
        own pattern: ``(4 s² τ + 2 τ²)/n + 2τ²/(n(L − 1))`` under the root, ``τ = σ²_y.stack/L``
        (the noise left in the averaged image). Unit: DN².
    n, L : int
        Pixels and images.
    """

    mean: float
    s2_measured: float
    var_stack: float
    s2: float
    s2_se: float
    n: int
    L: int


def spatial_stats(mean_image: ArrayLike, var_image: ArrayLike, n_images: int) -> SpatialStats:
    """Fixed-pattern variance of an averaged stack, the temporal part removed.

    Parameters
    ----------
    mean_image : array_like
        The average of the L images. Unit: DN.
    var_image : array_like
        Each pixel's temporal variance over the L images (ddof 1). Unit: DN².
    n_images : int
        L ≥ 2.
    """
    avg = np.asarray(mean_image, np.float64).ravel()
    if n_images < 2 or avg.size < 2:
        raise ValueError(f"spatial_stats: {avg.size} pixels × {n_images} images; need ≥ 2 each")
    s2_measured = float(avg.var(ddof=1))
    var_stack = float(np.mean(var_image))
    tau = var_stack / n_images
    s2 = s2_measured - tau
    n = avg.size
    se2 = (4.0 * max(s2, 0.0) * tau + 2.0 * tau * tau) / n + 2.0 * tau * tau / (n * (n_images - 1))
    return SpatialStats(float(avg.mean()), s2_measured, var_stack, s2, float(np.sqrt(se2)), n,
                        n_images)
