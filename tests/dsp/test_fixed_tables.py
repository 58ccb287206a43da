"""Unit: test-vector tables of the fixed-point core, every rounding and overflow mode.

Ties of both signs, ±full scale, saturation, wrap, −1 × −1 in Q1.15, the 64-bit limits, and zero /
full-scale ADC codes. Expected values are written out by hand from the definitions in
docs/background/sources.md (Fixed point).
"""

from __future__ import annotations

import numpy as np
import pytest

from chiptwin.dsp.fixed import (
    ROUNDING_MODES,
    Fmt,
    OverflowCounter,
    accumulate,
    accumulate_into,
    add,
    mul,
    quantize,
    requantize,
    sub,
)

MODES = ROUNDING_MODES  # TRN, TRN_ZERO, RND, RND_ZERO, RND_INF, RND_CONV

# x → integer after rounding, per mode (no overflow: Fmt(True, 8, 0) holds all of them)
ROUNDING_TABLE = {
    0.5: (0, 0, 1, 0, 1, 0),
    -0.5: (-1, 0, 0, 0, -1, 0),
    1.5: (1, 1, 2, 1, 2, 2),
    -1.5: (-2, -1, -1, -1, -2, -2),
    2.5: (2, 2, 3, 2, 3, 2),
    -2.5: (-3, -2, -2, -2, -3, -2),
    0.25: (0, 0, 0, 0, 0, 0),
    -0.25: (-1, 0, 0, 0, 0, 0),
    0.75: (0, 0, 1, 1, 1, 1),
    -0.75: (-1, 0, -1, -1, -1, -1),
    5e-324: (0, 0, 0, 0, 0, 0),
    -5e-324: (-1, 0, 0, 0, 0, 0),
    0.0: (0, 0, 0, 0, 0, 0),
    -1e-300: (-1, 0, 0, 0, 0, 0),
    127.0: (127, 127, 127, 127, 127, 127),
    -128.0: (-128, -128, -128, -128, -128, -128),
}


@pytest.mark.parametrize("mode_index, mode", list(enumerate(MODES)))
def test_quantize_rounding_table(mode_index: int, mode: str) -> None:
    xs = np.array([*ROUNDING_TABLE, -0.0])
    expected = np.array([row[mode_index] for row in ROUNDING_TABLE.values()] + [0])
    counter = OverflowCounter()
    got = quantize(xs, Fmt(True, 8, 0), mode, "SAT", counter)
    np.testing.assert_array_equal(got, expected)
    assert counter.as_dict() == {"sat": 0, "wrap": 0}


def test_quantize_ties_at_fractional_lsb() -> None:
    """The same table one binade down: Q4.4 (F = 4), ties at ±2^-5."""
    fmt = Fmt(True, 8, 4)
    xs = np.array(list(ROUNDING_TABLE)[:10]) / 16
    for i, mode in enumerate(MODES):
        expected = [row[i] for row in list(ROUNDING_TABLE.values())[:10]]
        np.testing.assert_array_equal(quantize(xs, fmt, mode, "SAT"), expected)


# Fmt(True, 4, 0): codes −8 … 7. x → (rounding used, WRAP, SAT, SAT_SYM) as (code, sat, wrap)
OVERFLOW_TABLE = [
    (7.0, "RND", (7, 0, 0), (7, 0, 0), (7, 0, 0)),
    (7.5, "RND", (-8, 0, 1), (7, 1, 0), (7, 1, 0)),
    (7.5, "TRN", (7, 0, 0), (7, 0, 0), (7, 0, 0)),
    (-8.0, "RND", (-8, 0, 0), (-8, 0, 0), (-7, 1, 0)),
    (-8.5, "RND", (-8, 0, 0), (-8, 0, 0), (-7, 1, 0)),
    (-8.5, "RND_INF", (7, 0, 1), (-8, 1, 0), (-7, 1, 0)),
    (-9.0, "RND", (7, 0, 1), (-8, 1, 0), (-7, 1, 0)),
    (100.0, "RND", (4, 0, 1), (7, 1, 0), (7, 1, 0)),
    (-100.0, "RND", (-4, 0, 1), (-8, 1, 0), (-7, 1, 0)),
    (1e300, "RND", (0, 0, 1), (7, 1, 0), (7, 1, 0)),
    (-1e300, "TRN", (0, 0, 1), (-8, 1, 0), (-7, 1, 0)),
    (2.0**62, "RND", (0, 0, 1), (7, 1, 0), (7, 1, 0)),
    (2.0**62 + 2.0**10 * 3, "RND", (0, 0, 1), (7, 1, 0), (7, 1, 0)),
    (2.0**52 + 5, "RND", (5, 0, 1), (7, 1, 0), (7, 1, 0)),
]


