"""The harness is itself tested: RTL variants with a planted bug (Verilog defines, not copies
of the files) must be caught by the comparison, with a report that names the first differing
output beats, their cycle and the input beats behind them.

``CT_MUTANT_ROUND`` treats a tie at the output rounding as below half (the rounding constant
2^(SH-1) becomes 2^(SH-1) - 1); ``CT_MUTANT_ACC`` makes every accumulator one bit narrower.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from rtl_ref import vectors

pytestmark = pytest.mark.rtl


def _run(bank, index: int, seed: int = 11):
    inputs = vectors.for_block(bank.blocks[index], 20_000, np.random.default_rng(seed))
    return bank.run(index, inputs, "verilator", p_valid=0.9, p_ready=0.7, seed=seed)


def test_a_changed_rounding_constant_is_caught(banks) -> None:
    report = _run(banks["mutants"], 0)
    assert not report.ok and report.n_mismatches > 0
    text = report.text()
    assert re.search(r"output beat \d+ at cycle \d+: out_d0 expected -?\d+", text)
    assert "x=" in text and "dark=" in text  # the inputs of the differing beat
    assert report.overflow_model == report.overflow_rtl  # only the rounding differs
    clean = _run(banks["background"], 0)  # the same config and vectors, unmutated
    assert clean.ok, clean.text()


def test_a_one_bit_narrower_accumulator_is_caught(banks) -> None:
    report = _run(banks["mutants"], 1)
    assert not report.ok and report.n_mismatches > 0
    assert report.overflow_rtl["acc"]["wrap"] > report.overflow_model["acc"]["wrap"] == 0
    assert re.search(r"run \d+ \(frames \d+…\d+\), pixel \d+: beat \d+ \(x=", report.text())
    clean = _run(banks["average"], 1)  # suite.average_blocks()[1] is the same chain average
    assert clean.ok, clean.text()
    assert banks["average"].blocks[1].cfg == banks["mutants"].blocks[1].cfg


def test_mismatch_report_lists_at_most_the_first_beats(banks) -> None:
    report = _run(banks["mutants"], 0)
    beats = sorted({m.index for m in report.mismatches})
    assert len(beats) <= 5 and beats == sorted(beats)
    assert report.n_mismatches > len(beats)
