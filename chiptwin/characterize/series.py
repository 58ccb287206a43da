"""The three measurement series of the EMVA 1288 protocol, as data: what
:mod:`~chiptwin.characterize.measure` makes and :mod:`~chiptwin.characterize.evaluate` reads."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from chiptwin.characterize.estimators import PairStats


@dataclass(frozen=True)
class TemporalSeries:
    """The photon-transfer series: per exposure, two bright and two dark images reduced to their
    pair statistics (:func:`~chiptwin.characterize.estimators.pair_stats`).

    Attributes
    ----------
    t_exp_s : (n,)  exposure times. Unit: s.
    mu_p : (n,)  photons on the pixel area (pitch²) in each exposure. Unit: photons/pixel.
    bright, dark : tuple of PairStats, one per exposure. Units: DN, DN².
    n_values : int  values per image (the chip's pixels × the mosaic's frames).
    irradiance_photons_per_s_per_um2 : float  the source at the sensor plane.
    reset_level_dn : float  mean code of the reset samples of the dark images. Unit: DN.
    reset_level_se_dn : float  its standard error, from the spread of the images' means. Unit: DN.
    """

    t_exp_s: NDArray[np.float64]
    mu_p: NDArray[np.float64]
    bright: tuple[PairStats, ...]
    dark: tuple[PairStats, ...]
    n_values: int
    irradiance_photons_per_s_per_um2: float
    reset_level_dn: float
    reset_level_se_dn: float

    def column(self, which: str, attr: str) -> NDArray[np.float64]:
        """One statistic over the series, e.g. ``column("bright", "var")``."""
        return np.array([getattr(p, attr) for p in getattr(self, which)])


@dataclass(frozen=True)
class SpatialSeries:
    """L bright and L dark images at one exposure, averaged (the images are the chip's pixels).

    Attributes
    ----------
    t_exp_s : float  exposure time. Unit: s.
    mu_p : float  photons per pixel. Unit: photons/pixel.
    n_images : int  L.
    bright_mean, bright_var, dark_mean, dark_var : (rows, cols) averaged images (DN) and the
        pixels' temporal variances over the L images (DN², ddof 1).
    """

    t_exp_s: float
    mu_p: float
    n_images: int
    bright_mean: NDArray[np.float64]
    bright_var: NDArray[np.float64]
    dark_mean: NDArray[np.float64]
    dark_var: NDArray[np.float64]


@dataclass(frozen=True)
class TemperatureSeries:
    """Dark images at several exposure times at each temperature.

    Attributes
    ----------
    temperature_C : (m,)  chip temperatures. Unit: °C.
    t_exp_s : (j,)  exposure times, the same at every temperature. Unit: s.
    dark : tuple of tuple of PairStats, ``dark[i][k]`` at temperature i, exposure k.
    """

    temperature_C: NDArray[np.float64]
    t_exp_s: NDArray[np.float64]
    dark: tuple[tuple[PairStats, ...], ...]


__all__ = ["SpatialSeries", "TemperatureSeries", "TemporalSeries"]