@pytest.mark.parametrize("x, rounding, wrap, sat, sat_sym", OVERFLOW_TABLE)
def test_quantize_overflow_table(x, rounding, wrap, sat, sat_sym) -> None:
    fmt = Fmt(True, 4, 0)
    for mode, (code, n_sat, n_wrap) in zip(
        ("WRAP", "SAT", "SAT_SYM"), (wrap, sat, sat_sym), strict=True
    ):
        counter = OverflowCounter()
        assert quantize(np.array([x]), fmt, rounding, mode, counter)[0] == code, (x, mode)
        assert counter.as_dict() == {"sat": n_sat, "wrap": n_wrap}, (x, mode)


# UQ4.0: codes 0 … 15
UNSIGNED_TABLE = [
    (-0.5, "RND", (0, 0, 0), (0, 0, 0)),
    (-0.5, "TRN", (15, 0, 1), (0, 1, 0)),
    (-1.0, "RND", (15, 0, 1), (0, 1, 0)),
    (15.0, "RND", (15, 0, 0), (15, 0, 0)),
    (15.5, "RND_CONV", (0, 0, 1), (15, 1, 0)),
    (15.5, "RND_ZERO", (15, 0, 0), (15, 0, 0)),
    (0.0, "RND", (0, 0, 0), (0, 0, 0)),
]


@pytest.mark.parametrize("x, rounding, wrap, sat", UNSIGNED_TABLE)
def test_quantize_unsigned_table(x, rounding, wrap, sat) -> None:
    fmt = Fmt(False, 4, 0)
    for mode, expect in (("WRAP", wrap), ("SAT", sat), ("SAT_SYM", sat)):
        counter = OverflowCounter()
        code = quantize(np.array([x]), fmt, rounding, mode, counter)[0]
        assert (code, counter.sat, counter.wrap) == expect, (x, mode)


# --- Q1.15 multiply ---------------------------------------------------------------------------

Q1_15 = Fmt(True, 16, 15)


def test_minus_one_times_minus_one_q1_15() -> None:
    """−1 × −1 = +1 needs Q2.30; back in Q1.15 it saturates, wraps or saturates symmetrically."""
    a = np.array([-32768])
    prod, fmt = mul(a, Q1_15, a, Q1_15)
    assert fmt == Fmt(True, 32, 30) and fmt.q == "Q2.30"
    assert prod[0] == 1 << 30
    for mode, (code, n_sat, n_wrap) in {
        "SAT": (32767, 1, 0),
        "SAT_SYM": (32767, 1, 0),
        "WRAP": (-32768, 0, 1),
    }.items():
        for rounding in MODES:
            counter = OverflowCounter()
            assert requantize(prod, fmt, Q1_15, rounding, mode, counter)[0] == code
            assert (counter.sat, counter.wrap) == (n_sat, n_wrap)


# product codes in Q2.30 (a · b with b = 1 LSB, i.e. a / 2^15 LSB of Q1.15) → Q1.15 per mode
Q15_PRODUCT_TABLE = {
    16384: (0, 0, 1, 0, 1, 0),  # +0.5 LSB
    -16384: (-1, 0, 0, 0, -1, 0),  # −0.5 LSB
    49152: (1, 1, 2, 1, 2, 2),  # +1.5 LSB
    -49152: (-2, -1, -1, -1, -2, -2),  # −1.5 LSB
    81920: (2, 2, 3, 2, 3, 2),  # +2.5 LSB
    16385: (0, 0, 1, 1, 1, 1),  # just above a tie
    -16385: (-1, 0, -1, -1, -1, -1),
}


