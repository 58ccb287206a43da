"""Unit: the format type, its validation, and the validation of codes and values."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from chiptwin.dsp.fixed import (
    Fmt,
    as_codes,
    fmt_for_range,
    quantize,
    requantize,
)
from chiptwin.dsp.registers import fmt_holding, reciprocal_code, reciprocal_fmt


@pytest.mark.parametrize(
    "fmt, q, lo, hi, lsb",
    [
        (Fmt(True, 16, 15), "Q1.15", -32768, 32767, 2**-15),
        (Fmt(False, 13, 0), "UQ13.0", 0, 8191, 1.0),
        (Fmt(True, 16, 2), "Q14.2", -32768, 32767, 0.25),
        (Fmt(True, 64, 0), "Q64.0", -(2**63), 2**63 - 1, 1.0),
        (Fmt(False, 63, 0), "UQ63.0", 0, 2**63 - 1, 1.0),
        (Fmt(True, 1, 0), "Q1.0", -1, 0, 1.0),
        (Fmt(True, 8, -2), "Q10.-2", -128, 127, 4.0),
        (Fmt(False, 4, 6), "UQ-2.6", 0, 15, 2**-6),
    ],
)
def test_format_properties(fmt: Fmt, q: str, lo: int, hi: int, lsb: float) -> None:
    assert fmt.q == q and str(fmt) == q
    assert (fmt.min_code, fmt.max_code, fmt.lsb) == (lo, hi, lsb)
    assert fmt.max_value == Fraction(hi) * Fraction(2) ** -fmt.frac_bits
    assert fmt.spec.dtype == np.int64 and fmt.spec.tolist() == [
        lo,
        hi,
        64 - fmt.word_bits,
        int(fmt.signed),
    ]


@pytest.mark.parametrize(
    "args, error, match",
    [
        ((True, 65, 0), ValueError, r"word_bits = 65: a signed format takes 1…64 bits .* refused"),
        ((False, 64, 0), ValueError, r"word_bits = 64: an? unsigned format takes 1…63"),
        ((True, 0, 0), ValueError, r"word_bits = 0"),
        ((True, 16, 5000), ValueError, r"frac_bits = 5000"),
        ((1, 16, 0), TypeError, r"signed = 1"),
        ((True, 16.0, 0), TypeError, r"word_bits = 16.0"),
        ((True, True, 0), TypeError, r"word_bits = True"),
    ],
)
def test_bad_formats_are_refused(args, error, match: str) -> None:
    with pytest.raises(error, match=match):
        Fmt(*args)


def test_formats_are_frozen_values() -> None:
    assert Fmt(True, 16, 15) == Fmt(True, np.int64(16), 15)
    assert len({Fmt(True, 16, 15), Fmt(True, 16, 15)}) == 1
    with pytest.raises(AttributeError):
        Fmt(True, 16, 15).word_bits = 8  # type: ignore[misc]


def test_codes_are_validated_once() -> None:
    fmt = Fmt(True, 4, 0)
    assert as_codes(np.array([-8, 7], dtype=np.int8), fmt).dtype == np.int64
    with pytest.raises(ValueError, match=r"code 8 outside Q4.0"):
        as_codes(np.array([8]), fmt)
    with pytest.raises(TypeError, match="uint64"):
        as_codes(np.array([1], dtype=np.uint64), fmt)
    with pytest.raises(TypeError, match="float64"):
        as_codes(np.array([1.0]), fmt)
    with pytest.raises(ValueError, match="outside"):
        requantize(np.array([-9]), fmt, fmt)


def test_non_finite_values_are_refused() -> None:
    for bad in (np.nan, np.inf, -np.inf):
        with pytest.raises(ValueError, match="NaN or infinite"):
            quantize(np.array([0.0, bad]), Fmt(True, 8, 0))


def test_unknown_modes_are_refused() -> None:
    with pytest.raises(ValueError, match=r"rounding = 'NEAREST': allowed TRN"):
        quantize(np.array([0.0]), Fmt(True, 8, 0), "NEAREST")
    with pytest.raises(ValueError, match=r"overflow = 'CLAMP': allowed WRAP, SAT, SAT_SYM"):
        quantize(np.array([0.0]), Fmt(True, 8, 0), "RND", "CLAMP")


def test_quantize_keeps_the_shape() -> None:
    x = np.linspace(-1, 1, 24).reshape(2, 3, 4)
    assert quantize(x, Fmt(True, 16, 14)).shape == (2, 3, 4)
    assert quantize(0.5, Fmt(True, 16, 14)).shape == ()


@pytest.mark.parametrize(
    "max_abs, word, signed, expected",
    [
        (0.99, 16, True, Fmt(True, 16, 15)),
        (1.0, 16, True, Fmt(True, 16, 14)),
        (1 - 2**-16, 16, True, Fmt(True, 16, 14)),  # rounds up to 1.0 in Q1.15
        (3.2, 18, True, Fmt(True, 18, 15)),
        (1.0, 16, False, Fmt(False, 16, 15)),
        (1000.0, 8, True, Fmt(True, 8, -3)),
    ],
)
def test_fmt_for_range(max_abs, word: int, signed: bool, expected: Fmt) -> None:
    assert fmt_for_range(max_abs, word, signed) == expected


def test_fmt_holding_and_reciprocal() -> None:
    assert fmt_holding(8191.75, 2) == Fmt(True, 16, 2)
    assert fmt_holding(8192.0, 2) == Fmt(True, 17, 2)
    assert fmt_holding(15, 0, signed=False) == Fmt(False, 4, 0)
    assert reciprocal_fmt(3, 18) == Fmt(False, 18, 19)
    assert reciprocal_code(3, 18) == round(2**19 / 3)  # 174763: 1/3 to 2^-20
    assert reciprocal_fmt(1000, 18) == Fmt(False, 18, 27)
    assert reciprocal_code(1000, 18) < 2**18
