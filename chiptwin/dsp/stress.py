"""Stress data for the bit-accurate DSP: full-range random codes plus the corners that break things.

Every generator takes an ``np.random.Generator``; nothing here draws from a global stream. Random
codes are uniform over the whole register range with a share of corners (most negative, most
positive, zero, ±1), and each routine adds the input that drives its own output to the extreme
(all-max runs for accumulators, the sign pattern of the taps for the FIR and of a Wiener row).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from chiptwin.dsp.errors import Case
from chiptwin.dsp.filters import (
    FirConfig,
    KineticsConfig,
    WienerConfig,
    WienerEqualizer,
    design_wiener,
)
from chiptwin.dsp.fixed import Fmt
from chiptwin.dsp.frame_ops import AverageConfig, BackgroundConfig, BinningConfig, CmsConfig

CORNER_SHARE = 0.1
"""Share of random codes replaced by corner codes."""


def random_codes(
    fmt: Fmt, shape: tuple[int, ...], rng: np.random.Generator, corner_share: float = CORNER_SHARE
) -> np.ndarray:
    """Uniform codes over ``fmt``'s whole range, ``corner_share`` of them corners.

    Corners: ``min_code``, ``max_code``, 0, 1, -1 (when representable), ``min_code + 1``.
    """
    codes = rng.integers(fmt.min_code, fmt.max_code, size=shape, dtype=np.int64, endpoint=True)
    corners = np.array(
        sorted(
            {fmt.min_code, fmt.max_code, 0, 1, fmt.min_code + 1} | ({-1} if fmt.signed else set())
        ),
        dtype=np.int64,
    )
    corners = corners[(corners >= fmt.min_code) & (corners <= fmt.max_code)]
    mask = rng.random(shape) < corner_share
    codes[mask] = rng.choice(corners, size=int(np.count_nonzero(mask)))
    return codes


def _extreme(fmt: Fmt, sign: np.ndarray | int) -> np.ndarray:
    return np.where(np.asarray(sign) >= 0, fmt.max_code, fmt.min_code).astype(np.int64)


def _with_extremes(x: np.ndarray, fmt: Fmt, axis_len: int) -> np.ndarray:
    """Overwrite the first ``axis_len`` entries of axis 0 with max, the next with min."""
    x = x.copy()
    k = min(axis_len, x.shape[0] // 2)
    x[:k] = fmt.max_code
    x[k : 2 * k] = fmt.min_code
    return x


def stress_background(
    cfg: BackgroundConfig, rng: np.random.Generator, n_frames: int, n_pixels: int
) -> dict[str, np.ndarray]:
    """Frames with an all-zero and an all-full-scale frame; dark with zeros and full scale."""
    frames = _with_extremes(random_codes(cfg.in_fmt, (n_frames, n_pixels), rng), cfg.in_fmt, 1)
    dark = random_codes(cfg.dark_fmt, (n_pixels,), rng, corner_share=0.3)
    return {"frames": frames, "dark": dark}


def stress_cms(
    cfg: CmsConfig, rng: np.random.Generator, n_frames: int, n_pixels: int
) -> dict[str, np.ndarray]:
    """Samples with one frame at (reset max, signal min) and one the other way round."""
    shape = (n_frames, cfg.m, n_pixels)
    reset = random_codes(cfg.in_fmt, shape, rng)
    signal = random_codes(cfg.in_fmt, shape, rng)
    if n_frames >= 2:
        reset[0], signal[0] = cfg.in_fmt.max_code, cfg.in_fmt.min_code
        reset[1], signal[1] = cfg.in_fmt.min_code, cfg.in_fmt.max_code
    return {"reset": reset, "signal": signal}


def stress_frames(
    cfg: AverageConfig | BinningConfig, rng: np.random.Generator, n_frames: int, n_pixels: int
) -> dict[str, np.ndarray]:
    """Frames whose first run is all full scale and the second all most-negative."""
    run = cfg.n if isinstance(cfg, AverageConfig) else 1
    frames = random_codes(cfg.in_fmt, (n_frames, n_pixels), rng)
    return {"frames": _with_extremes(frames, cfg.in_fmt, run)}


def stress_kinetics(
    cfg: KineticsConfig, rng: np.random.Generator, n_blocks: int, n_pixels: int
) -> dict[str, np.ndarray]:
    """Blocks of N frames; one block at full scale, one at the most negative code."""
    shape = (n_blocks, len(cfg.t_s), n_pixels)
    return {"frames": _with_extremes(random_codes(cfg.in_fmt, shape, rng), cfg.in_fmt, 1)}


def stress_fir(
    cfg: FirConfig, rng: np.random.Generator, n_frames: int, n_pixels: int
) -> dict[str, np.ndarray]:
    """Random frames, then a full-scale step, then the tap-sign pattern that maximises ``|y|``."""
    frames = random_codes(cfg.in_fmt, (n_frames, n_pixels), rng)
    h = np.array(cfg.coef_codes)
    if n_frames >= 3 * cfg.taps:
        frames[: cfg.taps] = cfg.in_fmt.max_code
        worst = _extreme(cfg.in_fmt, h[::-1])  # x[t-k] = sign(h_k) · full scale
        frames[cfg.taps : 2 * cfg.taps] = worst[:, None]
        frames[2 * cfg.taps : 3 * cfg.taps] = _extreme(cfg.in_fmt, -h[::-1])[:, None]
    return {"frames": frames}


def stress_wiener(
    eq: WienerEqualizer, rng: np.random.Generator, n_frames: int
) -> dict[str, np.ndarray]:
    """Random frames plus the frame ``x_p = sign(G_q[s, p]) · full scale`` for the largest row."""
    fmt = eq.cfg.in_fmt
    frames = random_codes(fmt, (n_frames, eq.n_pixels), rng)
    row = int(np.argmax(np.abs(eq.coef_codes).sum(axis=1)))
    if n_frames >= 2:
        frames[0] = _extreme(fmt, eq.coef_codes[row])
        frames[1] = _extreme(fmt, -eq.coef_codes[row])
    return {"frames": frames}


def stress_coupling(
    rows: int, cols: int, own: float = 0.6, neighbour: float = 0.08, diagonal: float = 0.02
) -> np.ndarray:
    """A synthetic site-to-pixel coupling (one site per pixel, nearest-neighbour spread).

    Not the optics stage's matrix: a stand-in with the same shape (n_pixels × n_sites) for stress
    runs. Pixel ``(r, c)`` receives ``own`` of its site, ``neighbour`` of each edge neighbour and
    ``diagonal`` of each corner neighbour.
    """
    n = rows * cols
    c = np.zeros((n, n))
    for r in range(rows):
        for q in range(cols):
            for dr in (-1, 0, 1):
                for dq in (-1, 0, 1):
                    rr, qq = r + dr, q + dq
                    if 0 <= rr < rows and 0 <= qq < cols:
                        share = (own, neighbour, diagonal)[abs(dr) + abs(dq)]
                        c[r * cols + q, rr * cols + qq] = share
    return c


def default_configs(rows: int = 8, cols: int = 16) -> dict[str, tuple[str, Any]]:
    """The reference chip's routines with default formats: label → (routine, config)."""
    eq = design_wiener(stress_coupling(rows, cols), WienerConfig())
    return {
        "background": ("background", BackgroundConfig()),
        "cms M=4": ("cms", CmsConfig(m=4)),
        "cms M=3": ("cms", CmsConfig(m=3)),
        "accumulate N=64": ("accumulate", AverageConfig(n=64)),
        "average N=4": ("average", AverageConfig(n=4)),
        "average N=5": ("average", AverageConfig(n=5)),
        "binning x2": ("binning", BinningConfig(rows=rows, cols=cols, factor=2)),
        "kinetics k=0.05/s": ("kinetics", KineticsConfig()),
        "fir 8-tap": ("fir", FirConfig()),
        "wiener": ("wiener", eq),
    }


