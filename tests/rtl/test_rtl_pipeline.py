"""Equivalence of the chip model's DSP stage, RTL vs fixed point: ``ct_chain`` (CMS → dark
reference → background subtraction → N-frame averaging) against the model's routines, the
``rtl`` pipeline against ``Pipeline("fixed")`` field by field, and a whole small scenario
routed through the RTL against the same scenario at the fixed level, bit for bit."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from chiptwin.dsp.chain import chain_configs
from chiptwin.dsp.fixed import Fmt
from chiptwin.dsp.pipeline import Frame, Pipeline
from chiptwin.fidelity import run
from rtl_ref.chain_block import ChainBlock
from rtl_ref.cosim import Bank
from rtl_ref.pipeline import RtlPipeline, run_chain_fixed, run_chain_rtl

pytestmark = pytest.mark.rtl


def _samples(rng, adc_bits: int, m: int, k: int, n: int, runs: int, pixels: int) -> np.ndarray:
    top = 2**adc_bits - 1
    s = rng.integers(0, top + 1, (k + n * runs, 2 * m, pixels))
    s[k : k + n] = top  # full scale
    s[k + n : k + 2 * n, :m], s[k + n : k + 2 * n, m:] = top, 0  # most negative CMS
    return s


@pytest.mark.parametrize("counts, pixels", [((13, 4, 16, 4), 16), ((13, 3, 10, 5), 7),
                                            ((13, 2, 4, 4), 24), ((8, 1, 1, 1), 1)])
def test_chain_rtl_equals_the_model_routines(counts, pixels, rng) -> None:
    chain = chain_configs(*counts)
    samples = _samples(rng, counts[0], *counts[1:], runs=12, pixels=pixels)
    report = Bank([ChainBlock(chain, pixels)]).run(0, {"samples": samples}, "verilator", 0.8, 0.5)
    assert report.ok, report.text()
    rtl, fixed = run_chain_rtl(samples, chain), run_chain_fixed(samples, chain)
    np.testing.assert_array_equal(rtl.dark.codes, fixed.dark.codes)
    np.testing.assert_array_equal(rtl.average.codes, fixed.average.codes)
    assert rtl.average.fmt == fixed.average.fmt and rtl.overflow == fixed.overflow


@pytest.mark.parametrize("acc_overflow", ["WRAP", "SAT"])
def test_chain_with_a_narrow_accumulator(acc_overflow: str, rng) -> None:
    """``[chip.dsp] acc_bits`` narrows the N-frame accumulator (``chain_for``): its overflow
    events are counted alike."""
    chain = chain_configs(13, 4, 16, 4)
    avg = chain.average
    narrow = replace(avg, acc_fmt=Fmt(True, 21, avg.in_fmt.frac_bits), acc_overflow=acc_overflow)
    chain = replace(chain, average=narrow)
    samples = _samples(rng, 13, 4, 16, 4, runs=10, pixels=8)
    rtl, fixed = run_chain_rtl(samples, chain, p_ready=0.6), run_chain_fixed(samples, chain)
    np.testing.assert_array_equal(rtl.average.codes, fixed.average.codes)
    assert rtl.overflow == fixed.overflow
    assert fixed.overflow["average"]["acc"]["sat" if acc_overflow == "SAT" else "wrap"] > 0


def test_chain_on_icarus(rng) -> None:
    chain = chain_configs(13, 3, 4, 2)
    samples = _samples(rng, 13, 3, 4, 2, runs=6, pixels=5)
    report = Bank([ChainBlock(chain, 5)]).run(0, {"samples": samples}, "icarus", 0.7, 0.6)
    assert report.ok, report.text()


def _frames(rng, m: int, pixels: int, count: int) -> list[Frame]:
    codes = rng.integers(0, 2**13, (count, 2 * m, pixels))
    return [Frame(codes=c, mean=rng.normal(size=pixels), var=rng.random(pixels)) for c in codes]


@pytest.mark.parametrize("counts", [(13, 4, 16, 4), (13, 3, 5, 3)])
def test_rtl_pipeline_equals_the_fixed_pipeline(counts, rng) -> None:
    chain = chain_configs(*counts)
    fixed = Pipeline("fixed", chain, report_error=True, keep_codes=True)
    rtl = RtlPipeline(chain, report_error=True, keep_codes=True)
    dark = _frames(rng, counts[1], 12, counts[2])
    fixed.dark(dark)
    rtl.dark(dark)
    for _ in range(5):
        frames = _frames(rng, counts[1], 12, counts[3])
        a, b = fixed.block(frames), rtl.block(frames)
        for field in ("value", "mean", "var"):
            np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
    assert rtl.overflow == fixed.overflow
    assert rtl.error.summary() == fixed.error.summary()
    np.testing.assert_array_equal(rtl.dark_mean, fixed.dark_mean)
    np.testing.assert_array_equal(rtl.dark_var, fixed.dark_var)
    assert len(rtl.kept) == len(fixed.kept)


def _comparable(summary: dict) -> dict:
    """The summary without wall times and without the names of the DSP level."""
    out = {k: v for k, v in summary.items() if k not in ("stage_time_s", "wall_time_s")}
    out["fidelity"] = {k: v for k, v in out["fidelity"].items() if k != "dsp"}
    out["dsp"] = {k: v for k, v in out["dsp"].items() if k != "level"}
    return out


def test_mode_rtl_equals_mode_fixed(small_toml) -> None:
    """``[chip.dsp] mode = "rtl"``: the chip model's DSP jobs simulated from the Verilog give
    every array and summary figure of the fixed level, bit for bit."""
    rtl = run(small_toml, ["chip.dsp.mode=rtl"])
    fixed = run(small_toml, ["chip.dsp.mode=fixed"])
    for key in fixed.arrays:
        np.testing.assert_array_equal(fixed.arrays[key], rtl.arrays[key], err_msg=key)
    assert rtl.summary["fidelity"]["dsp"] == rtl.summary["dsp"]["level"] == "rtl"
    assert _comparable(fixed.summary) == _comparable(rtl.summary)
