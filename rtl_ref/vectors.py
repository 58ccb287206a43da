"""Test vectors for every block: random full-range codes plus the corners that break hardware.

Every generator takes an ``np.random.Generator`` (reproducible from its seed) and returns the
inputs of the model routine (the keys of :class:`chiptwin.dsp.errors.Case`). A vector set is
the concatenation, along the frame (or run) axis, of

* ``random``: uniform codes over the whole input range, 10 % of them corner codes (most
  negative, most positive, 0, ±1; :func:`chiptwin.dsp.stress.random_codes`);
* ``ties``: random codes whose low bits are then chosen so that the value reaching the output
  rounding lies exactly half-way between two output codes; the signs come out mixed, so ties
  of both signs are covered (solved modulo ``2^SH`` with the 2-adic inverse of the
  coefficient where a coefficient multiplies the free sample; a tie that the formats cannot
  reach, e.g. after an odd reciprocal constant, is left random);
* ``extremes``: runs at full scale, at the most negative code, alternating, the sign pattern
  of the taps (largest ``|acc|``), zeros: saturation and wrap of narrow registers;
* ``near``: (background subtraction) values within ±1.5 output ranges of the dark reference,
  so that narrow outputs round as often as they clip.

Back-pressure is not in the vectors: the testbenches draw bubbles and ``ready`` deassertions
from a seeded stream (``p_valid``, ``p_ready`` of :meth:`rtl_ref.cosim.Bank.run`).
"""

from __future__ import annotations

import numpy as np

from chiptwin.dsp.fixed import Fmt
from chiptwin.dsp.stress import random_codes
from rtl_ref.block import Block, divide_shift
from rtl_ref.filter_blocks import FirBlock, KineticsBlock
from rtl_ref.frame_blocks import AverageBlock, BackgroundBlock, CmsBlock

BACKGROUND_PIXELS = 1024
"""Background subtraction is stateless: many pixels give many distinct dark words per call
(fewer for small vector sets, which keep 8 frames)."""

SHARES = {"ties": 0.25, "extremes": 0.1, "near": 0.2}
MAX_SOLVED = 2000
"""Frames (FIR) or runs (kinetics) whose ties are solved one by one, in Python."""


def set_low(v: np.ndarray, target: np.ndarray | int, bits: int) -> np.ndarray:
    """``v`` with its ``bits`` low bits replaced by ``target mod 2^bits`` (stays in range for
    any two's complement or unsigned format wider than ``bits``)."""
    mask = (1 << bits) - 1
    return (np.asarray(v, np.int64) & ~np.int64(mask)) | (np.asarray(target, np.int64) & mask)


def _split(n: int, shares: dict[str, float]) -> dict[str, slice]:
    out, start = {}, 0
    for name, share in shares.items():
        k = int(n * share)
        out[name] = slice(start, start + k)
        start += k
    out["random"] = slice(start, n)
    return out


def _solve(c: int, need: np.ndarray, sh: int, fmt: Fmt, x: np.ndarray) -> np.ndarray:
    """Where possible, replace ``x`` by a code of ``fmt`` with ``c·x ≡ need (mod 2^sh)``: the low
    ``sh - v`` bits of ``x`` are set (``v`` the 2-adic valuation of ``c``) where ``2^v`` divides
    ``need``; ``x`` is left alone where the congruence has no solution inside ``fmt``."""
    if c == 0 or sh <= 0:
        return x
    a = (c & -c).bit_length() - 1
    k = sh - a
    if k <= 0 or k >= fmt.word_bits:
        return x
    inv = pow((c >> a) % (1 << k), -1, 1 << k)
    need = np.asarray(need, dtype=object)
    ok = (need % (1 << a) == 0).astype(bool)
    res = (((need >> a) * inv) % (1 << k)).astype(np.int64)
    return np.where(ok, set_low(x, res, k), x)


