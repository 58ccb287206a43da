"""The DSP routines written with APyTypes 0.5.1: an independent bit-exact oracle.

Used as the fixed-point conventions require (sources.md F5): floats are converted with enough
fractional bits to be exact (``from_float`` rounds ties away and wraps, so it must never round) and
only then ``cast`` with the mode under test. APyTypes has no unsigned type: unsigned codes enter as
signed words one bit wider (the same values), and every register *cast* here is signed. APyTypes has
no SAT_SYM; that mode is checked against the Fraction reference instead.

APyTypes 0.5.1 defect found here: casting a *64-bit* source whose rounding carries past the top
(e.g. code 2^63 − 1 with 40 fractional bits, RND, SAT, to 24 bits) returns the most negative code
instead of saturating; 63- and 65-bit sources are right. :func:`cast` therefore first widens a
64-bit array to 65 bits (exact) before the cast under test.
"""

from __future__ import annotations

from fractions import Fraction

import apytypes as apy
import numpy as np

from chiptwin.dsp.fixed import Fmt
from tests.dsp._dsp_exact import exact_round

assert apy.__version__ == "0.5.1", apy.__version__

QMODE = {
    "TRN": apy.QuantizationMode.TRN,
    "TRN_ZERO": apy.QuantizationMode.TRN_ZERO,
    "RND": apy.QuantizationMode.RND,
    "RND_ZERO": apy.QuantizationMode.RND_ZERO,
    "RND_INF": apy.QuantizationMode.RND_INF,
    "RND_CONV": apy.QuantizationMode.RND_CONV,
}
OMODE = {"WRAP": apy.OverflowMode.WRAP, "SAT": apy.OverflowMode.SAT}


def from_codes(codes, fmt: Fmt) -> apy.APyFixedArray:
    """Codes of ``fmt`` as an APyTypes array of the same values (unsigned: one bit wider)."""
    int_bits = fmt.int_bits + (0 if fmt.signed else 1)
    return apy.APyFixedArray(
        np.array(codes, dtype=np.int64, order="C"), int_bits=int_bits, frac_bits=fmt.frac_bits
    )


def scalar(code: int, fmt: Fmt) -> apy.APyFixedArray:
    """One coefficient as a 1-element array (broadcasts over the last axis)."""
    return from_codes(np.array([code]), fmt)


def to_codes(a: apy.APyFixedArray, fmt: Fmt) -> np.ndarray:
    """The int64 codes of a signed APyTypes array of format ``fmt`` (sign-extended)."""
    assert fmt.signed and a.bits == fmt.word_bits and a.frac_bits == fmt.frac_bits
    bits = np.asarray(a.to_bits(numpy=True)).astype(np.uint64)
    if fmt.word_bits == 64:
        return bits.view(np.int64)
    v = bits.astype(np.int64)
    return np.where(v >= 1 << (fmt.word_bits - 1), v - (1 << fmt.word_bits), v)


def cast(a: apy.APyFixedArray, fmt: Fmt, rnd: str, ovf: str) -> apy.APyFixedArray:
    """The one place this oracle rounds and overflows: ``APyFixedArray.cast``."""
    assert fmt.signed, "APyTypes has no unsigned type: cast only to signed registers"
    if a.bits == 64:  # work around the 0.5.1 carry defect (module docstring); exact
        a = a.cast(int_bits=a.int_bits + 1, frac_bits=a.frac_bits)
    return a.cast(
        int_bits=fmt.int_bits, frac_bits=fmt.frac_bits, quantization=QMODE[rnd], overflow=OMODE[ovf]
    )


def exact(x: np.ndarray, fmt: Fmt) -> apy.APyFixedArray:
    """Float64 values as an APyTypes array with enough bits that ``from_float`` never rounds."""
    x = np.asarray(x, dtype=np.float64)
    _, ex = np.frexp(x[x != 0])
    frac = max(fmt.frac_bits, int((53 - ex).max()) if ex.size else 0)
    int_bits = max(fmt.int_bits, int(ex.max()) + 1 if ex.size else 1) + 1
    return apy.APyFixedArray.from_float(x, int_bits=int_bits, frac_bits=frac)


def quantize(x, fmt: Fmt, rnd: str, ovf: str, exact_x=None) -> np.ndarray:
    """Float64 → codes: exact conversion, then ``cast`` (pass ``exact_x`` to reuse it)."""
    exact_x = exact(x, fmt) if exact_x is None else exact_x
    return to_codes(cast(exact_x, fmt, rnd, ovf), fmt)


def requantize(codes, src: Fmt, dst: Fmt, rnd: str, ovf: str) -> np.ndarray:
    return to_codes(cast(from_codes(codes, src), dst, rnd, ovf), dst)


def accumulate(terms, acc: Fmt, ovf: str, shape) -> apy.APyFixedArray:
    """A hardware accumulator: zero, then ``acc = cast(acc + term)`` for each term in order."""
    signed_acc = acc if acc.signed else Fmt(True, acc.word_bits + 1, acc.frac_bits)
    total = apy.zeros(shape, int_bits=signed_acc.int_bits, frac_bits=signed_acc.frac_bits)
    for t in terms:
        total = cast(total + t, signed_acc, "TRN", ovf)
    return total


