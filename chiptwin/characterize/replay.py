"""The twin through a measured protocol: a scenario's chip read at the exposures and photon levels
of an EMVA 1288 data set, into the same :class:`~chiptwin.characterize.measure.Measurement` the
data set gives, so the two go through the same estimators and can be laid over each other.

The bench (:class:`~chiptwin.characterize.bench.Bench`) reads the chip as configured: per point
two bright and two dark images of the data set's exposure time and photons per pixel (EMVA's
μ_p falls on the pixel's area, pitch²; the photodiode gets μ_p × the fill factor), and, if the
data set has them, the spatial stacks. A camera's output holds its black level, where the twin's
CMS frame holds none: the twin's frames are reported as a camera reports them, the CMS frame
plus the mean reset code of its dark images (the chip's pedestal through its converter), so
dark means compare with the camera's directly.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from chiptwin.characterize.bench import Bench
from chiptwin.characterize.estimators import StackAccumulator, pair_stats
from chiptwin.characterize.measure import Measurement
from chiptwin.characterize.series import SpatialSeries, TemporalSeries
from chiptwin.config import Scenario


@dataclass(frozen=True)
class ReplayPlan:
    """A data set's protocol.

    Attributes
    ----------
    t_exp_s : (n,)  exposure times of the photon-transfer points. Unit: s.
    mu_p : (n,)  photons per pixel area at each point. Unit: photons/pixel.
    spatial : (exposure s, photons/pixel, L) of the spatial stacks, or None.
    """

    t_exp_s: NDArray[np.float64]
    mu_p: NDArray[np.float64]
    spatial: tuple[float, float, int] | None = None

    @classmethod
    def from_measurement(cls, m: Measurement) -> ReplayPlan:
        """The protocol a measurement was taken with."""
        sp = m.spatial
        return cls(np.asarray(m.temporal.t_exp_s, np.float64),
                   np.asarray(m.temporal.mu_p, np.float64),
                   None if sp is None else (float(sp.t_exp_s), float(sp.mu_p), sp.n_images))


def replay(s: Scenario, plan: ReplayPlan, rng: np.random.Generator, spatial: bool = True,
           max_pixels: int | None = None, shot_noise: str = "poisson") -> Measurement:
    """Read the scenario's chip through a data set's protocol.

    Parameters
    ----------
    s : Scenario
        Its ``[chip]`` is read (pixel, converter as built, CMS at the DSP's level).
    plan : ReplayPlan
    rng : numpy.random.Generator
        One stream for the whole protocol: the same generator state gives the same images, so
        candidates of a fit share their random numbers.
    spatial : bool
        Read the spatial stacks too (when the plan has them).
    max_pixels : int, optional
        Read only the chip's first ``max_pixels`` pixels in every temporal image (a fit's cheaper
        reading: the pair statistics' errors grow as 1/√n and are reported with them).
    shot_noise : {"poisson", "gaussian"}
        ``"gaussian"`` draws every count as ``rint(λ + √λ·z)``: the images move continuously with
        the scenario's values, as a fit's common random numbers need (a Poisson sampler takes
        another number of uniforms when its mean moves, and every later draw shifts).
    """
    bench = Bench(s)
    n = bench.camera.n_pixels if max_pixels is None else min(max_pixels, bench.camera.n_pixels)
    temporal, reset = _temporal(bench, plan, rng, n, shot_noise)
    sp = (_spatial(bench, plan, rng, reset, shot_noise)
          if spatial and plan.spatial is not None else None)
    return Measurement(camera=bench.camera, protocol=None, tiles=1, temporal=temporal,
                       spatial=sp, temperature=None, clipped_samples=bench.clipped)


def _photons_per_diode(bench: Bench, mu_p: float) -> float:
    """EMVA's photons per pixel area → photons on the photodiode."""
    return mu_p * bench.camera.fill_factor


def _temporal(bench: Bench, plan: ReplayPlan, rng: np.random.Generator, n: int,
              shot_noise: str) -> tuple[TemporalSeries, float]:
    sensor = bench.sensor

    def frames() -> Iterator[NDArray[np.float64]]:
        for t, mu_p in zip(plan.t_exp_s, plan.mu_p, strict=True):
            bright = bench.expected_e(sensor, _photons_per_diode(bench, mu_p), t, 1)[:n]
            dark = bench.expected_e(sensor, 0.0, t, 1)[:n]
            yield from (bright, bright, dark, dark)

    images = bench.read(rng, sensor, frames(), 4 * len(plan.t_exp_s), shot_noise=shot_noise)
    points = [[next(images) for _ in range(4)] for _ in plan.t_exp_s]
    resets = [r for point in points for _, r in point[2:]]
    reset = float(np.mean(resets))
    bright = tuple(pair_stats(a + reset, b + reset) for (a, _), (b, _), _, _ in points)
    dark = tuple(pair_stats(c + reset, d + reset) for _, _, (c, _), (d, _) in points)
    irradiance = float(np.median(plan.mu_p / plan.t_exp_s) / bench.camera.pixel_area_um2)
    return TemporalSeries(plan.t_exp_s, plan.mu_p, bright, dark, n, irradiance, reset,
                          float(np.std(resets, ddof=1) / np.sqrt(len(resets)))), reset


def _spatial(bench: Bench, plan: ReplayPlan, rng: np.random.Generator, reset: float,
             shot_noise: str) -> SpatialSeries:
    t, mu_p, n = plan.spatial
    sensor, cam = bench.sensor, bench.camera
    lit = bench.expected_e(sensor, _photons_per_diode(bench, mu_p), t, 1)
    dark = bench.expected_e(sensor, 0.0, t, 1)
    stacks = (StackAccumulator(), StackAccumulator())
    frames = iter([lit] * n + [dark] * n)
    for i, (img, _) in enumerate(bench.read(rng, sensor, frames, 2 * n, shot_noise=shot_noise)):
        stacks[i // n].add(img.reshape(cam.rows, cam.cols) + reset)
    (bm, bv), (dm, dv) = stacks[0].result(), stacks[1].result()
    return SpatialSeries(t, mu_p, n, bm, bv, dm, dv)


__all__ = ["ReplayPlan", "replay"]
