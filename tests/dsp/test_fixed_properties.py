"""Equivalence: the fixed-point core against exact rational arithmetic (``fractions.Fraction``).

Hypothesis draws formats (signed and unsigned, 1…64 bits, fractional bits from −70 to beyond the
float64 range), values (every finite float64, and exact ties at the format's half LSB) and codes;
every rounding and overflow mode; the kernels must match ``tests/dsp/_dsp_exact.py`` bit for bit,
saturation and wrap counts included.
"""

from __future__ import annotations

import math
import os
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from chiptwin.dsp.fixed import (
    OVERFLOW_MODES,
    ROUNDING_MODES,
    Fmt,
    OverflowCounter,
    accumulate,
    accumulate_into,
    add,
    mul,
    quantize,
    quantize_fraction,
    requantize,
    sub,
)
from tests.dsp._dsp_exact import exact_fit, exact_quantize, exact_requantize, exact_round, value

EXAMPLES = int(os.environ.get("CHIPTWIN_DSP_EXAMPLES", "200"))
"""Examples per property; raise it for a soak run (``CHIPTWIN_DSP_EXAMPLES=20000``)."""

SETTINGS = settings(
    max_examples=EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)

roundings = st.sampled_from(ROUNDING_MODES)
overflows = st.sampled_from(OVERFLOW_MODES)


@st.composite
def fmts(draw, max_word: int = 64, frac=None) -> Fmt:
    signed = draw(st.booleans())
    top = min(max_word, 64 if signed else 63)
    word = draw(st.integers(1, top))
    if frac is None:
        frac = draw(st.one_of(st.integers(-70, 140), st.integers(-1100, 1100)))
    return Fmt(signed, word, frac)


