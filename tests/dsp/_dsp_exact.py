"""Slow, obvious references for the fixed-point DSP: Python integers and ``fractions.Fraction``.

Written independently of ``chiptwin.dsp.fixed`` (no shared helper) from the definitions in
docs/background/sources.md F1–F4, so that a test comparing the two compares two implementations, not
one with itself. Every routine here works one value at a time; use small arrays.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np

from chiptwin.dsp.fixed import Fmt


def exact_round(v: Fraction, mode: str) -> int:
    """Round an exact rational by the definition of each mode."""
    down, up = math.floor(v), math.ceil(v)
    if down == up:
        return down
    if mode == "TRN":
        return down
    if mode == "TRN_ZERO":
        return down if v > 0 else up
    d_down, d_up = v - down, up - v
    if d_down != d_up:
        return down if d_down < d_up else up
    return {
        "RND": up,
        "RND_ZERO": down if v > 0 else up,
        "RND_INF": up if v > 0 else down,
        "RND_CONV": down if down % 2 == 0 else up,
    }[mode]


def exact_fit(q: int, fmt: Fmt, mode: str) -> tuple[int, int, int]:
    """Overflow handling of an exact integer: (code, sat, wrap)."""
    if fmt.signed:
        lo, hi = -(2 ** (fmt.word_bits - 1)), 2 ** (fmt.word_bits - 1) - 1
    else:
        lo, hi = 0, 2**fmt.word_bits - 1
    if mode == "SAT_SYM" and fmt.signed:
        lo_allowed = -hi
    else:
        lo_allowed = lo
    if lo_allowed <= q <= hi:
        return q, 0, 0
    if mode == "WRAP":
        return (q - lo) % 2**fmt.word_bits + lo, 0, 1
    return (hi if q > hi else lo_allowed), 1, 0


def value(code: int, fmt: Fmt) -> Fraction:
    """Exact value of a code."""
    return Fraction(int(code)) * Fraction(2) ** -fmt.frac_bits


def exact_quantize(x: float, fmt: Fmt, rnd: str, ovf: str) -> tuple[int, int, int]:
    """Quantize one float exactly."""
    return exact_fit(exact_round(Fraction(x) * Fraction(2) ** fmt.frac_bits, rnd), fmt, ovf)


def exact_requantize(code: int, src: Fmt, dst: Fmt, rnd: str, ovf: str) -> tuple[int, int, int]:
    """Requantize one code exactly."""
    return exact_fit(exact_round(value(code, src) * Fraction(2) ** dst.frac_bits, rnd), dst, ovf)


def to_code(v: Fraction, fmt: Fmt) -> int:
    """The code of an exactly representable value."""
    c = v * Fraction(2) ** fmt.frac_bits
    assert c.denominator == 1, (v, fmt)
    return int(c)


# ------------------------------------------------------------------------------------------
# naive routines: value by value, registers applied by their definitions
# ------------------------------------------------------------------------------------------


class Tally:
    """Counts per register."""

    def __init__(self) -> None:
        self.counts: dict[str, dict[str, int]] = {}

    def fit(self, register: str, q: int, fmt: Fmt, mode: str) -> int:
        code, sat, wrap = exact_fit(q, fmt, mode)
        entry = self.counts.setdefault(register, {"sat": 0, "wrap": 0})
        entry["sat"] += sat
        entry["wrap"] += wrap
        return code

    def get(self, register: str) -> dict[str, int]:
        return self.counts.get(register, {"sat": 0, "wrap": 0})


def out_code(v: Fraction, fmt: Fmt, rnd: str, ovf: str, tally: Tally) -> int:
    """Round the exact value ``v`` into ``fmt`` (the output register)."""
    return tally.fit("output", exact_round(v * Fraction(2) ** fmt.frac_bits, rnd), fmt, ovf)


def acc_sequence(terms: list[Fraction], acc: Fmt, ovf: str, tally: Tally, name: str) -> Fraction:
    """A hardware accumulator: reset to 0, add each exact term, fit every partial sum."""
    code = 0
    for t in terms:
        code = tally.fit(name, code + to_code(t, acc), acc, ovf)
    return value(code, acc)


def divide_exact(v: Fraction, n: int, recip_word_bits: int) -> Fraction:
    """The divide step's exact value: ``v / n`` (power of two) or ``v · round_even(1/n)``."""
    if n & (n - 1) == 0:
        return v / n
    frac = recip_word_bits + n.bit_length() - 1
    r = exact_round(Fraction(2**frac, n), "RND_CONV")
    return v * Fraction(r, 2**frac)


def naive_background(frames, dark, cfg, tally: Tally) -> np.ndarray:
    frames, dark = np.asarray(frames), np.asarray(dark)
    out = np.empty(frames.shape, dtype=np.int64)
    for idx in np.ndindex(frames.shape):
        v = value(frames[idx], cfg.in_fmt) - value(dark[idx[-1]], cfg.dark_fmt)
        out[idx] = out_code(v, cfg.out_fmt, cfg.rounding, cfg.overflow, tally)
    return out


