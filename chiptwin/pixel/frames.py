"""The ``binned`` level for many frames at once: expected charge → ADC codes, in one kernel call.

:func:`binned_codes` gives exactly what calling :func:`~chiptwin.pixel.sensor.sample_frame` →
:func:`~chiptwin.pixel.adc.to_volts` → :func:`~chiptwin.pixel.adc.adc_convert` frame after frame
on the same ``rng`` gives: the same draws, in the same order, from the caller's stream, and the same
arithmetic per sample, so the codes are bit for bit those (tested), and ``rng`` is left in the same
state. It is the path of the chip model, which reads a small array over thousands of frames: the
arguments are checked once per call instead of once per frame, and no Python runs per frame.

Large arrays use every core: given one stream per chunk of :data:`CHUNK_PIXELS` pixels
(:func:`chunk_streams`), each chunk is drawn in frame order from its own stream, the chunks in
parallel threads (the kernel releases the GIL). Chunk 0's stream is the caller's ``rng``, so an
array of at most :data:`CHUNK_PIXELS` pixels draws exactly what it drew before chunking; which
thread draws a chunk changes nothing, so the codes depend on the seed only, never on the thread
count (tested).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from numpy.typing import ArrayLike, NDArray

from chiptwin.limits import POISSON_LAM_MAX
from chiptwin.pixel import _kernels, _random
from chiptwin.pixel._checks import check_array, readonly
from chiptwin.pixel.chain import _readout_consts
from chiptwin.pixel.converter import Converter, resolve_converter
from chiptwin.pixel.sensor import _check_readout

#: Pixels per random stream at the ``binned`` level: the unit of parallel work. A fixed number
#: (never derived from the thread count), so the streams, and the numbers, depend on the seed only.
CHUNK_PIXELS: int = 2048


def chunk_streams(rng: np.random.Generator, n_pixels: int) -> list[np.random.Generator]:
    """One stream per chunk of :data:`CHUNK_PIXELS` pixels: ``rng`` itself for chunk 0, then the
    children of ``rng``'s seed sequence keyed ``(…, c)`` for chunk ``c`` (what
    ``SeedSequence.spawn`` would give, without changing ``rng``)."""
    n_chunks = max(1, -(-n_pixels // CHUNK_PIXELS))
    ss = rng.bit_generator.seed_seq
    return [rng] + [np.random.default_rng(np.random.SeedSequence(
        ss.entropy, spawn_key=(*ss.spawn_key, c), pool_size=ss.pool_size))
        for c in range(1, n_chunks)]


#: The drawing threads, one pool per thread count, made on first use and kept for the process.
_POOLS: dict[int, ThreadPoolExecutor] = {}
# A forked child (multiprocessing's default start method on Linux) inherits the pools but not
# their threads: its first draw would wait forever on work no thread takes. It makes its own.
os.register_at_fork(after_in_child=_POOLS.clear)


def _pool(threads: int) -> ThreadPoolExecutor:
    if threads not in _POOLS:
        _POOLS[threads] = ThreadPoolExecutor(max_workers=threads)
    return _POOLS[threads]


def default_threads() -> int:
    """Threads drawing chunks: numba's thread count (``NUMBA_NUM_THREADS``)."""
    try:
        import numba

        return int(numba.get_num_threads())
    except Exception:  # pragma: no cover - numba always importable here
        return os.cpu_count() or 1


#: Mean charge from which each ``shot_noise`` level draws the normal instead of the Poisson
#: count: never (``poisson``), always (``gaussian``). Unit: e⁻.
SHOT_MIN_MEAN_E = {"poisson": math.inf, "gaussian": 0.0}


def code_dtype(bits: int) -> type[np.unsignedinteger]:
    """The narrowest unsigned integer that holds a ``bits``-bit code: ``uint16`` up to 16 bits
    (a quarter of int64's memory for every frame a run holds), else ``uint32``. The DSP reads
    codes as int64 or float64 (:func:`chiptwin.dsp.fixed.as_codes`, the float reference), so
    arithmetic never happens in the narrow type."""
    return np.uint16 if bits <= 16 else np.uint32


