"""The DSP program's stages with an RTL block (kinetics: ``ct_kinetics``, fir8: ``ct_fir``) in
the chip model: a small scenario at ``mode = "rtl"`` gives the fixed level's outputs and
overflow counts bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from chiptwin.fidelity import run

pytestmark = pytest.mark.rtl


@pytest.mark.parametrize("program", [
    '["cms","dark","background","kinetics"]',
    '["cms","dark","background","average","fir8"]',
])
def test_program_rtl_equals_fixed_bit_for_bit(small_toml, program):
    sets = [f"chip.dsp.program={program}", "sites.height_um=150"]
    fixed = run(small_toml, [*sets, "chip.dsp.mode=fixed"])
    rtl = run(small_toml, [*sets, "chip.dsp.mode=rtl"])
    assert rtl.summary["dsp"]["level"] == "rtl"
    for key in ("site_signal_e", "peak_frame_e", "block_t_s"):
        np.testing.assert_array_equal(rtl.arrays[key], fixed.arrays[key])
    assert rtl.summary["dsp"]["overflow"] == fixed.summary["dsp"]["overflow"]
    assert rtl.summary["called_sequences"] == fixed.summary["called_sequences"]
    assert np.any(fixed.arrays["site_signal_e"] != 0)