@pytest.mark.parametrize("mode_index, mode", list(enumerate(MODES)))
def test_q1_15_product_ties(mode_index: int, mode: str) -> None:
    a = np.array(list(Q15_PRODUCT_TABLE), dtype=np.int64)
    prod, fmt = mul(a, Fmt(True, 18, 15), np.array([1]), Q1_15)
    assert np.array_equal(prod, a)
    expected = [row[mode_index] for row in Q15_PRODUCT_TABLE.values()]
    np.testing.assert_array_equal(requantize(prod, fmt, Q1_15, mode, "SAT"), expected)


def test_q1_15_full_scale_products() -> None:
    full = np.array([-32768, 32767, -32768, 32767])
    other = np.array([32767, 32767, -32768, -32768])
    prod, fmt = mul(full, Q1_15, other, Q1_15)
    np.testing.assert_array_equal(prod, full * other)
    out = requantize(prod, fmt, Q1_15, "RND_CONV", "SAT")
    # −(1 − 2^-15), (1 − 2^-15)² rounds to 32766, +1 saturates, −(1 − 2^-15)
    np.testing.assert_array_equal(out, [-32767, 32766, 32767, -32767])


# --- 64-bit limits ----------------------------------------------------------------------------

I64_MIN, I64_MAX = -(2**63), 2**63 - 1
W64 = Fmt(True, 64, 0)


def test_requantize_64_bit_identity_and_narrowing() -> None:
    codes = np.array([I64_MIN, -1, 0, 1, I64_MAX])
    np.testing.assert_array_equal(requantize(codes, W64, W64), codes)
    counter = OverflowCounter()
    got = requantize(codes, W64, Fmt(True, 32, 0), "TRN", "SAT", counter)
    np.testing.assert_array_equal(got, [-(2**31), -1, 0, 1, 2**31 - 1])
    assert counter.sat == 2
    got = requantize(codes, W64, Fmt(True, 32, 0), "TRN", "WRAP")
    np.testing.assert_array_equal(got, [0, -1, 0, 1, -1])


# Q0.64 (or Q1.63) → integer, per mode: (−0.5 tie, 0.5 − 2^-64, +0.5 tie, tiny −, tiny +)
SHIFT_64_TABLE = {
    "TRN": (-1, 0, 0, -1, 0),
    "TRN_ZERO": (0, 0, 0, 0, 0),
    "RND": (0, 0, 1, 0, 0),
    "RND_ZERO": (0, 0, 0, 0, 0),
    "RND_INF": (-1, 0, 1, 0, 0),
    "RND_CONV": (0, 0, 0, 0, 0),
}


@pytest.mark.parametrize("mode, expected", list(SHIFT_64_TABLE.items()))
def test_requantize_shifts_of_64_bits_and_more(mode: str, expected: tuple[int, ...]) -> None:
    """Shift 64: −2^63 is the tie −0.5; shift 63: ±2^62 are ties; shift 1000: only signs remain."""
    dst = Fmt(True, 2, 0)
    got = [
        *requantize(np.array([I64_MIN, I64_MAX]), Fmt(True, 64, 64), dst, mode, "SAT"),
        *requantize(np.array([2**62]), Fmt(True, 64, 63), dst, mode, "SAT"),
        *requantize(np.array([I64_MIN, I64_MAX]), Fmt(True, 64, 1000), dst, mode, "SAT"),
    ]
    assert got == list(expected)


