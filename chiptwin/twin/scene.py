"""The types a run's stages share: the prepared scene, the chip model's output, stage timing and the
random stream of each stage.

They live below both :mod:`chiptwin.twin.runner` (which makes them) and
:mod:`chiptwin.twin.results` (which reads them), and :mod:`chiptwin.study` reuses a prepared
:class:`Scene` across the replicates of a point.
"""

from __future__ import annotations

import time
from collections import defaultdict
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import sparse

from chiptwin import pixel
from chiptwin.chip import ChipRun, Schedule
from chiptwin.config.budget import moments_kept
from chiptwin.config.tiling import TilePlan
from chiptwin.dsp.pipeline import Pipeline
from chiptwin.limits import frames_per_block
from chiptwin.twin import stages

stage_rng = stages.stage_rng
"""The random stream of one stage (:func:`chiptwin.twin.stages.stage_rng`)."""


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


#: Bytes of light per pixel made in one product with the coupling (a large scene's frames in
#: chunks of whole blocks, kept until the chip model reads past them). A sparse coupling is read
#: from memory once per product: 34.6 million couplings (``pyro_array_256``'s flow cell) cost
#: 44 ms a frame two frames at a time and 11 ms a frame 16 or more at a time (SciPy's
#: ``csr_matvecs``, one core); the sums are the same bit for bit, the products being taken per
#: frame in the same order. Unit: bytes.
PHOTON_CHUNK_BYTES: int = 32 << 20


