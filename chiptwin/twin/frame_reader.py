"""How a run's chip model gets its frames: a block of frames drawn ahead in frame order as the
chip model reaches them (``FrameReader``), and, with ``[run] save_frames``, every frame streamed
to a ``.npy`` file (``_FrameFile``) that the run's outputs copy into ``run.nc``.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np

from chiptwin import pixel
from chiptwin.config import Scenario
from chiptwin.config.outputs import new_file_mode
from chiptwin.dsp._kernels import count_ends_kernel
from chiptwin.dsp.pipeline import Frame, FrameStack
from chiptwin.twin import stages
from chiptwin.twin.scene import PixelFrames, Scene, StageTimer, stage_rng


def frames_file() -> Path:
    """A fresh ``.npy`` path in the temporary folder (``TMPDIR``) for the frames of one run."""
    fd, name = tempfile.mkstemp(prefix="chiptwin-frames-", suffix=".npy")
    os.fchmod(fd, new_file_mode())  # copied into the output's run.nc; the umask's mode
    os.close(fd)
    return Path(name)


class FrameReader:
    """``read_frame(k)`` of the chip model: frame ``k`` as the ADCs deliver it.

    The chip model reads frames in order, each once. When frame ``k`` is first asked for, the
    block of frames ``k … k + B − 1`` (``B`` = :attr:`Scene.block_frames`) is made: its moments
    (:meth:`Scene.pixel_block`) and, at the ``binned`` and ``events`` levels, its codes in one
    call of :func:`chiptwin.pixel.binned_codes`, drawing what reading the frames one by one
    would. At the ``events`` level :class:`~chiptwin.twin.stages.EventPixels` (its own stream)
    times the filling of the site pixels' wells from the counts drawn there (the codes are
    ``binned``'s, bit for bit).
    Only the current block is held (and what the frame memory still holds of earlier ones).
    """

    def __init__(self, s: Scenario, scene: Scene, photons_level: str, rng: np.random.Generator,
                 timer: StageTimer, frames_path: Path | None = None,
                 moments_at: np.ndarray | None = None) -> None:
        self.s, self.scene, self.timer, self.moments_at = s, scene, timer, moments_at
        self.sampled = photons_level in ("binned", "events")
        self.streams = pixel.chunk_streams(rng, scene.n_pixels) if self.sampled else []
        # The kTC, read-noise and comparator normals on streams of their own, so two runs of a
        # seed that differ only in what the counts draw (photon, shot, kinetics or optics level)
        # read the same noise: their difference is the counts' alone (common random numbers).
        self.normal_streams = pixel.chunk_streams(
            stages.child_rng(rng, "read_noise"), scene.n_pixels) if self.sampled else []
        self.events = None
        if photons_level == "events":
            self.events = stages.EventPixels(
                scene.source, scene.coupling, stages.site_pixel_indices(s), scene.sensor,
                stage_rng(s.scenario.seed, "events"))
        self.first, self.stop = 0, 0  # the block made last: frames first … stop − 1
        self.moments: PixelFrames | None = None
        self.codes: np.ndarray | None = None
        self.clipped = 0  # ADC samples at code 0 or full scale
        self.full_well = 0  # pixel-frames whose expected charge reaches the full well
        self.saved = _FrameFile(frames_path, s, scene, self.sampled) if frames_path else None

    def __call__(self, k: int) -> Frame:
        if not self.first <= k < self.stop:
            self._make(k)
        i = k - self.first
        codes = self.codes[i] if self.codes is not None else None
        return Frame(codes=codes, mean=self.moments.cds_mean_lsb[i],
                     var=self.moments.cds_var_lsb2[i])

    def stack(self, k: int) -> FrameStack:
        """The next block of frames, ``k`` its first, stacked (for a run known ahead)."""
        self._make(k)
        return FrameStack(self.codes, self.moments.cds_mean_lsb, self.moments.cds_var_lsb2)

    def _make(self, k: int) -> None:
        """Make the block of frames starting at ``k`` (the next one)."""
        if k != self.stop:
            raise RuntimeError(f"frame {k} read out of order: the next one is {self.stop}")
        stop = min(k + self.scene.block_frames, self.scene.sch.n_frames)
        with self.timer("pixel"):
            self.moments = self.scene.pixel_block(self.s.chip.timing.t_int_s,
                                                  self.s.chip.adc.gain_error, k, stop,
                                                  self.moments_at)
            self.full_well += self.moments.full_well_pixel_frames
            if self.sampled:
                self.codes = self._draw(k, stop)
        if self.sampled:
            with self.timer("adc"):
                top = 2**self.s.chip.adc.bits - 1
                self.clipped += _clipped(self.codes, top)
        self.first, self.stop = k, stop
        if self.saved is not None:
            self.saved.write(k, self.codes if self.sampled else self.moments.cds_mean_lsb)

    def _draw(self, k: int, stop: int) -> np.ndarray:
        sensor = self.scene.sensor
        pixels, drawn = (), None
        if self.events is not None:
            pixels = self.events.pixels
            drawn = np.empty((stop - k, len(pixels)))
        codes = pixel.binned_codes(
            self.streams, self.moments.mean_e, full_well_e=sensor.full_well_e,
            ktc_e=sensor.ktc_e, read_noise_e=sensor.read_noise_e,
            n_samples=sensor.cms_samples, true_cds=sensor.true_cds,
            conversion_gain_uV_per_e=sensor.conversion_gain_uV_per_e,
            pedestal_V=sensor.pedestal_V, converter=sensor.converter,
            report_pixels=pixels, report_e=drawn, shot_noise=self.s.run.fidelity.shot,
            normal_rng=self.normal_streams)
        if self.events is not None:
            for j in range(k, stop):
                self.events.fill(*self.scene.sch.window_s(j), drawn[j - k])
        return codes

    def close(self) -> None:
        if self.saved is not None:
            self.saved.close()


def _clipped(codes: np.ndarray, top: int) -> int:
    """ADC samples at code 0 or at full scale ``top``."""
    if codes.dtype in (np.int64, np.uint16, np.uint32) and codes.flags.c_contiguous:
        return int(count_ends_kernel(codes.reshape(-1), 0, top))  # one pass, no temporaries
    return int(np.count_nonzero((codes == 0) | (codes == top)))


class _FrameFile:
    """Every frame as read, streamed to a ``.npy`` file block by block (``[run] save_frames``).

    ``(n_frames, 2M, rows · cols)`` ADC codes (unsigned, the narrowest type that holds the
    ADC's bits) at the ``binned`` and ``events`` levels; ``(n_frames, rows · cols)`` expected
    CMS differences (LSB, float64) at the ``expected`` level. Frames the memory dropped are
    written too: the file is what the ADCs delivered, the DSP read all the others.
    """

    def __init__(self, path: Path, s: Scenario, scene: Scene, sampled: bool) -> None:
        n, p = scene.sch.n_frames, scene.n_pixels
        if sampled:
            dtype = pixel.code_dtype(s.chip.adc.bits)
            shape: tuple[int, ...] = (n, 2 * scene.sensor.cms_samples, p)
        else:
            dtype, shape = np.float64, (n, p)
        self.array = np.lib.format.open_memmap(path, mode="w+", dtype=dtype, shape=shape)

    def write(self, k: int, block: np.ndarray) -> None:
        self.array[k:k + len(block)] = block
        self.array.flush()

    def close(self) -> None:
        self.array.flush()
        del self.array