def test_left_shift_overflow_at_64_bits() -> None:
    counter = OverflowCounter()
    codes = np.array([2**62, -(2**62), -(2**62) - 1, 1])
    got = requantize(codes, W64, Fmt(True, 64, 1), "RND", "SAT", counter)
    np.testing.assert_array_equal(got, [I64_MAX, I64_MIN, I64_MIN, 2])
    assert counter.sat == 2
    got = requantize(codes, W64, Fmt(True, 64, 1), "RND", "WRAP")
    np.testing.assert_array_equal(got, [I64_MIN, I64_MIN, I64_MAX - 1, 2])
    got = requantize(np.array([1, -1]), W64, Fmt(True, 64, 200), "RND", "WRAP")
    np.testing.assert_array_equal(got, [0, 0])


@pytest.mark.parametrize(
    "terms, mode, expected, sat, wrap",
    [
        ([I64_MAX, 1], "SAT", I64_MAX, 1, 0),
        ([I64_MAX, 1], "WRAP", I64_MIN, 0, 1),
        ([I64_MIN, -1], "SAT", I64_MIN, 1, 0),
        ([I64_MIN, -1], "WRAP", I64_MAX, 0, 1),
        ([I64_MIN, -1], "SAT_SYM", -I64_MAX, 2, 0),  # MIN itself is rewritten, then saturates
        ([I64_MAX, I64_MAX, I64_MIN, I64_MIN], "WRAP", -2, 0, 2),
        ([I64_MAX, I64_MAX, I64_MIN, I64_MIN], "SAT", I64_MIN, 2, 0),
        ([I64_MAX, I64_MIN, I64_MAX, I64_MIN], "WRAP", -2, 0, 0),
    ],
)
def test_accumulate_into_64_bit_register(terms, mode, expected, sat, wrap) -> None:
    """The exact sum leaves int64: the register still saturates or wraps exactly."""
    counter = OverflowCounter()
    got = accumulate_into(np.array(terms)[:, None], W64, W64, mode, counter)
    assert got[0] == expected
    assert (counter.sat, counter.wrap) == (sat, wrap)


def test_full_precision_limits() -> None:
    w63 = Fmt(True, 63, 0)
    got, fmt = add(np.array([-(2**62)]), w63, np.array([-(2**62)]), w63)
    assert fmt == W64 and got[0] == I64_MIN
    got, fmt = sub(np.array([2**62 - 1]), w63, np.array([-(2**62)]), w63)
    assert fmt == W64 and got[0] == I64_MAX
    w32 = Fmt(True, 32, 0)
    got, fmt = mul(np.array([-(2**31)]), w32, np.array([-(2**31)]), w32)
    assert fmt == W64 and got[0] == 2**62
    with pytest.raises(ValueError, match="65 bits"):
        mul(np.array([1]), Fmt(True, 33, 0), np.array([1]), w32)
    with pytest.raises(ValueError, match="65 bits"):
        add(np.array([1]), W64, np.array([1]), W64)
    total, fmt = accumulate(np.full((4, 1), I64_MIN // 4), Fmt(True, 62, 0))
    assert fmt == W64 and total[0] == I64_MIN


# --- ADC codes --------------------------------------------------------------------------------


def test_zero_and_full_scale_adc_codes() -> None:
    """13-bit ADC codes 0 and 8191 into signed Q14.2 and back: exact in every mode."""
    adc = Fmt(False, 13, 0)
    word = Fmt(True, 16, 2)
    codes = np.array([0, 1, 8190, 8191])
    for rounding in MODES:
        for overflow in ("WRAP", "SAT", "SAT_SYM"):
            counter = OverflowCounter()
            up = requantize(codes, adc, word, rounding, overflow, counter)
            np.testing.assert_array_equal(up, codes * 4)
            np.testing.assert_array_equal(requantize(up, word, adc, rounding, overflow), codes)
            assert counter.as_dict() == {"sat": 0, "wrap": 0}
    np.testing.assert_array_equal(
        quantize(np.array([0.0, 8191.0, 8191.5]), adc, "RND"), [0, 8191, 8191]
    )
    np.testing.assert_array_equal(quantize(np.array([8191.5]), adc, "RND", "WRAP"), [0])
