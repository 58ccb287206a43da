"""The types a run's stages share: the prepared scene, the chip model's output, stage timing and the
random stream of each stage.

They live below both :mod:`chiptwin.run` (which makes them) and :mod:`chiptwin.results` (which reads
them), and :mod:`chiptwin.study` reuses a prepared :class:`Scene` across the replicates of a point.
"""

from __future__ import annotations

import time
import zlib
from collections import defaultdict
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np

from chiptwin import pixel, stages
from chiptwin.chip import ChipRun, Schedule
from chiptwin.dsp.pipeline import Pipeline


def stage_rng(seed: int, stage: str) -> np.random.Generator:
    """The random stream of one stage: ``SeedSequence(seed)``'s child keyed by the stage's name."""
    key = zlib.crc32(stage.encode())
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(key,)))


class StageTimer:
    """Wall time per stage, accumulated over the run."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = defaultdict(float)

    @contextmanager
    def __call__(self, stage: str):
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.seconds[stage] += time.perf_counter() - t0


@dataclass(frozen=True)
class PixelFrames:
    """What the pixels of a scene expect in every frame: the part of the pixel stage that no random
    draw enters, for all frames at once (:func:`pixel_frames`).

    Attributes
    ----------
    mean_e : array (n_frames, n_pixels)
        Expected charge before the full-well clip (:func:`chiptwin.pixel.mean_electrons`), the
        mean of the ``binned`` level's Poisson draw. Unit: e⁻.
    cds_mean_lsb, cds_var_lsb2 : array (n_frames, n_pixels)
        Each frame's expected CMS difference at the ADC's gain, and its variance with the
        rounding of the two M-sample means (the ``mean`` and ``var`` of the DSP's
        :class:`~chiptwin.dsp.pipeline.Frame`). Unit: LSB, LSB².
    full_well_pixel_frames : int
        Pixel-frames whose expected charge reaches the full well.
    """

    mean_e: np.ndarray
    cds_mean_lsb: np.ndarray
    cds_var_lsb2: np.ndarray
    full_well_pixel_frames: int


@dataclass(frozen=True)
class Scene:
    """What the chip sees: its schedule, the light per site and per pixel, and its sensor.

    A scene is not changed after :func:`chiptwin.run.prepare` made it (derive another with
    ``dataclasses.replace``): what is computed from it once (:meth:`pixel_frames`) is kept with
    it and reused by every replicate that runs on it.
    """

    sch: Schedule
    source: stages.LightSource
    site_photons: np.ndarray
    coupling: np.ndarray
    pix_photons: np.ndarray
    sensor: stages.SensorModel
    _memo: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def pixel_frames(self, t_int_s: float, gain_error: float) -> PixelFrames:
        """:func:`pixel_frames` of this scene, computed at the first call and kept."""
        key = ("pixel_frames", t_int_s, gain_error)
        if key not in self._memo:
            self._memo[key] = pixel_frames(self, t_int_s, gain_error)
        return self._memo[key]


def pixel_frames(scene: Scene, t_int_s: float, gain_error: float) -> PixelFrames:
    """Expected charge and CMS moments of every pixel in every frame of ``scene``.

    Parameters
    ----------
    scene : Scene
        Photons per pixel per frame and the sensor.
    t_int_s : float
        Integration time (the dark charge is dark current × ``t_int_s``). Unit: s.
    gain_error : float
        The ADC's fractional gain error (``chip.adc.gain_error``): codes per electron are
        ``(1 + gain_error) / e_per_lsb``.

    Notes
    -----
    Element by element the same arithmetic as :func:`chiptwin.pixel.mean_electrons` and
    :func:`chiptwin.pixel.expected_frame` called on one frame at a time, so the numbers are those.
    """
    sensor = scene.sensor
    photons = np.ascontiguousarray(scene.pix_photons.T)
    dark_e = sensor.dark_e_per_s * t_int_s
    mean_e = pixel.mean_electrons(photons, sensor.qe, sensor.gain_map, dark_e)
    cds_e, cds_var_e2 = pixel.expected_frame(
        photons, sensor.qe, sensor.gain_map, dark_e, sensor.full_well_e, sensor.ktc_e,
        sensor.read_noise_e, sensor.cms_samples, sensor.true_cds)
    to_lsb = (1.0 + gain_error) / sensor.e_per_lsb
    read_lsb = sensor.read_noise_e / sensor.e_per_lsb * (1.0 + gain_error)
    quant_var = 2.0 * pixel.quantization_var_of_mean(sensor.cms_samples, read_lsb)
    arrays = (mean_e, cds_e * to_lsb, cds_var_e2 * to_lsb**2 + quant_var)
    for arr in arrays:
        arr.flags.writeable = False  # shared by every replicate of the scene
    full = int(np.count_nonzero(mean_e >= sensor.full_well_e))
    return PixelFrames(*arrays, full_well_pixel_frames=full)


@dataclass
class ChainOutput:
    """The chip model's outputs at the pixels, in electrons.

    Electrons are read back from codes at the ADC's nominal gain, as the chip itself would: an
    ADC gain error (``chip.adc.gain_error``) shows up as a scale error of every figure.
    """

    chip: ChipRun
    block_t_s: np.ndarray
    value_e: np.ndarray
    mean_e: np.ndarray
    var_e2: np.ndarray
    dark_var_e2: np.ndarray
    dsp: Pipeline
    saturation_s: np.ndarray | None = None  # events level: (n_frames, n_sites), inf = not full
    adc_clipped_samples: int = 0
    full_well_pixel_frames: int = 0
