"""The chip model: timings add up, memory and DSP limits are flagged, events scale with frames."""

from __future__ import annotations

import numpy as np
import pytest

from chiptwin.chip import Recorder, Schedule, simulate_chip
from chiptwin.config import ScenarioError, load_scenario
from chiptwin.fidelity import run


def _schedule(small_toml, *overrides):
    s = load_scenario(small_toml, overrides)
    return s, Schedule.from_chip(s.chip, s.run.duration_s)


def test_frame_timing_adds_up_to_the_frame_period(small_toml):
    """reset + M conversions + t_int + M conversions + idle = the frame period, for every frame."""
    s, sch = _schedule(small_toml)
    rec = run(s).trace
    resets = rec.times("pixel", "reset")
    assert np.all(np.diff(resets) == sch.frame_period_ns)
    conv_ns = round((2**s.chip.adc.bits) / s.chip.adc.clock_hz * 1e9)
    m = s.chip.dsp.cms_samples
    np.testing.assert_array_equal(rec.times("adc", "convert_reset") - resets, sch.t_reset_ns)
    np.testing.assert_array_equal(rec.times("pixel", "integrate_start") - resets,
                                  sch.t_reset_ns + m * conv_ns)
    np.testing.assert_array_equal(rec.times("adc", "frame_ready") - resets,
                                  sch.t_reset_ns + 2 * m * conv_ns + sch.t_int_ns)
    assert sch.busy_ns <= sch.frame_period_ns


def test_dsp_job_time_follows_its_clock(small_toml):
    s, sch = _schedule(small_toml)
    rec = run(s).trace
    starts, ends = rec.times("dsp", "job_start"), rec.times("dsp", "job_end")
    words = s.chip.n_pixels * 2 * s.chip.dsp.cms_samples
    per_frame = round(words * s.chip.dsp.cycles_per_sample / s.chip.dsp.clock_hz * 1e9)
    blocks = np.r_[s.chip.dsp.n_dark_frames, np.full(len(ends) - 1, s.chip.dsp.average_frames)]
    np.testing.assert_array_equal(ends - starts, blocks * per_frame)


def test_events_grow_with_frames_not_pixels(small_toml):
    small = run(load_scenario(small_toml)).trace
    wide = run(load_scenario(small_toml, ["chip.rows=16", "chip.cols=32",
                                          "chip.memory.capacity_bits=8000000"])).trace
    assert len(small) == len(wide)


def test_slow_dsp_is_flagged_and_memory_overflows(small_toml):
    s = load_scenario(small_toml, ["chip.dsp.clock_hz=20", "chip.memory.capacity_bits=16000"])
    chip = run(s).summary["chip"]
    assert "dsp_cannot_keep_up" in chip["flags"] and "memory_overflow" in chip["flags"]
    assert chip["overflows"] > 0 and chip["memory_peak_frames"] == chip["memory_capacity_frames"]


def test_fast_dsp_keeps_memory_low(small_toml):
    chip = run(load_scenario(small_toml)).summary["chip"]
    assert chip["flags"] == [] and chip["overflows"] == 0
    assert chip["memory_peak_frames"] == 4  # one block of 4 frames (dark block: 4 too)
    assert 0 < chip["dsp_utilization"] < 1


def test_memory_write_into_a_full_memory_drops_the_frame():
    """A memory of 2 frames and a DSP that needs 3: the third write overflows, nothing deadlocks."""
    sch = Schedule(n_frames=6, frame_period_ns=100, t_reset_ns=1, t_conv_ns=1, t_int_ns=10,
                   cms_samples=1, memory_frames=2, dark_frames=3, block_frames=3,
                   dsp_ns_per_frame=1)

    class Null:
        def dark(self, frames):
            raise AssertionError("never reached: the dark block cannot fill")

        def block(self, frames):
            raise AssertionError("never reached")

    rec = Recorder()
    out = simulate_chip(sch, lambda k: k, Null(), rec)
    assert out.dropped == [2, 3, 4, 5] and out.memory_peak_frames == 2
    assert rec.count("memory", "overflow") == 4


def test_trace_writes_a_vcd(small_toml, tmp_path):
    rec = run(load_scenario(small_toml)).trace
    path = tmp_path / "chip.vcd"
    rec.write_vcd(path)
    text = path.read_text()
    assert "$timescale 1ns $end" in text and "$var wire 1 ! reset $end" in text
    # a time stamp for each tick where a signal changes (tests/report/test_vcd.py: each change)
    assert text.count("\n#") <= len(np.unique(rec.to_arrays()["trace_t_ns"]))


@pytest.mark.parametrize("bits", [8, 13])
def test_conversion_time_is_two_to_the_bits_clock_cycles(small_toml, bits):
    s, sch = _schedule(small_toml, f"chip.adc.bits={bits}", "chip.memory.word_bits=16")
    assert sch.t_conv_ns == round(2**bits / s.chip.adc.clock_hz * 1e9)


def test_saturation_and_adc_clipping_are_flagged(small_toml):
    """Light beyond the full well is flagged; an ADC range meant to clip is counted."""
    bright = run(load_scenario(small_toml, ["assay.photons_per_incorporation=0"])).summary
    assert "full_well" in bright["chip"]["flags"] and bright["chip"]["full_well_pixel_frames"] > 0
    clip = run(load_scenario(small_toml, ["assay.photons_per_incorporation=0",
                                          "chip.adc.v_max_V=0.5",
                                          "chip.adc.range_below_full_well_ok=true"])).summary
    assert "adc_clipped" in clip["chip"]["flags"] and clip["chip"]["adc_clipped_samples"] > 0
    dim = run(load_scenario(small_toml)).summary["chip"]
    assert dim["adc_clipped_samples"] == dim["full_well_pixel_frames"] == 0


@pytest.mark.parametrize(("override", "key"), [
    ("chip.adc.offset_error_lsb=-1000", "chip.adc.offset_error_lsb"),
    ("chip.adc.gain_error=0.3", "chip.adc.v_max_V"),
])
def test_adc_errors_that_would_clip_are_refused(small_toml, override, key):
    with pytest.raises(ScenarioError, match=key):
        load_scenario(small_toml, [override])