@st.composite
def codes_of(draw, fmt: Fmt, min_size: int = 1, max_size: int = 12) -> list[int]:
    corner = st.sampled_from([fmt.min_code, fmt.max_code, 0, fmt.max_code // 2])
    return draw(
        st.lists(
            st.one_of(st.integers(fmt.min_code, fmt.max_code), corner),
            min_size=min_size,
            max_size=max_size,
        )
    )


def _finite(make) -> float:
    """``make()`` as a float, or 0.0 where the format's scale leaves the float64 range."""
    with np.errstate(over="ignore"):
        try:
            v = float(make())
        except OverflowError:
            return 0.0
    return v if math.isfinite(v) else 0.0


@st.composite
def values_for(draw, fmt: Fmt) -> list[float]:
    """Any finite floats, plus exact ties and near-ties at the format's LSB and range edges."""
    any_float = st.floats(allow_nan=False, allow_infinity=False)
    k = st.integers(-(2**52), 2**52)
    f = fmt.frac_bits
    tie = k.map(lambda i: _finite(lambda: np.ldexp(np.float64(i) + 0.5, -f)))
    scaled = k.map(lambda i: _finite(lambda: np.ldexp(np.float64(i), -f - 3)))
    half = _finite(lambda: np.ldexp(1.0, -f - 1))
    hi, lo = _finite(lambda: fmt.max_value), _finite(lambda: fmt.min_value)
    edge = st.sampled_from([hi, lo, hi + half, lo - half, -hi, hi + 2 * half])
    return draw(st.lists(st.one_of(any_float, tie, scaled, edge), min_size=1, max_size=12))


def _check_counts(counter: OverflowCounter, expected: list[tuple[int, int, int]]) -> None:
    assert counter.sat == sum(e[1] for e in expected)
    assert counter.wrap == sum(e[2] for e in expected)


@SETTINGS
@given(data=st.data(), rnd=roundings, ovf=overflows)
def test_quantize_is_exact(data, rnd: str, ovf: str) -> None:
    fmt = data.draw(fmts())
    xs = data.draw(values_for(fmt))
    counter = OverflowCounter()
    got = quantize(np.array(xs), fmt, rnd, ovf, counter)
    expected = [exact_quantize(x, fmt, rnd, ovf) for x in xs]
    assert got.tolist() == [e[0] for e in expected]
    _check_counts(counter, expected)


@SETTINGS
@given(data=st.data(), rnd=roundings, ovf=overflows)
def test_requantize_is_exact(data, rnd: str, ovf: str) -> None:
    src = data.draw(fmts())
    dst = data.draw(
        st.one_of(fmts(frac=data.draw(st.integers(src.frac_bits - 70, src.frac_bits + 70))), fmts())
    )
    codes = data.draw(codes_of(src))
    counter = OverflowCounter()
    got = requantize(np.array(codes, dtype=np.int64), src, dst, rnd, ovf, counter)
    expected = [exact_requantize(c, src, dst, rnd, ovf) for c in codes]
    assert got.tolist() == [e[0] for e in expected]
    _check_counts(counter, expected)


def _grown(fa: Fmt, fb: Fmt, op: str) -> tuple[bool, int, int]:
    """Expected result format (signed, int_bits, frac_bits) by fixed-point word growth (sources.md
    F4), written out."""
    signed = fa.signed or fb.signed or op == "sub"
    ia = fa.int_bits + (1 if signed and not fa.signed else 0)
    ib = fb.int_bits + (1 if signed and not fb.signed else 0)
    if op == "mul":
        return fa.signed or fb.signed, fa.int_bits + fb.int_bits, fa.frac_bits + fb.frac_bits
    return signed, max(ia, ib) + 1, max(fa.frac_bits, fb.frac_bits)


@SETTINGS
@given(data=st.data(), op=st.sampled_from(["add", "sub", "mul"]))
def test_full_precision_ops_are_exact(data, op: str) -> None:
    fa = data.draw(fmts(max_word=40, frac=data.draw(st.integers(-20, 40))))
    fb = data.draw(fmts(max_word=40, frac=data.draw(st.integers(-20, 40))))
    signed, int_bits, frac_bits = _grown(fa, fb, op)
    fn = {"add": add, "sub": sub, "mul": mul}[op]
    n = data.draw(st.integers(1, 8))
    a = data.draw(codes_of(fa, n, n))
    b = data.draw(codes_of(fb, n, n))
    if int_bits + frac_bits > (64 if signed else 63):
        with pytest.raises(ValueError, match="full-precision result needs"):
            fn(np.array(a), fa, np.array(b), fb)
        return
    got, fmt = fn(np.array(a), fa, np.array(b), fb)
    assert (fmt.signed, fmt.int_bits, fmt.frac_bits) == (signed, int_bits, frac_bits)
    exact = {
        "add": lambda x, y: x + y,
        "sub": lambda x, y: x - y,
        "mul": lambda x, y: x * y,
    }[op]
    for code, ca, cb in zip(got.tolist(), a, b, strict=True):
        assert value(code, fmt) == exact(value(ca, fa), value(cb, fb))
        assert fmt.min_code <= code <= fmt.max_code


@SETTINGS
@given(data=st.data(), ovf=overflows)
def test_accumulate_into_is_exact(data, ovf: str) -> None:
    frac = data.draw(st.integers(-10, 30))
    fmt = data.draw(fmts(frac=frac))
    acc = data.draw(fmts(frac=frac))
    terms = data.draw(codes_of(fmt, 1, 20))
    counter = OverflowCounter()
    got = accumulate_into(np.array(terms, dtype=np.int64)[:, None], fmt, acc, ovf, counter)
    code, n_sat, n_wrap = 0, 0, 0
    for t in terms:
        code, s, w = exact_fit(code + t, acc, ovf)
        n_sat, n_wrap = n_sat + s, n_wrap + w
    assert got.tolist() == [code]
    assert (counter.sat, counter.wrap) == (n_sat, n_wrap)


@SETTINGS
@given(data=st.data())
def test_accumulate_full_precision_is_exact(data) -> None:
    fmt = data.draw(fmts(max_word=48, frac=data.draw(st.integers(-10, 30))))
    terms = data.draw(codes_of(fmt, 1, 40))
    got, out = accumulate(np.array(terms, dtype=np.int64), fmt)
    assert out.int_bits == fmt.int_bits + (len(terms) - 1).bit_length()
    assert value(int(got), out) == sum(value(t, fmt) for t in terms)


@SETTINGS
@given(
    num=st.integers(-(2**80), 2**80),
    den=st.integers(1, 2**40),
    data=st.data(),
    rnd=roundings,
    ovf=overflows,
)
def test_quantize_fraction_is_exact(num: int, den: int, data, rnd: str, ovf: str) -> None:
    fmt = data.draw(fmts())
    v = Fraction(num, den)
    expected = exact_fit(exact_round(v * Fraction(2) ** fmt.frac_bits, rnd), fmt, ovf)
    counter = OverflowCounter()
    assert quantize_fraction(v, fmt, rnd, ovf, counter) == expected[0]
    assert (counter.sat, counter.wrap) == expected[1:]