def _extreme_runs(fmt: Fmt, shape: tuple[int, ...], axis_len: int) -> np.ndarray:
    """Runs (along axis 0, ``axis_len`` long) cycling: all max, all min, alternating, zeros."""
    x = np.zeros(shape, dtype=np.int64)
    pattern = (fmt.max_code, fmt.min_code, None, 0)
    for r in range(shape[0]):
        kind = pattern[(r // max(axis_len, 1)) % 4]
        if kind is None:
            x[r] = fmt.max_code if r % 2 else fmt.min_code
        else:
            x[r] = kind
    return x


def background(block: BackgroundBlock, n_beats: int, rng: np.random.Generator) -> dict:
    """Frames ``(F, P ≤ 1024)`` and a dark reference whose pixels include the extreme codes."""
    c = block.cfg
    p = int(np.clip(n_beats // 8, 16, BACKGROUND_PIXELS))
    n_frames = max(-(-n_beats // p), 8)
    frames = random_codes(c.in_fmt, (n_frames, p), rng)
    dark = random_codes(c.dark_fmt, (p,), rng, corner_share=0.2)
    dark[1:6:2] = (c.dark_fmt.min_code, c.dark_fmt.max_code, 0)  # odd pixels keep them
    parts = _split(n_frames, SHARES)
    f = max(c.in_fmt.frac_bits, c.dark_fmt.frac_bits)
    ax, ad, sh = f - c.in_fmt.frac_bits, f - c.dark_fmt.frac_bits, f - c.out_fmt.frac_bits
    ties = frames[parts["ties"]]
    if 0 < sh:
        half = 1 << (sh - 1)
        if ax == 0 and sh < c.in_fmt.word_bits:
            frames[parts["ties"]] = set_low(ties, (dark << ad) + half, sh)
        elif ax > 0 and sh < c.dark_fmt.word_bits:
            tie_px = np.arange(p) % 2 == 0  # half the pixels get a tie-friendly dark word
            k = max(sh - ax, 0)
            cls = rng.integers(0, 1 << k, size=p) if k else np.zeros(p, np.int64)
            dark = np.where(tie_px, set_low(dark, (cls << ax) - half, sh), dark)
            if k:
                frames[parts["ties"]] = np.where(tie_px, set_low(ties, cls, k), ties)
    ext = parts["extremes"]
    frames[ext] = _extreme_runs(c.in_fmt, frames[ext].shape, 1)
    frames[parts["near"]] = _near(c, dark, frames[parts["near"]].shape, rng)
    return {"frames": frames, "dark": dark}


def _near(c, dark: np.ndarray, shape: tuple[int, int], rng: np.random.Generator) -> np.ndarray:
    """Frames whose difference to the dark word lies within ±1.5 output ranges."""
    span = 1.5 * float(c.out_fmt.max_value - c.out_fmt.min_value) / 2
    d = c.dark_fmt.to_float(dark)
    x = d + rng.uniform(-span, span, size=shape)
    codes = np.round(np.ldexp(x, c.in_fmt.frac_bits))
    return np.clip(codes, c.in_fmt.min_code, c.in_fmt.max_code).astype(np.int64)


def average(block: AverageBlock, n_beats: int, rng: np.random.Generator) -> dict:
    """Runs of ``n`` frames; ties set through the last frame of a run (``n`` a power of two)."""
    c, p = block.cfg, block.n_pixels
    runs = max(-(-n_beats // (p * c.n)), 8)
    x = random_codes(c.in_fmt, (runs, c.n, p), rng)
    parts = _split(runs, {"ties": SHARES["ties"], "extremes": SHARES["extremes"]})
    mult, sh = divide_shift(c.in_fmt.frac_bits, c.n, c.recip_word_bits, c.out_fmt)
    t = x[parts["ties"]][:MAX_SOLVED] if mult != 1 else x[parts["ties"]]
    if sh > 0:
        rest = t[:, :-1].sum(axis=1).astype(object) * mult
        t[:, -1] = _solve(mult, (1 << (sh - 1)) - rest, sh, c.in_fmt, t[:, -1])
    e = x[parts["extremes"]]
    x[parts["extremes"]] = _extreme_runs(c.in_fmt, (e.shape[0] * c.n, p), c.n).reshape(e.shape)
    return {"frames": x.reshape(runs * c.n, p)}


def cms(block: CmsBlock, n_beats: int, rng: np.random.Generator) -> dict:
    """Frames of M reset and M signal samples; ties set through the last signal sample."""
    c, p = block.cfg, block.n_pixels
    n_frames = max(-(-n_beats // (p * 2 * c.m)), 8)
    reset = random_codes(c.in_fmt, (n_frames, c.m, p), rng)
    signal = random_codes(c.in_fmt, (n_frames, c.m, p), rng)
    parts = _split(n_frames, {"ties": SHARES["ties"], "extremes": SHARES["extremes"]})
    mult, sh = divide_shift(c.in_fmt.frac_bits, c.m, c.recip_word_bits, c.out_fmt)
    lim = MAX_SOLVED if mult != 1 else None
    s, r = signal[parts["ties"]][:lim], reset[parts["ties"]][:lim]
    if sh > 0:
        rest = (s[:, :-1].sum(axis=1) - r.sum(axis=1)).astype(object) * mult
        s[:, -1] = _solve(mult, (1 << (sh - 1)) - rest, sh, c.in_fmt, s[:, -1])
    ext = parts["extremes"]
    k = ext.stop - ext.start
    hi, lo = c.in_fmt.max_code, c.in_fmt.min_code
    pattern = np.array([(hi, lo), (lo, hi), (hi, hi), (lo, lo)])[np.arange(k) % 4]
    reset[ext] = pattern[:, 0, None, None]
    signal[ext] = pattern[:, 1, None, None]
    return {"reset": reset, "signal": signal}


def fir(block: FirBlock, n_beats: int, rng: np.random.Generator) -> dict:
    """Frames along time; ties solved frame by frame through the newest sample's tap."""
    c, p = block.cfg, block.n_pixels
    n_frames = max(-(-n_beats // p), 4 * c.taps)
    x = random_codes(c.in_fmt, (n_frames, p), rng)
    h = [int(v) for v in c.coef_codes]
    parts = _split(n_frames, {"extremes": SHARES["extremes"], "ties": SHARES["ties"]})
    e0 = parts["extremes"].start
    worst = np.where(np.array(h[::-1]) >= 0, c.in_fmt.max_code, c.in_fmt.min_code)
    seg = [np.full((c.taps, p), c.in_fmt.max_code), worst[:, None] + np.zeros((1, p), np.int64),
           (c.in_fmt.max_code + c.in_fmt.min_code - worst)[:, None] + np.zeros((1, p), np.int64),
           np.full((c.taps, p), c.in_fmt.min_code)]
    ext = np.concatenate(seg * (1 + (parts["extremes"].stop - e0) // (4 * c.taps)))
    x[parts["extremes"]] = ext[: parts["extremes"].stop - e0]
    sh = c.acc_fmt.frac_bits - c.out_fmt.frac_bits
    for t in range(parts["ties"].start, min(parts["ties"].stop, parts["ties"].start + MAX_SOLVED)):
        rest = sum(h[k] * x[t - k].astype(object) for k in range(1, c.taps) if t - k >= 0)
        x[t] = _solve(h[0], (1 << (sh - 1)) - rest, sh, c.in_fmt, x[t]) if sh > 0 else x[t]
    return {"frames": x}


def kinetics(block: KineticsBlock, n_beats: int, rng: np.random.Generator) -> dict:
    """Runs of N frames; ties solved through the last frame's weight where the formats allow."""
    c, p = block.cfg, block.n_pixels
    n = len(c.t_s)
    runs = max(-(-n_beats // (p * n)), 8)
    x = random_codes(c.in_fmt, (runs, n, p), rng)
    parts = _split(runs, {"ties": SHARES["ties"], "extremes": SHARES["extremes"]})
    w = [int(v) for v in c.weight_codes]
    sh = c.acc_fmt.frac_bits + c.norm_fmt.frac_bits - c.out_fmt.frac_bits
    for r in range(parts["ties"].start, min(parts["ties"].stop, parts["ties"].start + MAX_SOLVED)):
        rest = sum(w[j] * x[r, j].astype(object) for j in range(n - 1)) * c.norm_code
        x[r, -1] = _solve(w[-1] * c.norm_code, (1 << (sh - 1)) - rest, sh, c.in_fmt, x[r, -1])
    e = x[parts["extremes"]]
    x[parts["extremes"]] = _extreme_runs(c.in_fmt, (e.shape[0] * n, p), n).reshape(e.shape)
    return {"frames": x}


def for_block(block: Block, n_beats: int, rng: np.random.Generator) -> dict:
    """About ``n_beats`` input beats (at least a few runs) for ``block``."""
    makers = {BackgroundBlock: background, AverageBlock: average, CmsBlock: cms, FirBlock: fir,
              KineticsBlock: kinetics}
    for cls, make in makers.items():
        if isinstance(block, cls):
            return make(block, n_beats, rng)
    raise TypeError(f"no vector generator for {type(block).__name__}")