def divide(v: apy.APyFixedArray, n: int, recip_word_bits: int) -> apy.APyFixedArray:
    """The divide step: binary-point shift for a power of two, else times round_even(1/n)."""
    if n & (n - 1) == 0:
        return v >> (n.bit_length() - 1)
    frac = recip_word_bits + n.bit_length() - 1
    code = exact_round(Fraction(2**frac, n), "RND_CONV")
    return v * scalar(code, Fmt(False, recip_word_bits, frac))


def background(frames, dark, cfg) -> np.ndarray:
    diff = from_codes(frames, cfg.in_fmt) - from_codes(dark, cfg.dark_fmt)
    return to_codes(cast(diff, cfg.out_fmt, cfg.rounding, cfg.overflow), cfg.out_fmt)


def cms(reset, signal, cfg) -> np.ndarray:
    shape = reset.shape[:-2] + reset.shape[-1:]
    sums = [
        accumulate(
            (from_codes(x[..., j, :], cfg.in_fmt) for j in range(cfg.m)),
            cfg.acc_fmt,
            cfg.acc_overflow,
            shape,
        )
        for x in (reset, signal)
    ]
    v = divide(sums[1] - sums[0], cfg.m, cfg.recip_word_bits)
    return to_codes(cast(v, cfg.out_fmt, cfg.rounding, cfg.overflow), cfg.out_fmt)


def _runs_sum(frames, cfg):
    runs = np.asarray(frames).reshape(frames.shape[0] // cfg.n, cfg.n, -1)
    terms = (from_codes(runs[:, j, :], cfg.in_fmt) for j in range(cfg.n))
    return accumulate(terms, cfg.acc_fmt, cfg.acc_overflow, (runs.shape[0], runs.shape[2]))


def accumulate_frames(frames, cfg) -> np.ndarray:
    total = _runs_sum(frames, cfg)
    return to_codes(total, total_fmt(total)).reshape((-1,) + frames.shape[1:])


def total_fmt(a: apy.APyFixedArray) -> Fmt:
    return Fmt(True, a.bits, a.frac_bits)


def average(frames, cfg) -> np.ndarray:
    v = divide(_runs_sum(frames, cfg), cfg.n, cfg.recip_word_bits)
    out = to_codes(cast(v, cfg.out_fmt, cfg.rounding, cfg.overflow), cfg.out_fmt)
    return out.reshape((-1,) + frames.shape[1:])


def binning(frames, cfg) -> np.ndarray:
    lead = frames.shape[:-1]
    grouped = frames.reshape(*lead, cfg.rows // cfg.factor, cfg.factor, cfg.cols)
    total = from_codes(grouped[..., 0, :], cfg.in_fmt)
    for i in range(1, cfg.factor):
        total = total + from_codes(grouped[..., i, :], cfg.in_fmt)
    out = to_codes(cast(total, cfg.out_fmt, cfg.rounding, cfg.overflow), cfg.out_fmt)
    return out.reshape(*lead, -1)


def kinetics(frames, cfg) -> np.ndarray:
    shape = frames.shape[:-2] + frames.shape[-1:]
    terms = (
        from_codes(frames[..., j, :], cfg.in_fmt) * scalar(cfg.weight_codes[j], cfg.coef_fmt)
        for j in range(len(cfg.t_s))
    )
    total = accumulate(terms, cfg.acc_fmt, cfg.acc_overflow, shape)
    v = total * scalar(cfg.norm_code, cfg.norm_fmt)
    return to_codes(cast(v, cfg.out_fmt, cfg.rounding, cfg.overflow), cfg.out_fmt)


def fir(frames, cfg) -> np.ndarray:
    def delayed(k: int) -> apy.APyFixedArray:
        xk = np.zeros_like(frames)
        xk[k:] = frames[: frames.shape[0] - k]
        return from_codes(xk, cfg.in_fmt) * scalar(cfg.coef_codes[k], cfg.coef_fmt)

    total = accumulate(
        (delayed(k) for k in range(cfg.taps)), cfg.acc_fmt, cfg.acc_overflow, frames.shape
    )
    return to_codes(cast(total, cfg.out_fmt, cfg.rounding, cfg.overflow), cfg.out_fmt)


def wiener(frames, eq, sequential: bool) -> np.ndarray:
    """``sequential``: pixel by pixel through the accumulator (any overflow mode); else one
    full-precision matmul cast once into the accumulator (equal when the accumulator wraps or
    cannot overflow: two's complement sums are exact modulo 2^W)."""
    cfg = eq.cfg
    x = from_codes(frames, cfg.in_fmt)
    g = from_codes(eq.coef_codes, eq.coef_fmt)
    if sequential:
        terms = (
            from_codes(frames[:, p : p + 1], cfg.in_fmt)
            * from_codes(eq.coef_codes[:, p], eq.coef_fmt)
            for p in range(eq.n_pixels)
        )
        total = accumulate(terms, eq.acc_fmt, cfg.acc_overflow, (frames.shape[0], eq.n_sites))
    else:
        assert cfg.acc_overflow == "WRAP"
        total = cast(x @ g.T, eq.acc_fmt, "TRN", "WRAP")
    return to_codes(cast(total, eq.out_fmt, cfg.rounding, cfg.overflow), eq.out_fmt)