@dataclass(frozen=True)
class Scene:
    """What the chip sees: its schedule, the light per site, its coupling to the pixels, its sensor.

    The light per pixel is ``coupling @ site_photons``; it is made a block of frames at a time
    (:meth:`pixel_block`), never held for the whole run unless the scene is small. A scene is not
    changed after :func:`chiptwin.twin.runner.prepare` made it (derive another with
    ``dataclasses.replace``): what is computed from it once is kept with it and reused by every
    replicate that runs on it.
    """

    sch: Schedule
    source: stages.LightSource
    site_photons: np.ndarray
    coupling: np.ndarray
    sensor: stages.SensorModel
    #: ``[run] tile``: the simulated sites of a tiled run (:mod:`chiptwin.twin.tile`; the
    #: scene's pixels are theirs, its schedule the array's), None when the array runs whole.
    tile: TilePlan | None = None
    #: ``summary['tiled']`` (None when ``[run] tile = "off"``).
    tile_section: dict | None = None
    _memo: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    @property
    def n_pixels(self) -> int:
        return int(self.coupling.shape[0])

    @property
    def block_frames(self) -> int:
        """Frames per block (:func:`chiptwin.limits.frames_per_block`)."""
        return frames_per_block(self.n_pixels, self.sensor.cms_samples)

    def photons_block(self, start: int, stop: int) -> np.ndarray:
        """Photons per pixel in frames ``start … stop − 1``: ``(stop − start, n_pixels)``.

        A sparse coupling's products are made a chunk of :data:`PHOTON_CHUNK_BYTES` at a time
        (whole blocks, the one holding ``start``); a request across two chunks is made on its own.
        A dense coupling (a small scene) is multiplied as asked: BLAS may sum in another order
        for another number of frames.
        """
        chunk = self.block_frames * max(1, PHOTON_CHUNK_BYTES
                                        // (8 * self.n_pixels * self.block_frames))
        first = start - start % chunk
        if (not sparse.issparse(self.coupling) or chunk <= self.block_frames
                or stop > first + chunk):
            return self._photons(start, stop)
        kept = self._memo.get("photons_chunk")
        if kept is None or kept[0] != first:
            kept = (first, self._photons(first, min(first + chunk, self.site_photons.shape[1])))
            self._memo["photons_chunk"] = kept
        return kept[1][start - first:stop - first]

    def _photons(self, start: int, stop: int) -> np.ndarray:
        return np.ascontiguousarray((self.coupling @ self.site_photons[:, start:stop]).T)

    @property
    def pix_photons(self) -> np.ndarray:
        """Photons per pixel per frame, ``(n_pixels, n_frames)``, made block by block (the whole
        run at once: for small scenes, tests and plots, not for the chip model's path)."""
        n, b = self.site_photons.shape[1], self.block_frames
        blocks = [self.photons_block(k, min(k + b, n)) for k in range(0, n, b)]
        return np.concatenate(blocks).T if blocks else np.zeros((self.n_pixels, 0))

    def pixel_block(self, t_int_s: float, gain_error: float, start: int, stop: int,
                    moments_at: np.ndarray | None = None) -> PixelFrames:
        """:func:`pixel_frames` of frames ``start … stop − 1`` (``moments_at``: as there).

        ``start`` is a multiple of :attr:`block_frames` and ``stop`` at most one block later, so
        the numbers are the same whether the scene keeps every block (small scenes: computed at
        the first call, shared by replicates) or computes each one when asked (large scenes).
        """
        if start % self.block_frames or stop - start > self.block_frames:
            raise ValueError(f"frames {start}…{stop}: not within one block of {self.block_frames}")
        n_frames = self.site_photons.shape[1]
        if not moments_kept(self.n_pixels, n_frames):
            return pixel_frames(self, t_int_s, gain_error, start, stop, moments_at)
        whole = self.pixel_frames(t_int_s, gain_error, moments_at)
        return PixelFrames(whole.mean_e[start:stop], whole.cds_mean_lsb[start:stop],
                           whole.cds_var_lsb2[start:stop],
                           int(np.count_nonzero(whole.mean_e[start:stop]
                                                >= self.sensor.full_well_e)))

    def once(self, key: str, make: Callable[[], Any]) -> Any:
        """``make()``, computed once per scene: figures that depend on the scene alone, not on
        a replicate's draws (a study's replicates share the scene)."""
        if key not in self._memo:
            self._memo[key] = make()
        return self._memo[key]

    def pixel_frames(self, t_int_s: float, gain_error: float,
                     moments_at: np.ndarray | None = None) -> PixelFrames:
        """Every frame's :func:`pixel_frames`, block by block (kept for a small scene)."""
        key = ("pixel_frames", t_int_s, gain_error, _at_key(moments_at))
        if key in self._memo:
            return self._memo[key]
        whole = _all_blocks(self, t_int_s, gain_error, moments_at)
        if moments_kept(self.n_pixels, self.site_photons.shape[1]):
            self._memo[key] = whole
        return whole


def _at_key(moments_at: np.ndarray | None) -> bytes | None:
    return None if moments_at is None else np.asarray(moments_at, np.int64).tobytes()


def _all_blocks(scene: Scene, t_int_s: float, gain_error: float,
                moments_at: np.ndarray | None = None) -> PixelFrames:
    """:func:`pixel_frames` of every block of ``scene``, stacked; read-only."""
    n, b = scene.site_photons.shape[1], scene.block_frames
    parts = [pixel_frames(scene, t_int_s, gain_error, k, min(k + b, n), moments_at)
             for k in range(0, n, b)]
    if not parts:
        empty = np.zeros((0, scene.n_pixels))
        parts = [PixelFrames(empty, empty, empty, 0)]
    arrays = [np.concatenate([getattr(p, name) for p in parts])
              for name in ("mean_e", "cds_mean_lsb", "cds_var_lsb2")]
    for arr in arrays:
        arr.flags.writeable = False  # shared by every replicate of the scene
    return PixelFrames(*arrays, full_well_pixel_frames=sum(p.full_well_pixel_frames
                                                           for p in parts))


def pixel_frames(scene: Scene, t_int_s: float, gain_error: float, start: int = 0,
                 stop: int | None = None, moments_at: np.ndarray | None = None) -> PixelFrames:
    """Expected charge and CMS moments of every pixel in frames ``start … stop − 1`` of ``scene``.

    Parameters
    ----------
    scene : Scene
        Light per site, coupling and the sensor.
    t_int_s : float
        Integration time (the dark charge is dark current × ``t_int_s``). Unit: s.
    gain_error : float
        The ADC's fractional gain error (``chip.adc.gain_error``): codes per electron are
        ``(1 + gain_error) / e_per_lsb``.
    start, stop : int
        The frames (all by default).
    moments_at : ndarray of int, optional
        The pixels whose CMS moments the run reads (sorted flat indices; None: all). With a
        converter as built its exact moments cost about 0.1 ms a pixel and frame, so a run that
        reads the DSP's moments at a few pixels (the sites of a large array: outputs elsewhere are
        dropped as they leave the DSP) has them computed there only; the other pixels' moments
        are NaN, never a number nobody computed. The ideal converter's moments are closed form
        and computed everywhere.

    Notes
    -----
    Element by element the same arithmetic as :func:`chiptwin.pixel.mean_electrons` and
    :func:`chiptwin.pixel.expected_frame` called on one frame at a time, so the numbers are those.
    With a converter as built (``sensor.converter`` not ideal) the CMS moments are the
    converter's own, its transition tables summed against the Gaussian samples
    (:func:`chiptwin.pixel.cms_moments`); ``gain_error`` is then in the converter.
    """
    sensor = scene.sensor
    stop = scene.site_photons.shape[1] if stop is None else stop
    photons = scene.photons_block(start, stop)
    dark_e = sensor.dark_e_per_s * t_int_s
    mean_e = pixel.mean_electrons(photons, sensor.qe, sensor.gain_map, dark_e)
    # pixel.expected_frame's arithmetic on the charge just computed (it would compute it again)
    cds_e, cds_var_e2 = pixel.clipped_poisson_moments(mean_e, sensor.full_well_e)
    conv = sensor.converter
    if conv is not None and not conv.ideal:  # the converter as built: its tables, exactly
        full = int(np.count_nonzero(mean_e >= sensor.full_well_e))
        at = slice(None) if moments_at is None else np.asarray(moments_at, np.int64)
        if moments_at is not None:
            conv = scene.once(("converter_at", _at_key(at)), lambda: sensor.converter.at(at))
        mean = np.full(mean_e.shape, np.nan)
        var = np.full(mean_e.shape, np.nan)
        mean[..., at], var[..., at] = pixel.cms_moments(
            conv, cds_e[..., at], cds_var_e2[..., at], ktc_e=sensor.ktc_e,
            read_noise_e=sensor.read_noise_e, cg_V=sensor.conversion_gain_uV_per_e * 1e-6,
            pedestal_V=sensor.pedestal_V, n_samples=sensor.cms_samples,
            true_cds=sensor.true_cds)
        return PixelFrames(mean_e, mean, var, full_well_pixel_frames=full)
    cds_var_e2 = cds_var_e2 + 2.0 * sensor.read_noise_e * sensor.read_noise_e / sensor.cms_samples
    if not sensor.true_cds:
        cds_var_e2 = cds_var_e2 + 2.0 * sensor.ktc_e * sensor.ktc_e
    to_lsb = (1.0 + gain_error) / sensor.e_per_lsb
    read_lsb = sensor.read_noise_e / sensor.e_per_lsb * (1.0 + gain_error)
    quant_var = 2.0 * pixel.quantization_var_of_mean(sensor.cms_samples, read_lsb)
    full = int(np.count_nonzero(mean_e >= sensor.full_well_e))
    return PixelFrames(mean_e, cds_e * to_lsb, cds_var_e2 * to_lsb**2 + quant_var,
                       full_well_pixel_frames=full)


@dataclass
class ChainOutput:
    """The chip model's outputs at the pixels, in electrons.

    Electrons are read back from codes at the ADC's nominal gain, as the chip itself would: an
    ADC gain error (``chip.adc.gain_error``) shows up as a scale error of every figure.

    ``value_e``, ``mean_e`` and ``var_e2`` are ``(n_blocks, n_kept)``: the DSP outputs at the kept
    ``pixels`` (sorted indices; None = every pixel). ``dark_var_e2`` covers every pixel (NaN
    where the run read no moments: converters as built, outside the kept pixels).
    ``peak_frame_e`` is the whole DSP output whose kept pixels sum highest (``peak_block``).
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
    pixels: np.ndarray | None = None
    peak_frame_e: np.ndarray | None = None
    peak_block: int = 0
    #: Pixels the run did not draw but carried at the ``expected`` level
    #: (:mod:`chiptwin.twin.shortcuts`, carried dark pixels); 0 on the full path.
    carried_pixels: int = 0

    def columns(self, idx: np.ndarray) -> np.ndarray:
        """Columns of ``value_e`` (and ``mean_e``, ``var_e2``) holding pixels ``idx``."""
        if self.pixels is None:
            return np.asarray(idx)
        cols = np.searchsorted(self.pixels, idx)
        if not np.array_equal(self.pixels[np.minimum(cols, len(self.pixels) - 1)], idx):
            raise KeyError(f"pixels {idx!r} were not kept (kept: {self.pixels!r})")
        return cols