def naive_cms(reset, signal, cfg, tally: Tally) -> np.ndarray:
    reset, signal = np.asarray(reset), np.asarray(signal)
    lead = reset.shape[:-2] + reset.shape[-1:]
    out = np.empty(lead, dtype=np.int64)
    for idx in np.ndindex(lead):
        pre, p = idx[:-1], idx[-1]
        sums = {}
        for name, x in (("sum_reset", reset), ("sum_signal", signal)):
            terms = [value(x[pre + (j, p)], cfg.in_fmt) for j in range(cfg.m)]
            sums[name] = acc_sequence(terms, cfg.acc_fmt, cfg.acc_overflow, tally, name)
        v = divide_exact(sums["sum_signal"] - sums["sum_reset"], cfg.m, cfg.recip_word_bits)
        out[idx] = out_code(v, cfg.out_fmt, cfg.rounding, cfg.overflow, tally)
    return out


def naive_average(frames, cfg, tally: Tally, divide: bool = True) -> np.ndarray:
    frames = np.asarray(frames)
    nb = frames.shape[0] // cfg.n
    out = np.empty((nb,) + frames.shape[1:], dtype=np.int64)
    for idx in np.ndindex(out.shape):
        b, rest = idx[0], idx[1:]
        terms = [value(frames[(b * cfg.n + j,) + rest], cfg.in_fmt) for j in range(cfg.n)]
        s = acc_sequence(terms, cfg.acc_fmt, cfg.acc_overflow, tally, "acc")
        if not divide:
            out[idx] = to_code(s, cfg.acc_fmt)
            continue
        v = divide_exact(s, cfg.n, cfg.recip_word_bits)
        out[idx] = out_code(v, cfg.out_fmt, cfg.rounding, cfg.overflow, tally)
    return out


def naive_binning(frames, cfg, tally: Tally) -> np.ndarray:
    frames = np.asarray(frames)
    lead = frames.shape[:-1]
    n_out = cfg.rows // cfg.factor * cfg.cols
    out = np.empty(lead + (n_out,), dtype=np.int64)
    for idx in np.ndindex(out.shape):
        pre, o = idx[:-1], idx[-1]
        r0, c = (o // cfg.cols) * cfg.factor, o % cfg.cols
        v = sum(
            value(frames[pre + ((r0 + i) * cfg.cols + c,)], cfg.in_fmt) for i in range(cfg.factor)
        )
        out[idx] = out_code(v, cfg.out_fmt, cfg.rounding, cfg.overflow, tally)
    return out


def naive_kinetics(frames, cfg, tally: Tally) -> np.ndarray:
    frames = np.asarray(frames)
    n = len(cfg.t_s)
    lead = frames.shape[:-2] + frames.shape[-1:]
    w = [value(c, cfg.coef_fmt) for c in cfg.weight_codes]
    g = value(cfg.norm_code, cfg.norm_fmt)
    out = np.empty(lead, dtype=np.int64)
    for idx in np.ndindex(lead):
        pre, p = idx[:-1], idx[-1]
        terms = [value(frames[pre + (j, p)], cfg.in_fmt) * w[j] for j in range(n)]
        s = acc_sequence(terms, cfg.acc_fmt, cfg.acc_overflow, tally, "acc")
        out[idx] = out_code(s * g, cfg.out_fmt, cfg.rounding, cfg.overflow, tally)
    return out


def naive_fir(frames, cfg, tally: Tally) -> np.ndarray:
    frames = np.asarray(frames)
    h = [value(c, cfg.coef_fmt) for c in cfg.coef_codes]
    out = np.empty(frames.shape, dtype=np.int64)
    for idx in np.ndindex(frames.shape):
        t, rest = idx[0], idx[1:]
        terms = [h[k] * value(frames[(t - k,) + rest], cfg.in_fmt) for k in range(len(h)) if t >= k]
        s = acc_sequence(terms, cfg.acc_fmt, cfg.acc_overflow, tally, "acc")
        out[idx] = out_code(s, cfg.out_fmt, cfg.rounding, cfg.overflow, tally)
    return out


def naive_wiener(frames, eq, tally: Tally) -> np.ndarray:
    frames = np.asarray(frames)
    cfg = eq.cfg
    lead = frames.shape[:-1]
    out = np.empty(lead + (eq.n_sites,), dtype=np.int64)
    for idx in np.ndindex(out.shape):
        pre, s = idx[:-1], idx[-1]
        terms = [
            value(eq.coef_codes[s, p], eq.coef_fmt) * value(frames[pre + (p,)], cfg.in_fmt)
            for p in range(eq.n_pixels)
        ]
        acc = acc_sequence(terms, eq.acc_fmt, cfg.acc_overflow, tally, "acc")
        out[idx] = out_code(acc, eq.out_fmt, cfg.rounding, cfg.overflow, tally)
    return out
