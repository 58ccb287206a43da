"""Overflow is never silent: a long accumulation into a too-narrow accumulator is detected,
counted exactly, and flagged by ``accumulator_bits_needed`` and the error report.
"""

from __future__ import annotations

import numpy as np
import pytest

from chiptwin.dsp.errors import Case, compare
from chiptwin.dsp.fixed import (
    Fmt,
    OverflowCounter,
    accumulate_into,
    accumulator_bits_needed,
    needs_checks,
    sum_fmt,
)
from chiptwin.dsp.frame_ops import AverageConfig, accumulate_frames_fixed, average_frames_fixed

ADC = Fmt(False, 13, 0)


def test_long_accumulation_overflows_a_narrow_accumulator_and_is_counted() -> None:
    """4096 full-scale 13-bit frames need 25 bits; a 20-bit accumulator overflows.

    WRAP: one wrap each time the running sum crosses 2^20, ⌊4096 · 8191 / 2^20⌋ = 31 per pixel,
    and the final code is the exact sum modulo 2^20. SAT: every addition after the first that
    exceeds 2^20 − 1 saturates: 4096 − ⌊(2^20 − 1) / 8191⌋ = 3968 per pixel.
    """
    n, pixels = 4096, 16
    frames = np.full((n, pixels), 8191, dtype=np.int64)
    acc = Fmt(False, 20, 0)
    assert accumulator_bits_needed(ADC, n) == 25 > acc.word_bits
    wrap = OverflowCounter()
    got = accumulate_into(frames, ADC, acc, "WRAP", wrap)
    assert (wrap.sat, wrap.wrap) == (0, 31 * pixels)
    np.testing.assert_array_equal(got, (n * 8191) % 2**20)
    sat = OverflowCounter()
    got = accumulate_into(frames, ADC, acc, "SAT", sat)
    assert (sat.sat, sat.wrap) == ((4096 - (2**20 - 1) // 8191) * pixels, 0)
    np.testing.assert_array_equal(got, 2**20 - 1)
    ok = OverflowCounter()
    accumulate_into(frames, ADC, Fmt(False, 25, 0), "WRAP", ok)
    assert ok.as_dict() == {"sat": 0, "wrap": 0}


def test_signed_accumulation_overflow_both_ways() -> None:
    x = np.array([[30000], [30000], [-32768], [-32768], [-32768]], dtype=np.int64)
    fmt = acc = Fmt(True, 16, 0)
    c = OverflowCounter()
    got = accumulate_into(x, fmt, acc, "SAT", c)  # 32767 (sat), −1, −32768 (sat), −32768 (sat)
    assert got[0] == -32768 and (c.sat, c.wrap) == (3, 0)
    c = OverflowCounter()
    got = accumulate_into(x, fmt, acc, "WRAP", c)  # −5536 (wrap), 27232 (wrap), −5536, 27232 (wrap)
    assert got[0] == (60000 - 3 * 32768) % 2**16 and (c.sat, c.wrap) == (0, 3)


def test_narrow_accumulator_in_the_averaging_routine_is_reported() -> None:
    cfg = AverageConfig(n=64, in_fmt=ADC, acc_fmt=Fmt(False, 16, 0), out_fmt=Fmt(False, 13, 0))
    frames = np.full((128, 8), 8000, dtype=np.int64)
    acc = accumulate_frames_fixed(frames, cfg)
    assert acc.overflow["acc"]["wrap"] == 2 * 8 * (64 * 8000 // 2**16)
    avg = average_frames_fixed(frames, cfg)
    assert avg.total()["wrap"] > 0 and not np.all(avg.codes == 8000)
    row = compare(Case("average", cfg, {"frames": frames}))
    assert row["bound_ok"] is None
    assert row["bound_note"] == "overflow before the output at acc"
    assert row["max_abs_err_lsb"] > 1000


@pytest.mark.parametrize(
    "fmt, n, bits",
    [
        (ADC, 1, 13),
        (ADC, 2, 14),
        (ADC, 64, 19),
        (ADC, 65, 20),
        (ADC, 4096, 25),
        (Fmt(True, 16, 15), 2, 17),
        (Fmt(True, 16, 2), 64, 22),
        (Fmt(True, 16, 2), 3, 18),
        (Fmt(False, 1, 0), 3, 2),  # max 3: 2 bits, one fewer than W + ⌈log2 n⌉
        (Fmt(True, 1, 0), 2, 2),  # −1 + −1 = −2
        (Fmt(True, 64, 0), 1, 64),
        (Fmt(True, 64, 0), 2, 65),
    ],
)
def test_accumulator_bits_needed(fmt: Fmt, n: int, bits: int) -> None:
    assert accumulator_bits_needed(fmt, n) == bits
    if bits <= (64 if fmt.signed else 63):
        acc = Fmt(fmt.signed, bits, fmt.frac_bits)
        assert not needs_checks(fmt, n, acc, "WRAP")
        if bits > 1:
            assert needs_checks(fmt, n, Fmt(fmt.signed, bits - 1, fmt.frac_bits), "WRAP")


def test_accumulator_bits_needed_is_what_extreme_sums_need() -> None:
    for fmt in (ADC, Fmt(True, 16, 2), Fmt(True, 3, 0), Fmt(False, 2, 0)):
        for n in (1, 2, 3, 5, 7, 8, 9, 100):
            bits = accumulator_bits_needed(fmt, n)
            acc = Fmt(fmt.signed, bits, fmt.frac_bits)
            for extreme in (fmt.min_code, fmt.max_code):
                c = OverflowCounter()
                accumulate_into(np.full((n, 1), extreme), fmt, acc, "WRAP", c)
                assert c.wrap == 0
            assert bits <= sum_fmt(fmt, n).word_bits
            if bits > 1:
                narrow = Fmt(fmt.signed, bits - 1, fmt.frac_bits)
                worst = [OverflowCounter() for _ in (fmt.min_code, fmt.max_code)]
                for counter, extreme in zip(worst, (fmt.min_code, fmt.max_code), strict=True):
                    accumulate_into(np.full((n, 1), extreme), fmt, narrow, "WRAP", counter)
                assert sum(c.wrap for c in worst) > 0, (fmt, n)


def test_accumulator_bits_needed_refuses_no_frames() -> None:
    with pytest.raises(ValueError, match="n_frames = 0"):
        accumulator_bits_needed(ADC, 0)


def test_default_accumulators_never_overflow() -> None:
    for n in (1, 2, 3, 4, 5, 64, 65, 1000, 65536):
        cfg = AverageConfig(n=n, in_fmt=ADC)
        assert cfg.acc_fmt.word_bits >= accumulator_bits_needed(ADC, n)
        assert not needs_checks(ADC, n, cfg.acc_fmt, cfg.acc_overflow)