def binned_codes(
    rng: np.random.Generator | Sequence[np.random.Generator],
    mean_e: ArrayLike,
    *,
    full_well_e: float,
    ktc_e: float,
    read_noise_e: float,
    n_samples: int,
    true_cds: bool,
    conversion_gain_uV_per_e: float,
    pedestal_V: float,
    bits: int | None = None,
    v_min_V: float | None = None,
    v_max_V: float | None = None,
    offset_lsb: float | None = None,
    gain_error: float | None = None,
    converter: Converter | None = None,
    report_pixels: ArrayLike = (),
    report_e: NDArray[np.float64] | None = None,
    threads: int | None = None,
    shot_noise: str = "poisson",
    normal_rng: np.random.Generator | Sequence[np.random.Generator] | None = None,
) -> NDArray[np.unsignedinteger]:
    """ADC codes of the reset and signal samples of ``n_frames`` frames, drawn in frame order.

    Parameters
    ----------
    rng : numpy.random.Generator, or a sequence of them
        The pixel stage's stream; advanced as the frame-by-frame path advances it. A sequence
        (:func:`chunk_streams`) gives one stream per chunk of :data:`CHUNK_PIXELS` pixels, the
        chunks drawn in parallel; with one chunk it is the single-stream path.
    mean_e : array_like (n_frames, n_pixels)
        Expected charge of each pixel in each frame, before the full-well clip
        (:func:`~chiptwin.pixel.sensor.mean_electrons`). Unit: e⁻.
    full_well_e, ktc_e, read_noise_e, n_samples, true_cds
        As in :func:`~chiptwin.pixel.sensor.sample_frame`.
    conversion_gain_uV_per_e, pedestal_V
        As in :func:`~chiptwin.pixel.adc.to_volts`.
    bits, v_min_V, v_max_V, offset_lsb, gain_error
        As in :func:`~chiptwin.pixel.adc.adc_convert` (``offset_lsb``, ``gain_error`` default
        0); required unless ``converter`` is given, and not with it.
    converter : Converter, optional
        The converters as built (:func:`~chiptwin.pixel.converter.build_converter`, one per
        pixel). An ideal one gives the keywords' codes bit for bit. Comparator noise is folded
        into each sample's read-noise draw (one Gaussian of the summed variance,
        :func:`chiptwin.pixel._kernels.sample_noise`): it draws nothing more and moves no stream.
    report_pixels : array_like of int (n_report,), optional
        Pixels (indices along ``n_pixels``) whose drawn counts are written to ``report_e`` (the
        ``events`` level times their wells' filling from them). Nothing else changes: the codes
        and the streams are those of a call without them.
    report_e : ndarray of float64 (n_frames, n_report), optional
        Filled with those pixels' counts in each frame, before the full-well clip. Unit: e⁻.
    threads : int, optional
        Threads drawing the chunks (default :func:`default_threads`); never changes the codes.
    shot_noise : {"poisson", "gaussian"}
        ``"poisson"``: exact counts. ``"gaussian"`` (the ``[run.fidelity] shot`` level): every
        count is ``max(0, rint(λ + √λ·z))``, the normal of the same mean and variance (plus
        1/12 e⁻² of rounding); its total-variation distance to the Poisson law is
        :func:`chiptwin.twin.levels.gaussian_tv` of the mean (≈ 0.13/√λ: 0.004 at λ = 1000).
    normal_rng : numpy.random.Generator, or a sequence of them, optional
        The kTC, read-noise and comparator normals' own stream(s), shaped as ``rng``; ``rng``
        then draws the counts only (the ``gaussian`` level's normal too). The normals are then
        the same draws whatever the counts' means or law: two runs that differ in the photon,
        shot, kinetics or optics level share them (common random numbers; the counts of
        different means or laws are not coupled). Default: ``rng`` draws everything, in
        ``sample_frame``'s order.

    Returns
    -------
    ndarray of uint16 (up to 16 bits) or uint32 (n_frames, 2M, n_pixels)
        Per frame the M reset codes, then the M signal codes: frame ``k`` is
        ``adc_convert(to_volts(np.concatenate(sample_frame(rng, ...)), ...), ...)`` of the
        frame-by-frame path. Unit: codes.
    """
    lam = np.ascontiguousarray(check_array("mean_e", mean_e, 0.0, POISSON_LAM_MAX))
    if lam.ndim != 2:
        raise ValueError(f"mean_e has shape {lam.shape}: must be (n_frames, n_pixels)")
    fw, ktc, read, m = _check_readout(full_well_e, ktc_e, read_noise_e, n_samples)
    conv = resolve_converter(converter, bits, v_min_V, v_max_V, offset_lsb, gain_error)
    conv.check_pixels(lam.shape[1])
    readout = _readout_consts(pedestal_V, conversion_gain_uV_per_e, conv)
    pixels, report = _report(report_pixels, report_e, lam.shape)
    codes = np.empty((lam.shape[0], 2 * m, lam.shape[1]), code_dtype(conv.bits))
    if shot_noise not in SHOT_MIN_MEAN_E:
        raise ValueError(f"shot_noise = {shot_noise!r}: must be one of {sorted(SHOT_MIN_MEAN_E)}")
    consts = (fw, ktc, read, bool(true_cds), *readout, SHOT_MIN_MEAN_E[shot_noise])
    fold = (read, readout[1])  # read noise (e⁻) and conversion gain (V/e⁻): comparator folded
    if isinstance(rng, np.random.Generator):
        _draw_chunk(rng, normal_rng, lam, pixels, report, consts,
                    conv.kernel_conv(0, None, fold), codes)
        return codes
    streams = list(rng)
    normals = [None] * len(streams) if normal_rng is None else list(normal_rng)
    n_chunks = max(1, -(-lam.shape[1] // CHUNK_PIXELS))
    if len(streams) != n_chunks or len(normals) != n_chunks:
        raise ValueError(f"{len(streams)} streams ({len(normals)} normal) for {lam.shape[1]} "
                         f"pixels: must be {n_chunks}, one per chunk of {CHUNK_PIXELS}")

    def draw(c: int) -> None:
        lo, hi = c * CHUNK_PIXELS, min((c + 1) * CHUNK_PIXELS, lam.shape[1])
        mine = (pixels >= lo) & (pixels < hi)
        drawn = np.empty((lam.shape[0], int(mine.sum())))
        _draw_chunk(streams[c], normals[c], lam[:, lo:hi], pixels[mine] - lo, drawn, consts,
                    conv.kernel_conv(lo, hi, fold), codes[:, :, lo:hi])
        report[:, mine] = drawn  # the chunks' columns are disjoint: safe from threads

    threads = default_threads() if threads is None else int(threads)
    if n_chunks == 1 or threads <= 1:
        for c in range(n_chunks):
            draw(c)
    else:
        list(_pool(threads).map(draw, range(n_chunks)))
    return codes


def _draw_chunk(rng: np.random.Generator, normal_rng: np.random.Generator | None, lam, pixels,
                report, consts, conv, codes) -> None:
    """:func:`_kernels.frame_codes` on ``rng`` (and ``normal_rng``, if given, for the normals):
    a PCG64 or SFC64 state advanced inline and written back (:mod:`chiptwin.pixel._random`), any
    other bit generator through numba's ``Generator`` interface (the same draws, ≈ 2× slower)."""
    if normal_rng is not None and type(normal_rng.bit_generator) is not type(rng.bit_generator):
        raise ValueError("normal_rng: must have the bit generator of rng "
                         f"({type(rng.bit_generator).__name__})")
    source = _random.state_of(rng)
    normal = None if normal_rng is None else _random.state_of(normal_rng)
    # One compiled version per code width: numba compiles the kernel again for every layout and
    # write flag of its arrays (≈ 20 s each on a cold cache; the tests made five). The means go
    # in as a read-only C array, the codes as a C array (a chunk's written back after).
    lam = readonly(np.ascontiguousarray(lam))
    out = codes if codes.flags.c_contiguous else np.empty(codes.shape, codes.dtype)
    shot = rng if source is None else source
    if normal_rng is None:
        normal_src = shot  # one stream: the same state (or Generator) advanced by every draw
    else:
        normal_src = normal_rng if normal is None else normal
    _kernels.frame_codes(shot, normal_src, lam, pixels, report, *consts, conv, out)
    if out is not codes:
        codes[...] = out
    if source is not None:
        _random.put_state(rng, source)
    if normal is not None:
        _random.put_state(normal_rng, normal)


def _report(pixels: ArrayLike, report_e: NDArray[np.float64] | None, shape: tuple[int, int]
            ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Checked ``report_pixels`` and ``report_e`` for a ``(n_frames, n_pixels)`` run."""
    idx = np.asarray(pixels, dtype=np.int64).reshape(-1)
    if idx.size and (idx.min() < 0 or idx.max() >= shape[1]):
        raise ValueError(f"report_pixels = {pixels!r}: must be indices in [0, {shape[1] - 1}]")
    if report_e is None:
        if idx.size:
            raise ValueError("report_e: an array (n_frames, n_report) is needed with "
                             "report_pixels")
        return idx, np.zeros((shape[0], 0))
    if (not isinstance(report_e, np.ndarray) or report_e.dtype != np.float64
            or report_e.shape != (shape[0], idx.size) or not report_e.flags.c_contiguous):
        raise ValueError(f"report_e: must be a C-contiguous float64 array of shape "
                         f"{(shape[0], idx.size)}")
    return idx, report_e
