"""The sensor chain on large arrays: photons → codes, frame by frame, on every core.

:func:`sensor_chain` is the fast path of :func:`~chiptwin.pixel.sensor.sample_frame` →
:func:`~chiptwin.pixel.adc.to_volts` → :func:`~chiptwin.pixel.adc.adc_convert`: the same physics
and the same statistics (tested), fused into one numba pass per pixel
(:func:`chiptwin.pixel._kernels.chain_chunk`).

Parallelism without changing the numbers: the pixels of a frame are cut into fixed chunks of
``chunk_pixels``; chunk ``c`` owns the streams of the ``c``-th child of a ``SeedSequence`` seeded
from the caller's ``rng`` (:func:`chunk_streams`) and keeps drawing from them frame after frame.
Threads (the kernel releases the GIL) take chunks in any order, so the codes depend on the seed
and on ``chunk_pixels``, never on the number of threads or cores. Memory does not grow with the
number of frames: frames are processed one at a time and, given ``out``, written into the same
buffers.
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Iterable, Iterator
from concurrent.futures import ThreadPoolExecutor
from typing import Literal, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from chiptwin.pixel import _kernels
from chiptwin.pixel._checks import check_array, check_int, check_scalar, readonly
from chiptwin.pixel.converter import Converter, resolve_converter

#: Default pixels per chunk: one stream each, the unit of work of a thread.
CHUNK_PIXELS: int = 1 << 16

#: Default mean above which ``shot_noise="gaussian"`` replaces the Poisson draw. Unit: e⁻.
GAUSSIAN_MIN_MEAN_E: float = 1000.0

_SHOT = {"poisson": _kernels.SHOT_POISSON, "gaussian": _kernels.SHOT_GAUSSIAN}

Codes = NDArray[np.int64]


def available_cores() -> int:
    """Cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def chunk_streams(
    rng: np.random.Generator, n_pixels: int, chunk_pixels: int
) -> tuple[list[np.random.Generator], list[np.random.Generator]]:
    """Two independent SFC64 generators per chunk: one for shot noise, one for Gaussian draws.

    Chunk ``c`` gets the ``c``-th child of a SeedSequence seeded from ``rng``, and that child's
    two children seed its generators. SFC64 is NumPy's fast, statistically high-quality bit
    generator; the kernel advances both states inline (:mod:`chiptwin.pixel._random`).
    """
    return _streams(_chunk_seeds(rng, n_pixels, chunk_pixels))


