"""The three measurement series of the protocol, run on the bench: photon transfer, spatial stacks,
dark current against temperature (EMVA 1288 Release 4.0 Linear).

Each series draws from its own named stream (``stage_rng(seed, "characterize.<series>")``), so
changing one series never shifts another's numbers. The bench plans its exposures as an operator
would from a live image: the irradiance so that the longest exposure passes the nominal
saturation, the spatial exposure from the measured saturation, the dark exposures of the
temperature series from the measured dark current.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from chiptwin.characterize import evaluate as ev
from chiptwin.characterize.bench import Bench, Camera, Progress
from chiptwin.characterize.estimators import StackAccumulator, pair_stats
from chiptwin.characterize.protocol import Protocol
from chiptwin.characterize.series import SpatialSeries, TemperatureSeries, TemporalSeries
from chiptwin.config import Scenario
from chiptwin.twin.scene import stage_rng

#: Share of the nominal saturation the dark charge may take at the longest PTC exposure, and at
#: the hottest, longest exposure of the temperature series (choice: the rest is for light / range).
DARK_SHARE: float = 0.5

#: Doubling temperature assumed only to plan the temperature series (Theuwissen, Harvest Imaging:
#: 5–8 °C). Unit: °C.
PLANNING_DOUBLING_C: float = 7.0


@dataclass(frozen=True)
class Measurement:
    """Everything the bench measured, plus what it needs to say about the device."""

    camera: Camera
    protocol: Protocol
    tiles: int
    temporal: TemporalSeries
    spatial: SpatialSeries
    temperature: TemperatureSeries
    clipped_samples: int
    #: With ``keep_images``: the images themselves (``ptc``: per exposure the bright pair and the
    #: dark pair; ``spatial_bright``, ``spatial_dark``: the L images), for cross-checks.
    images: dict = field(default_factory=dict, repr=False, compare=False)


class _Counter:
    """Progress over the whole protocol from the per-series counts."""

    def __init__(self, total: int, progress: Progress | None) -> None:
        self.done, self.total, self.progress = 0, total, progress

    def __call__(self, _done: int, _n: int) -> None:
        self.done += 1
        if self.progress is not None:
            self.progress(self.done, self.total)


def measure(s: Scenario, protocol: Protocol | None = None, progress: Progress | None = None,
            keep_images: bool = False) -> Measurement:
    """Run the whole protocol on the scenario's chip.

    Parameters
    ----------
    s : Scenario
        Its chip is measured; its seed seeds the series' streams; its fixed pattern is the run's.
    protocol : Protocol, optional
        Default ``Protocol()``.
    progress : callable, optional
        ``progress(images_done, images_total)``.
    keep_images : bool
        Keep every image in :attr:`Measurement.images` (for a cross-check; memory grows).
    """
    protocol = protocol or Protocol()
    bench = Bench(s)
    tiles = protocol.tiles(bench.camera.n_pixels)
    n_temp = len(protocol.temperature_offsets_C)
    count = _Counter(4 * protocol.n_points + 2 * protocol.spatial_frames
                     + 2 * protocol.dark_exposures * n_temp, progress)
    images: dict = {} if keep_images else None  # type: ignore[assignment]
    seed = s.scenario.seed
    temporal = photon_transfer(bench, protocol, tiles, stage_rng(seed, "characterize.ptc"),
                               count, images)
    spatial = spatial_series(bench, protocol, temporal, stage_rng(seed, "characterize.spatial"),
                             count, images)
    temperature = temperature_series(bench, protocol, temporal, tiles,
                                     stage_rng(seed, "characterize.temperature"), count)
    return Measurement(bench.camera, protocol, tiles, temporal, spatial, temperature,
                       bench.clipped, images if keep_images else {})


def ptc_plan(bench: Bench, protocol: Protocol) -> tuple[NDArray[np.float64], float]:
    """Exposure times and the irradiance of the photon-transfer series.

    ``t_max`` is the chip's integration time, shortened if dark charge alone would take more than
    :data:`DARK_SHARE` of the nominal saturation; the irradiance brings the mean pixel to
    ``overdrive`` × saturation at ``t_max``. Units: s, photons/s/µm² at the sensor plane.
    """
    sat = bench.saturation_e
    dark = float(bench.sensor.dark_e_per_s.mean())
    t_max = bench.scenario.chip.timing.t_int_s
    if dark > 0:
        t_max = min(t_max, DARK_SHARE * sat / dark)
    photons_needed = protocol.overdrive * sat - dark * t_max
    irradiance = photons_needed / (bench.sensor.qe * bench.camera.diode_area_um2 * t_max)
    k = np.arange(1, protocol.n_points + 1)
    return t_max * k / protocol.n_points, float(irradiance)


def photon_transfer(bench: Bench, protocol: Protocol, tiles: int, rng: np.random.Generator,
                    count: _Counter, images: dict | None) -> TemporalSeries:
    """The photon-transfer series: per exposure time two bright, then two dark mosaic images."""
    t_exp, irradiance = ptc_plan(bench, protocol)
    sensor, area = bench.sensor, bench.camera.diode_area_um2

    def frames() -> Iterator[NDArray[np.float64]]:
        for t in t_exp:
            bright = bench.expected_e(sensor, irradiance * area * t, t, tiles)
            dark = bench.expected_e(sensor, 0.0, t, tiles)
            yield from (bright, bright, dark, dark)

    read = bench.read(rng, sensor, frames(), 4 * len(t_exp), count)
    bright, dark, resets = [], [], []
    for _point in t_exp:
        (a, _), (b, _), (c, rc), (d, rd) = (next(read) for _ in range(4))
        bright.append(pair_stats(a, b))
        dark.append(pair_stats(c, d))
        resets += [rc, rd]
        if images is not None:
            images.setdefault("ptc", []).append((a, b, c, d))
    mu_p = irradiance * bench.camera.pixel_area_um2 * t_exp
    reset_se = float(np.std(resets, ddof=1) / np.sqrt(len(resets)))
    return TemporalSeries(t_exp, mu_p, tuple(bright), tuple(dark), bright[0].n, irradiance,
                          float(np.mean(resets)), reset_se)


def spatial_series(bench: Bench, protocol: Protocol, temporal: TemporalSeries,
                   rng: np.random.Generator, count: _Counter, images: dict | None
                   ) -> SpatialSeries:
    """L bright images at 50 % of the measured saturation, then L dark images, single frames."""
    t50 = ev.half_saturation_exposure(temporal)
    sensor, cam = bench.sensor, bench.camera
    irradiance, n = temporal.irradiance_photons_per_s_per_um2, protocol.spatial_frames
    lit = bench.expected_e(sensor, irradiance * cam.diode_area_um2 * t50, t50, 1)
    dark = bench.expected_e(sensor, 0.0, t50, 1)
    frames = [lit] * n + [dark] * n
    stacks = (StackAccumulator(), StackAccumulator())
    for i, (img, _) in enumerate(bench.read(rng, sensor, iter(frames), 2 * n, count)):
        stacks[i // n].add(img.reshape(cam.rows, cam.cols))
        if images is not None:
            images.setdefault("spatial_bright" if i < n else "spatial_dark", []).append(
                img.reshape(cam.rows, cam.cols))
    (bm, bv), (dm, dv) = stacks[0].result(), stacks[1].result()
    return SpatialSeries(t50, irradiance * cam.pixel_area_um2 * t50, n, bm, bv, dm, dv)


def dark_plan(bench: Bench, protocol: Protocol, temporal: TemporalSeries) -> NDArray[np.float64]:
    """Exposure times of the temperature series: the longest takes the hottest chip's dark charge
    to :data:`DARK_SHARE` of the measured saturation (planned with the measured dark current and
    a :data:`PLANNING_DOUBLING_C` doubling), at most ``max_dark_exposure_s``; the PTC's longest
    exposure when no dark current was measured."""
    t_ptc = float(temporal.t_exp_s[-1])
    gain, _ = ev.system_gain(temporal, ev.saturation_index(temporal))
    slope_dn, _ = ev.ols(temporal.t_exp_s, temporal.column("dark", "mean"),
                         temporal.column("dark", "mean_se") ** 2)
    dark_e = slope_dn[1] / gain
    t_max = t_ptc
    if dark_e > 0:
        hottest = dark_e * 2.0 ** (max(protocol.temperature_offsets_C) / PLANNING_DOUBLING_C)
        sat = ev.saturation_dn(temporal) / gain
        t_max = float(min(DARK_SHARE * sat / hottest, protocol.max_dark_exposure_s))
    k = np.arange(1, protocol.dark_exposures + 1)
    return t_max * k / protocol.dark_exposures


def temperature_series(bench: Bench, protocol: Protocol, temporal: TemporalSeries, tiles: int,
                       rng: np.random.Generator, count: _Counter) -> TemperatureSeries:
    """Two dark mosaic images per exposure time at each temperature."""
    t_exp = dark_plan(bench, protocol, temporal)
    temps = bench.camera.temperature_C + np.array(sorted(protocol.temperature_offsets_C))
    rows = []
    for temp in temps:
        sensor = bench.sensor_at(float(temp))
        frames = (bench.expected_e(sensor, 0.0, t, tiles) for t in t_exp for _ in range(2))
        imgs = [img for img, _ in bench.read(rng, sensor, frames, 2 * len(t_exp), count)]
        rows.append(tuple(pair_stats(imgs[2 * k], imgs[2 * k + 1]) for k in range(len(t_exp))))
    return TemperatureSeries(temps, t_exp, tuple(rows))
