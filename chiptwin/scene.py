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
from dataclasses import dataclass

import numpy as np

from chiptwin import stages
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
class Scene:
    """What the chip sees: its schedule, the light per site and per pixel, and its sensor."""

    sch: Schedule
    source: stages.LightSource
    site_photons: np.ndarray
    coupling: np.ndarray
    pix_photons: np.ndarray
    sensor: stages.SensorModel


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
