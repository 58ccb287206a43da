"""What the bit-accurate routines share: result object, overflow log, mode checks, divide step.

A routine declares a format for every register on its data path (``cfg.registers()``) and reports,
per register, how many values saturated or wrapped there (``FixedResult.overflow``). Registers
that are full precision by construction are listed too, with zero counts, so that the table an RTL
engineer reads is complete.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from fractions import Fraction

import numpy as np

from chiptwin.dsp.fixed import (
    NEAREST_MODES,
    Fmt,
    OverflowCounter,
    _mul,
    _requantize,
    mul_fmt,
    overflow_code,
    quantize_fraction,
    rounding_code,
)


@dataclass(frozen=True)
class FixedResult:
    """Output of a bit-accurate routine.

    Attributes
    ----------
    codes : ndarray of int64
        Output codes (shape documented by each routine).
    fmt : Fmt
        Output register format; values are ``codes · 2^-fmt.frac_bits``.
    overflow : dict
        ``register name -> {"sat": n, "wrap": n}``, in data-path order.
    """

    codes: np.ndarray
    fmt: Fmt
    overflow: dict[str, dict[str, int]] = field(default_factory=dict)

    def values(self) -> np.ndarray:
        """Output values as float64 (same unit as the routine's input, e.g. LSB of the ADC)."""
        return self.fmt.to_float(self.codes)

    def total(self) -> dict[str, int]:
        """Overflow events summed over all registers: ``{"sat": n, "wrap": n}``."""
        return {kind: sum(reg[kind] for reg in self.overflow.values()) for kind in ("sat", "wrap")}


class OverflowLog:
    """One :class:`OverflowCounter` per register, created in data-path order."""

    def __init__(self, *registers: str) -> None:
        self._counters: dict[str, OverflowCounter] = {r: OverflowCounter() for r in registers}

    def __getitem__(self, register: str) -> OverflowCounter:
        if register not in self._counters:
            self._counters[register] = OverflowCounter()
        return self._counters[register]

    def as_dict(self) -> dict[str, dict[str, int]]:
        """``register -> {"sat": n, "wrap": n}``."""
        return {name: c.as_dict() for name, c in self._counters.items()}


def check_modes(owner: str, **modes: str) -> None:
    """Refuse unknown rounding / overflow names in a config (``rounding=…``, ``*overflow=…``)."""
    for key, value in modes.items():
        try:
            (rounding_code if "rounding" in key else overflow_code)(value)
        except ValueError as err:
            raise ValueError(f"{owner}.{key}: {err}") from None


@contextmanager
def errors_named(owner: str) -> Iterator[None]:
    """Prefix a ``ValueError`` raised while deriving a config's registers with the config's name."""
    try:
        yield
    except ValueError as err:
        raise ValueError(f"{owner}: {err}") from None


def check_positive(owner: str, **values: int) -> None:
    """Refuse non-integer or < 1 counts in a config."""
    for key, value in values.items():
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise ValueError(f"{owner}.{key} = {value!r}: must be an integer ≥ 1")


def rounding_error_lsb(rounding: str, src: Fmt, dst: Fmt) -> float:
    """Worst-case error of one requantization ``src → dst`` in ``dst`` LSB (no overflow).

    0 when no bit is dropped, 0.5 for the round-to-nearest modes, 1 (exclusive) for TRN and
    TRN_ZERO.
    """
    if dst.frac_bits >= src.frac_bits:
        return 0.0
    return 0.5 if rounding in NEAREST_MODES else 1.0


def is_power_of_two(n: int) -> bool:
    """True for 1, 2, 4, …"""
    return n >= 1 and n & (n - 1) == 0


def reciprocal_fmt(n: int, word_bits: int) -> Fmt:
    """Unsigned register for ``1/n`` (n not a power of two) using all ``word_bits`` bits.

    ``F = word_bits + ⌊log2 n⌋``: then ``1/n < 2^-⌊log2 n⌋`` fits below ``max_code`` and the
    quantization error ``≤ 2^-(F+1)`` is a relative error ``≤ 2^-word_bits``.
    """
    return Fmt(False, word_bits, word_bits + n.bit_length() - 1)


def reciprocal_code(n: int, word_bits: int) -> int:
    """``1/n`` in :func:`reciprocal_fmt`, rounded to nearest even from the exact rational."""
    return quantize_fraction(Fraction(1, n), reciprocal_fmt(n, word_bits), "RND_CONV", "SAT")


def divide_registers(fmt: Fmt, n: int, recip_word_bits: int) -> dict[str, Fmt]:
    """Registers of the divide-by-``n`` step applied to a value of format ``fmt``.

    ``n`` a power of two: ``scaled`` is the same codes read with ``log2 n`` more fractional bits
    (a wire shift, free). Otherwise ``recip`` holds ``1/n`` and ``product`` the full-precision
    product ``value · recip``.
    """
    if is_power_of_two(n):
        return {"scaled": Fmt(fmt.signed, fmt.word_bits, fmt.frac_bits + n.bit_length() - 1)}
    recip = reciprocal_fmt(n, recip_word_bits)
    return {"recip": recip, "product": mul_fmt(fmt, recip)}


def divide(
    codes: np.ndarray,
    fmt: Fmt,
    n: int,
    recip_word_bits: int,
    out_fmt: Fmt,
    rounding: str,
    overflow: str,
    counter: OverflowCounter,
) -> np.ndarray:
    """``value / n`` into ``out_fmt``: one rounding, at the output register (codes validated).

    Shift when ``n`` is a power of two, else multiply by the rounded reciprocal
    (:func:`reciprocal_code`) in full precision; then requantize to ``out_fmt``.
    """
    regs = divide_registers(fmt, n, recip_word_bits)
    if "scaled" in regs:
        return _requantize(codes, regs["scaled"], out_fmt, rounding, overflow, counter)
    r = np.array([reciprocal_code(n, recip_word_bits)], dtype=np.int64)
    prod, prod_fmt = _mul(codes, fmt, r, regs["recip"])
    return _requantize(prod, prod_fmt, out_fmt, rounding, overflow, counter)


def reciprocal_error(n: int, recip_word_bits: int) -> float:
    """``|recip - 1/n|`` of the divide step (0 for a power of two)."""
    if is_power_of_two(n):
        return 0.0
    fmt = reciprocal_fmt(n, recip_word_bits)
    exact = Fraction(reciprocal_code(n, recip_word_bits), 2**fmt.frac_bits)
    return float(abs(exact - Fraction(1, n)))


def fmt_holding(max_abs: Fraction | float, frac_bits: int, signed: bool = True) -> Fmt:
    """The narrowest format with ``frac_bits`` fractional bits whose range holds ``±max_abs``."""
    target = abs(Fraction(max_abs)) * Fraction(2) ** frac_bits
    need = math.ceil(target)
    word = max(need.bit_length() + (1 if signed else 0), 1)
    return Fmt(signed, word, frac_bits)