def stress_inputs(
    routine: str, cfg: Any, rng: np.random.Generator, n_frames: int = 64, n_pixels: int = 128
) -> dict[str, np.ndarray]:
    """Stress inputs for one routine (frames rounded to a multiple of the routine's run)."""
    if routine == "background":
        return stress_background(cfg, rng, n_frames, n_pixels)
    if routine == "cms":
        return stress_cms(cfg, rng, n_frames, n_pixels)
    if routine in ("accumulate", "average"):
        return stress_frames(cfg, rng, max(n_frames // cfg.n, 2) * cfg.n, n_pixels)
    if routine == "binning":
        return stress_frames(cfg, rng, n_frames, cfg.rows * cfg.cols)
    if routine == "kinetics":
        return stress_kinetics(cfg, rng, max(n_frames // len(cfg.t_s), 2), n_pixels)
    if routine == "fir":
        return stress_fir(cfg, rng, n_frames, n_pixels)
    if routine == "wiener":
        return stress_wiener(cfg, rng, n_frames)
    raise ValueError(f"stress_inputs: unknown routine {routine!r}")


def default_cases(
    rng: np.random.Generator, n_frames: int = 64, rows: int = 8, cols: int = 16
) -> dict[str, Case]:
    """Every routine with its default formats on stress data: ready for ``error_report``."""
    return {
        label: Case(routine, cfg, stress_inputs(routine, cfg, rng, n_frames, rows * cols))
        for label, (routine, cfg) in default_configs(rows, cols).items()
    }
