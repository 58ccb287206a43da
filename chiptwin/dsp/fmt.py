"""Fixed-point formats and their algebra: modes, :class:`Fmt`, word growth, exact rationals.

A value is an ``int64`` *code* ``c`` in a format :class:`Fmt` ``(signed, word_bits, frac_bits)``;
it stands for ``c · 2^-frac_bits``. Semantics follow the fixed-point conventions
(names as in SystemC / HLS ``ap_fixed`` / APyTypes; docs/background/sources.md F1–F3):

rounding (applied first)
    ``TRN`` floor · ``TRN_ZERO`` toward zero · ``RND`` nearest, ties → +∞ · ``RND_ZERO`` nearest,
    ties → 0 · ``RND_INF`` nearest, ties away from 0 · ``RND_CONV`` nearest, ties to even.
overflow (applied to the rounded, exact integer)
    ``WRAP`` two's complement modulo ``2^W`` · ``SAT`` clamp to ``[min_code, max_code]`` ·
    ``SAT_SYM`` clamp to ``[-max_code, max_code]`` for signed formats: the most negative code is
    never produced (a result equal to it becomes ``-max_code`` and counts as a saturation);
    for unsigned formats ``SAT_SYM`` is ``SAT``.

Word growth (full precision, never overflows): add/sub → ``max(I) + 1`` integer bits and
``max(F)`` fractional bits; multiply → ``I1 + I2``, ``F1 + F2``; sum of n → ``+⌈log2 n⌉``.
``I = word_bits - frac_bits`` counts the sign bit. When signedness differs, the unsigned operand
first becomes signed with one more integer bit (lossless); a difference is always signed.
Codes are ``int64``: signed words up to 64 bits, unsigned up to 63.

The array operations are in :mod:`chiptwin.dsp.fixed`; the pure-Python exact helpers here
(:func:`round_fraction`, :func:`fit_int`, :func:`quantize_fraction`) serve coefficient design.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction
from typing import Literal

import numpy as np

Rounding = Literal["TRN", "TRN_ZERO", "RND", "RND_ZERO", "RND_INF", "RND_CONV"]
Overflow = Literal["WRAP", "SAT", "SAT_SYM"]

ROUNDING_MODES: tuple[str, ...] = ("TRN", "TRN_ZERO", "RND", "RND_ZERO", "RND_INF", "RND_CONV")
"""Rounding modes, in the order of their kernel codes."""

OVERFLOW_MODES: tuple[str, ...] = ("WRAP", "SAT", "SAT_SYM")
"""Overflow modes, in the order of their kernel codes."""

NEAREST_MODES: frozenset[str] = frozenset({"RND", "RND_ZERO", "RND_INF", "RND_CONV"})
"""Round-to-nearest modes: error ≤ 0.5 LSB. The others (TRN, TRN_ZERO) err by < 1 LSB."""

MAX_FRAC_BITS = 4096
"""Largest ``|frac_bits|`` accepted: more than any float64 needs (2^-1074 … 2^1024)."""


@dataclass(frozen=True)
class Fmt:
    """A fixed-point format: ``word_bits`` bits, the lowest ``frac_bits`` of them fractional.

    Parameters
    ----------
    signed : bool
        Two's complement when true, plain binary when false.
    word_bits : int
        1…64 for signed, 1…63 for unsigned (every code must be an ``int64``).
    frac_bits : int
        Fractional bits; may be negative (LSB above 1) or exceed ``word_bits``.
    """

    signed: bool
    word_bits: int
    frac_bits: int

    def __post_init__(self) -> None:
        if not isinstance(self.signed, bool):
            raise TypeError(f"Fmt.signed = {self.signed!r}: must be true or false")
        for name in ("word_bits", "frac_bits"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | np.integer):
                raise TypeError(f"Fmt.{name} = {value!r}: must be an integer")
            object.__setattr__(self, name, int(value))
        top = 64 if self.signed else 63
        if not 1 <= self.word_bits <= top:
            kind = "signed" if self.signed else "unsigned"
            raise ValueError(
                f"Fmt.word_bits = {self.word_bits}: a {kind} format takes 1…{top} bits "
                "(codes are int64); wider words are refused"
            )
        if abs(self.frac_bits) > MAX_FRAC_BITS:
            raise ValueError(f"Fmt.frac_bits = {self.frac_bits}: allowed ±{MAX_FRAC_BITS}")

    @property
    def int_bits(self) -> int:
        """Integer bits ``I = W - F``, the sign bit included."""
        return self.word_bits - self.frac_bits

    @property
    def q(self) -> str:
        """Display string ``Qm.n`` (``UQm.n`` unsigned), m counting the sign bit."""
        return f"{'' if self.signed else 'U'}Q{self.int_bits}.{self.frac_bits}"

    @property
    def min_code(self) -> int:
        """Smallest code: ``-2^(W-1)`` signed, 0 unsigned."""
        return -(1 << (self.word_bits - 1)) if self.signed else 0

    @property
    def max_code(self) -> int:
        """Largest code: ``2^(W-1) - 1`` signed, ``2^W - 1`` unsigned."""
        return (1 << (self.word_bits - (1 if self.signed else 0))) - 1

    @property
    def lsb(self) -> float:
        """Value of one code step, ``2^-F`` (exact in float64 for ``|F| ≤ 1022``)."""
        return math.ldexp(1.0, -self.frac_bits)

    @property
    def min_value(self) -> Fraction:
        """Most negative value, exact."""
        return Fraction(self.min_code) * Fraction(2) ** -self.frac_bits

    @property
    def max_value(self) -> Fraction:
        """Most positive value, exact."""
        return Fraction(self.max_code) * Fraction(2) ** -self.frac_bits

    @property
    def spec(self) -> np.ndarray:
        """Kernel register description ``int64[4] = (lo, hi, 64 - W, signed)``."""
        return np.array(
            [self.min_code, self.max_code, 64 - self.word_bits, int(self.signed)], dtype=np.int64
        )

    def to_float(self, codes: np.ndarray) -> np.ndarray:
        """Values of ``codes`` as float64 (exact when ``W ≤ 53`` and the exponent fits)."""
        return np.ldexp(np.asarray(codes, dtype=np.float64), -self.frac_bits)

    def describe(self) -> str:
        """``'Q15.2 (signed, 16 b, 2 frac)'``: the display string with the raw parameters."""
        kind = "signed" if self.signed else "unsigned"
        return f"{self.q} ({kind}, {self.word_bits} b, {self.frac_bits} frac)"

    def __str__(self) -> str:
        return self.q


@dataclass
class OverflowCounter:
    """Running count of overflow events, passed in by the caller (a probe, not a global)."""

    sat: int = 0
    wrap: int = 0

    def add(self, sat: int, wrap: int) -> None:
        """Add ``sat`` saturations and ``wrap`` wraps."""
        self.sat += int(sat)
        self.wrap += int(wrap)

    def as_dict(self) -> dict[str, int]:
        """``{"sat": n, "wrap": n}``."""
        return {"sat": self.sat, "wrap": self.wrap}


def rounding_code(rounding: str) -> int:
    """Kernel code of a rounding mode; refuses unknown names."""
    if rounding not in ROUNDING_MODES:
        raise ValueError(f"rounding = {rounding!r}: allowed {', '.join(ROUNDING_MODES)}")
    return ROUNDING_MODES.index(rounding)


def overflow_code(overflow: str) -> int:
    """Kernel code of an overflow mode; refuses unknown names."""
    if overflow not in OVERFLOW_MODES:
        raise ValueError(f"overflow = {overflow!r}: allowed {', '.join(OVERFLOW_MODES)}")
    return OVERFLOW_MODES.index(overflow)


# ---------------------------------------------------------------------------------------------
# exact rationals (pure Python)
# ---------------------------------------------------------------------------------------------


def quantize_fraction(
    value: Fraction | int,
    fmt: Fmt,
    rounding: Rounding = "RND_CONV",
    overflow: Overflow = "SAT",
    counter: OverflowCounter | None = None,
) -> int:
    """One exact rational to a code (pure Python; for coefficients such as ``1/n``)."""
    scaled = Fraction(value) * Fraction(2) ** fmt.frac_bits
    q = round_fraction(scaled, rounding)
    code, sat, wrap = fit_int(q, fmt, overflow)
    if counter is not None:
        counter.add(sat, wrap)
    return code


def round_fraction(v: Fraction, rounding: str) -> int:
    """Round an exact rational to an integer with a named mode (pure Python)."""
    q = v.numerator // v.denominator
    r = v - q
    rounding_code(rounding)
    if r == 0 or rounding == "TRN":
        return q
    if rounding == "TRN_ZERO":
        return q + 1 if v < 0 else q
    half = Fraction(1, 2)
    if r != half:
        return q + 1 if r > half else q
    tie_up = {"RND": True, "RND_ZERO": v < 0, "RND_INF": v > 0, "RND_CONV": q % 2 == 1}
    return q + 1 if tie_up[rounding] else q


def fit_int(q: int, fmt: Fmt, overflow: str) -> tuple[int, int, int]:
    """Put an exact Python integer into ``fmt``: ``(code, n_sat, n_wrap)`` (pure Python)."""
    overflow_code(overflow)
    lo, hi = fmt.min_code, fmt.max_code
    sym = overflow == "SAT_SYM" and fmt.signed
    if lo <= q <= hi:
        return (-hi, 1, 0) if sym and q == lo else (q, 0, 0)
    if overflow == "WRAP":
        m = q % (1 << fmt.word_bits)
        return (m - (1 << fmt.word_bits) if fmt.signed and m > hi else m), 0, 1
    if q > hi:
        return hi, 1, 0
    return (-hi if sym else lo), 1, 0


# ---------------------------------------------------------------------------------------------
# word growth
# ---------------------------------------------------------------------------------------------


def _widen_unsigned(fmt: Fmt, to_signed: bool) -> tuple[int, int]:
    """(integer bits, frac bits) of ``fmt`` as an operand of a signed result."""
    extra = 1 if to_signed and not fmt.signed else 0
    return fmt.int_bits + extra, fmt.frac_bits


def _checked_fmt(signed: bool, int_bits: int, frac_bits: int, what: str) -> Fmt:
    word = int_bits + frac_bits
    top = 64 if signed else 63
    if word > top:
        raise ValueError(
            f"{what}: the full-precision result needs {word} bits "
            f"({'signed' if signed else 'unsigned'}; at most {top}); requantize the operands first"
        )
    return Fmt(signed, max(word, 1), frac_bits)


def add_fmt(fa: Fmt, fb: Fmt, subtract: bool = False) -> Fmt:
    """Result format of a full-precision add (or subtract): ``max(I) + 1``, ``max(F)``."""
    signed = fa.signed or fb.signed or subtract
    ia, fra = _widen_unsigned(fa, signed)
    ib, frb = _widen_unsigned(fb, signed)
    frac = max(fra, frb)
    return _checked_fmt(signed, max(ia, ib) + 1, frac, "sub" if subtract else "add")


def mul_fmt(fa: Fmt, fb: Fmt) -> Fmt:
    """Result format of a full-precision multiply: ``I1 + I2``, ``F1 + F2``."""
    signed = fa.signed or fb.signed
    return _checked_fmt(signed, fa.int_bits + fb.int_bits, fa.frac_bits + fb.frac_bits, "mul")


def sum_fmt(fmt: Fmt, n: int) -> Fmt:
    """Result format of a full-precision sum of ``n`` values: ``+⌈log2 n⌉`` integer bits."""
    if n < 1:
        raise ValueError(f"sum of n = {n} values: n must be ≥ 1")
    grow = (n - 1).bit_length()
    return _checked_fmt(fmt.signed, fmt.int_bits + grow, fmt.frac_bits, f"sum of {n}")


def accumulator_bits_needed(in_fmt: Fmt, n_frames: int) -> int:
    """Smallest accumulator word (same signedness) that holds any sum of ``n_frames`` inputs.

    Every partial sum then fits too, so no wrap or saturation can occur. This is the exact
    minimum; the word-growth rule ``W + ⌈log2 n⌉`` is never smaller and exceeds it by one bit
    only for a few tiny unsigned words.

    Parameters
    ----------
    in_fmt : Fmt
        Format of one input (one frame's codes).
    n_frames : int
        Number of inputs summed, ≥ 1.

    Returns
    -------
    int
        Bits; may exceed 64 (then no accumulator of this library can hold the sum).
    """
    if n_frames < 1:
        raise ValueError(f"accumulator_bits_needed: n_frames = {n_frames}: must be ≥ 1")
    lo, hi = n_frames * in_fmt.min_code, n_frames * in_fmt.max_code
    if in_fmt.signed:
        return max(hi.bit_length(), (-lo - 1).bit_length()) + 1
    return max(hi.bit_length(), 1)


def fmt_for_range(max_abs: float | Fraction, word_bits: int, signed: bool = True) -> Fmt:
    """The format of ``word_bits`` bits with the most fractional bits that still holds ``±max_abs``.

    Used to pick coefficient formats (Wiener matrix, normalisation gain): ``max_abs`` rounded to
    nearest must not exceed ``max_code``.
    """
    target = abs(Fraction(max_abs))
    if target == 0:
        return Fmt(signed, word_bits, word_bits - (1 if signed else 0))
    frac = word_bits - (1 if signed else 0) - math.floor(math.log2(target))  # one too many
    while True:
        fmt = Fmt(signed, word_bits, frac)
        if round_fraction(target * Fraction(2) ** frac, "RND_INF") <= fmt.max_code:
            return fmt
        frac -= 1