def _chunk_seeds(
    rng: np.random.Generator, n_pixels: int, chunk_pixels: int
) -> list[np.random.SeedSequence]:
    """The chunks' SeedSequences (4 integers drawn from ``rng``)."""
    n_chunks = -(-n_pixels // chunk_pixels)
    root = np.random.SeedSequence(rng.integers(0, 2**63, size=4).tolist())
    return root.spawn(n_chunks)


def _child(seq: np.random.SeedSequence, k: int) -> np.random.Generator:
    """An SFC64 generator on the ``k``-th child of ``seq`` (what ``seq.spawn`` gives it)."""
    key = np.random.SeedSequence(
        seq.entropy, spawn_key=(*seq.spawn_key, k), pool_size=seq.pool_size
    )
    return np.random.Generator(np.random.SFC64(key))


def _streams(
    seeds: list[np.random.SeedSequence],
) -> tuple[list[np.random.Generator], list[np.random.Generator]]:
    return [_child(s, 0) for s in seeds], [_child(s, 1) for s in seeds]


def _states(gens: list[np.random.Generator]) -> NDArray[np.uint64]:
    """The SFC64 states ``(n_chunks, 4)`` the kernel advances in place
    (:mod:`chiptwin.pixel._random`)."""
    return np.array([g.bit_generator.state["state"]["state"] for g in gens], dtype=np.uint64)


def _frames(photons: ArrayLike | Iterable[ArrayLike], n_frames: int | None) -> Iterator:
    """The frames to process: one frame repeated ``n_frames`` times, or the items of an iterable."""
    if n_frames is not None:
        frame = check_array("photons", photons, 0.0)
        return itertools.repeat(frame, check_int("n_frames", n_frames, 0))
    scalar = isinstance(photons, np.ndarray) and photons.ndim == 0
    if scalar or not isinstance(photons, Iterable):
        raise ValueError(f"photons = {photons!r}: must be frames when n_frames is not given")
    return iter(photons)  # type: ignore[arg-type]


def _frame_array(frame: ArrayLike, shape: tuple[int, ...] | None) -> NDArray[np.float64]:
    arr = np.ascontiguousarray(check_array("photons", frame, 0.0))
    if shape is not None and arr.shape != shape:
        raise ValueError(f"photons frame has shape {arr.shape}: must match the first, {shape}")
    return arr


def _pixel_map(name: str, values: ArrayLike, shape: tuple[int, ...]) -> NDArray[np.float64]:
    arr = check_array(name, values, 0.0)
    try:
        return np.ascontiguousarray(np.broadcast_to(arr, shape)).ravel()
    except ValueError:
        raise ValueError(f"{name} has shape {arr.shape}: must broadcast to {shape}") from None


def _buffers(
    shape: tuple[int, ...], n_reset: int, n_samples: int, out: tuple[Codes, Codes] | None
) -> tuple[Codes, Codes]:
    """Output arrays ``(n_reset, *shape)`` and ``(n_samples, *shape)``: ``out`` or new ones."""
    want = ((n_reset, *shape), (n_samples, *shape))
    if out is None:
        return np.empty(want[0], np.int64), np.empty(want[1], np.int64)
    for name, arr, w in zip(("out[0]", "out[1]"), out, want, strict=True):
        ok = arr.shape == w and arr.dtype == np.int64 and arr.flags.c_contiguous
        if not ok:
            raise ValueError(f"{name} must be a C-contiguous int64 array of shape {w}")
    return out


class _Plan(NamedTuple):
    """What the run needs besides the data: kernel constants and sizes, all checked."""

    consts: tuple
    convs: list[tuple]  # the converter of each chunk (Converter.kernel_conv)
    chunk: int
    n_samples: int
    n_reset: int
    n_threads: int
    repeat: bool  # one checked frame used n_frames times: no per-frame check or copy


def _sensor_consts(
    qe: float, full_well_e: float, ktc_e: float, read_noise_e: float, true_cds: bool,
    read_reset: bool, shot_noise: str, gaussian_min_mean_e: float,
) -> tuple:  # fmt: skip
    """The pixel half of the kernel's constants, checked."""
    if shot_noise not in _SHOT:
        raise ValueError(f"shot_noise = {shot_noise!r}: must be one of {sorted(_SHOT)}")
    return (
        check_scalar("qe", qe, 0.0, 1.0),
        check_scalar("full_well_e", full_well_e, 0.0, lo_open=True),
        check_scalar("ktc_e", ktc_e, 0.0),
        check_scalar("read_noise_e", read_noise_e, 0.0),
        bool(true_cds),
        bool(read_reset),
        _SHOT[shot_noise],
        check_scalar("gaussian_min_mean_e", gaussian_min_mean_e, 0.0, lo_open=True),
    )


def _readout_consts(
    pedestal_V: float, conversion_gain_uV_per_e: float, converter: Converter
) -> tuple:  # fmt: skip
    """The voltage and nominal ADC half of the kernel constants (the converter checked itself)."""
    cg = check_scalar("conversion_gain_uV_per_e", conversion_gain_uV_per_e, 0.0, lo_open=True)
    ped = check_scalar("pedestal_V", pedestal_V)
    return (ped, cg * 1e-6, *converter.consts())


def _run_frame(
    pool: ThreadPoolExecutor | None,
    streams: tuple[NDArray[np.uint64], NDArray[np.uint64]],
    plan: _Plan,
    arrays: tuple[NDArray[np.float64], ...],
    outs: tuple[Codes, Codes],
) -> None:
    """Run the kernel over every chunk of one frame, on the pool's threads or inline."""
    (photons, gain, dark), (reset2d, signal2d), chunk = arrays, outs, plan.chunk
    (shot, noise), n_chunks = streams, len(streams[1])

    def work(c: int) -> None:
        sl = slice(c * chunk, (c + 1) * chunk)
        _kernels.chain_chunk(  # read-only inputs: one compiled version whatever the caller's
            shot[c], noise[c], photons[sl], readonly(gain[sl]), readonly(dark[sl]), *plan.consts,
            plan.convs[c], reset2d, signal2d, sl.start,
        )  # fmt: skip

    if pool is None:
        for c in range(n_chunks):
            work(c)
        return
    for future in [pool.submit(work, c) for c in range(n_chunks)]:
        future.result()


def _run(
    frames: Iterator,
    first: NDArray[np.float64],
    maps: tuple[NDArray[np.float64], NDArray[np.float64]],
    streams: tuple[NDArray[np.uint64], NDArray[np.uint64]],
    plan: _Plan,
    out: tuple[Codes, Codes] | None,
) -> Iterator[tuple[Codes, Codes]]:
    """The frame loop: one frame in flight, buffers reused when ``out`` is given."""
    pool = ThreadPoolExecutor(plan.n_threads) if plan.n_threads > 1 else None
    try:
        frame: NDArray[np.float64] | None = first
        while frame is not None:
            reset, signal = _buffers(first.shape, plan.n_reset, plan.n_samples, out)
            outs = (
                reset.reshape(plan.n_reset, first.size),
                signal.reshape(plan.n_samples, first.size),
            )
            _run_frame(pool, streams, plan, (frame.ravel(), *maps), outs)
            yield reset, signal
            item = next(frames, None)
            if item is None or plan.repeat:
                frame = None if item is None else first
            else:
                frame = _frame_array(item, first.shape)
    finally:
        if pool is not None:
            pool.shutdown()


def sensor_chain(
    rng: np.random.Generator,
    photons: ArrayLike | Iterable[ArrayLike],
    *,
    qe: float,
    dark_e: ArrayLike,
    full_well_e: float,
    read_noise_e: float,
    conversion_gain_uV_per_e: float,
    n_frames: int | None = None,
    gain_map: ArrayLike = 1.0,
    ktc_e: float = 0.0,
    true_cds: bool = True,
    n_samples: int = 1,
    read_reset: bool = False,
    pedestal_V: float = 0.0,
    bits: int | None = None,
    v_min_V: float | None = None,
    v_max_V: float | None = None,
    offset_lsb: float | None = None,
    gain_error: float | None = None,
    converter: Converter | None = None,
    shot_noise: Literal["poisson", "gaussian"] = "poisson",
    gaussian_min_mean_e: float = GAUSSIAN_MIN_MEAN_E,
    n_threads: int | None = None,
    chunk_pixels: int = CHUNK_PIXELS,
    out: tuple[Codes, Codes] | None = None,
) -> Iterator[tuple[Codes, Codes]]:
    """Photons → ADC codes for a series of frames, fast, on every core (the ``binned`` level).

    Parameters
    ----------
    rng : numpy.random.Generator
        Seeds the per-chunk streams (4 integers are drawn from it when this is called).
    photons : array_like or iterable of array_like
        Expected photons per pixel per frame (the exact integral of the rate). Unit: photons.
        With ``n_frames``: one frame of any shape ``S``, used for each of the ``n_frames``.
        Without: the frames themselves, e.g. an ``(n_frames, *S)`` array or a generator of
        ``S``-shaped arrays (consumed lazily, one frame at a time).
    qe, gain_map, dark_e : float, array_like, array_like
        As in :func:`~chiptwin.pixel.sensor.mean_electrons`; maps broadcast to ``S``.
    full_well_e, ktc_e, read_noise_e, n_samples, true_cds
        As in :func:`~chiptwin.pixel.sensor.sample_frame`.
    read_reset : bool
        Convert the M reset samples too. False gives the one-read chain of Pyxel's CMOS model
        (reset codes then have shape ``(0, *S)``).
    conversion_gain_uV_per_e, pedestal_V
        As in :func:`~chiptwin.pixel.adc.to_volts`.
    bits, v_min_V, v_max_V, offset_lsb, gain_error
        As in :func:`~chiptwin.pixel.adc.adc_convert`; default 12, 0, 1, 0, 0. Not with
        ``converter``.
    converter : Converter, optional
        The converters as built (:func:`~chiptwin.pixel.converter.build_converter`, one per
        pixel of ``S``), instead of the keywords above. Its comparator noise is folded into each
        sample's read-noise draw (one Gaussian of the summed variance,
        :func:`chiptwin.pixel._kernels.sample_noise`): no stream moves, nothing more is drawn.
        An ideal converter gives the keywords' codes bit for bit.
    shot_noise : {"poisson", "gaussian"}
        ``"poisson"``: exact counts (:func:`~chiptwin.pixel._random.poisson_fast`: Ahrens &
        Dieter's sampler above a mean of 10, the same law as NumPy's, ≈ 2× faster, other draws;
        NumPy's below). ``"gaussian"``: a named approximation, the count
        ``max(0, rint(λ + √λ·z))`` for means ``λ ≥ gaussian_min_mean_e`` (exact Poisson below).
        Its error (``benchmarks/bench_sensor_chain.py``): total-variation distance to the Poisson
        law 0.0040 at λ = 1000 and 0.0013 at 10⁴ (it drops the skewness 1/√λ); it adds 1/12 e⁻² of
        rounding variance. ≈ 1.3–1.6× faster than "poisson" on the benchmark scene.
    n_threads : int, optional
        Worker threads; default all available cores. Does not change the codes.
    chunk_pixels : int
        Pixels per chunk, each with its own stream. Changing it changes the codes.
    out : (ndarray, ndarray), optional
        C-contiguous int64 arrays ``(n_reset, *S)``, ``(n_samples, *S)`` written every frame and
        yielded again (copy a frame you keep); default new arrays for each frame.

    Yields
    ------
    reset_codes, signal_codes : ndarray of int64, ``(M or 0, *S)`` and ``(M, *S)``
        ADC codes of the reset and signal samples of each frame, in order.

    Notes
    -----
    Exactly the statistics of ``sample_frame`` → ``to_volts`` → ``adc_convert`` with the same
    parameters (tested), though not the same draws: the kernel draws pixel by pixel from its
    chunk's stream (order in :func:`chiptwin.pixel._kernels.chain_chunk`). Scalars, maps and the
    first frame are checked when this is called; every later frame when it is reached.
    """
    sensor = _sensor_consts(
        qe, full_well_e, ktc_e, read_noise_e, true_cds, read_reset, shot_noise, gaussian_min_mean_e
    )
    conv = resolve_converter(
        converter, bits, v_min_V, v_max_V, offset_lsb, gain_error, (12, 0.0, 1.0, 0.0, 0.0)
    )
    readout = _readout_consts(pedestal_V, conversion_gain_uV_per_e, conv)
    m = check_int("n_samples", n_samples, 1)
    chunk = check_int("chunk_pixels", chunk_pixels, 1)
    threads = check_int("n_threads", available_cores() if n_threads is None else n_threads, 1)
    frames = _frames(photons, n_frames)
    first_item = next(frames, None)
    if first_item is None:
        return iter(())
    first = _frame_array(first_item, None)
    maps = (
        _pixel_map("gain_map", gain_map, first.shape),
        _pixel_map("dark_e", dark_e, first.shape),
    )
    conv.check_pixels(first.size)
    seeds = _chunk_seeds(rng, max(first.size, 1), chunk)
    shot, noise = _streams(seeds)
    fold = (sensor[3], readout[1])  # read noise (e⁻) and conversion gain (V/e⁻), checked
    convs = [conv.kernel_conv(c * chunk, (c + 1) * chunk, fold) for c in range(len(seeds))]
    n_reset = m if read_reset else 0
    plan = _Plan(
        sensor + readout,
        convs,
        chunk,
        m,
        n_reset,
        min(threads, len(noise)),
        n_frames is not None,
    )
    _buffers(first.shape, plan.n_reset, m, out)  # check out now, not at the first frame
    return _run(frames, first, maps, (_states(shot), _states(noise)), plan, out)
