"""The measurement protocol of EMVA 1288 Release 4.0 Linear, as the bench runs it.

Three series, all under uniform illumination at the sensor plane (the ``flux`` assay kind's light)
or in the dark, with the exposure *time* varied at constant irradiance:

* **photon transfer**: ``n_points`` equally spaced exposure times ``t_k = t_max·k/n`` (the
  standard asks for ≥ 50 equally spaced radiant exposures from dark to saturation); ``t_max``
  drives the pixels to ``overdrive`` × their nominal saturation, so the series ends beyond it. At
  each point two bright and two dark images.
* **spatial**: ``spatial_frames`` (L ≥ 16) bright images at 50 % of the measured saturation and
  L dark images at the same exposure time: DSNU and PRNU.
* **temperature**: dark images at ``dark_exposures`` exposure times at each of the operating
  temperature plus ``temperature_offsets_C``: the dark current's doubling temperature.

A chip with fewer than ``min_values`` pixels is measured with mosaic images: each temporal image
is ``⌈min_values / n_pixels⌉`` frames of the chip taken at the same point and laid side by side,
so the standard's pair statistics run over ≥ ``min_values`` values (the 8 × 16 reference chip:
128 frames per image, 16,384 values). Its spatial images stay single frames: the fixed pattern of
a chip is that of its own pixels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: Fewest photon-transfer points the standard accepts.
MIN_POINTS: int = 50

#: Fewest images of a spatial stack (the standard's L).
MIN_SPATIAL_FRAMES: int = 16


def _need(name: str, value: float, ok: bool, allowed: str) -> None:
    if not ok:
        raise ValueError(f"Protocol.{name} = {value!r}: {allowed}")


@dataclass(frozen=True)
class Protocol:
    """What the bench measures. Every default is the standard's minimum or a stated choice.

    Attributes
    ----------
    n_points : int
        Photon-transfer points, ≥ 50 (standard). Default 60 (choice: 2 % of saturation apart).
    overdrive : float
        Longest exposure / nominal saturation, > 1 so the series passes saturation. Default 1.25.
    spatial_frames : int
        L, images per spatial stack, ≥ 16. Default 16.
    min_values : int
        Fewest values per temporal image (mosaic of frames below it). Default 16,384 (choice:
        the relative standard error of one pair's variance is then √(2/n) ≈ 1.1 %).
    temperature_offsets_C : tuple of float
        Temperatures of the dark-current series relative to the operating one. Unit: °C.
        Default −10 … +15 in 5 °C steps (six temperatures, choice).
    dark_exposures : int
        Exposure times per temperature, ≥ 2. Default 6.
    max_dark_exposure_s : float
        Longest dark exposure of the temperature series. Unit: s. Default 3600.
    """

    n_points: int = 60
    overdrive: float = 1.25
    spatial_frames: int = 16
    min_values: int = 16384
    temperature_offsets_C: tuple[float, ...] = (-10.0, -5.0, 0.0, 5.0, 10.0, 15.0)
    dark_exposures: int = 6
    max_dark_exposure_s: float = 3600.0

    def __post_init__(self) -> None:
        _need("n_points", self.n_points, self.n_points >= MIN_POINTS,
              f"must be ≥ {MIN_POINTS} (EMVA 1288: ≥ 50 exposure points)")
        _need("overdrive", self.overdrive, 1.0 < self.overdrive <= 4.0,
              "must be in (1, 4]: the series must pass saturation")
        _need("spatial_frames", self.spatial_frames, self.spatial_frames >= MIN_SPATIAL_FRAMES,
              f"must be ≥ {MIN_SPATIAL_FRAMES}")
        _need("min_values", self.min_values, self.min_values >= 2, "must be ≥ 2")
        offsets = self.temperature_offsets_C
        _need("temperature_offsets_C", offsets,
              len(set(offsets)) >= 2 and all(math.isfinite(t) for t in offsets),
              "must hold ≥ 2 distinct finite temperatures")
        _need("dark_exposures", self.dark_exposures, self.dark_exposures >= 2, "must be ≥ 2")
        _need("max_dark_exposure_s", self.max_dark_exposure_s, self.max_dark_exposure_s > 0,
              "must be > 0")

    def tiles(self, n_pixels: int) -> int:
        """Frames per temporal image for a chip of ``n_pixels``: ``⌈min_values / n_pixels⌉``."""
        return max(1, -(-self.min_values // n_pixels))
