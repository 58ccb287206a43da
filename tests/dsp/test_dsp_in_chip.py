"""The bit-accurate DSP in the chip model: same bits as float where exact, overflow counted and
warned about where the accumulator is too narrow, and the dsp-report command."""

from __future__ import annotations

import json

import numpy as np

from chiptwin.cli import main
from chiptwin.config import load_scenario
from chiptwin.config.consistency import scenario_warnings
from chiptwin.fidelity import run


def test_fixed_chain_equals_float_when_m_k_n_are_powers_of_two(small_toml):
    """With M, K, N powers of two every division is a shift with room for its bits: exact."""
    float_run = run(load_scenario(small_toml))
    fixed_run = run(load_scenario(small_toml, ["chip.dsp.mode=fixed",
                                               "chip.dsp.report_error=true"]))
    np.testing.assert_array_equal(fixed_run.arrays["site_signal_e"],
                                  float_run.arrays["site_signal_e"])
    err = fixed_run.summary["dsp"]["error_vs_float"]
    assert err["max_abs_err_lsb"] == 0.0 and err["outputs"] > 0
    assert fixed_run.summary["dsp"]["overflow_total"] == {"sat": 0, "wrap": 0}
    assert fixed_run.summary["fidelity"]["dsp"] == "fixed"


def test_rounded_chain_stays_within_half_an_lsb_per_rounding(small_toml):
    """M = 3: the CMS divide rounds once (≤ 0.5 LSB of Q.2, i.e. 0.125 ADC LSB); averaging and
    subtraction after it are exact, so the output differs from float by ≤ 0.125 ADC LSB."""
    s = load_scenario(small_toml, ["chip.dsp.mode=fixed", "chip.dsp.report_error=true",
                                   "chip.dsp.cms_samples=3"])
    result = run(s)
    err = result.summary["dsp"]["error_vs_float"]
    out_q = result.summary["dsp"]["registers"]["average"]["output"]  # e.g. "Q15.8"
    lsb = 2.0 ** -int(out_q.split(".")[1])  # output LSB in ADC LSB
    assert 0 < err["max_abs_err_lsb"] * lsb <= 0.125 + 1e-12
    assert result.summary["called_sequence"] == result.summary["true_sequence"]


def test_too_narrow_accumulator_is_warned_and_counted(small_toml, capsys):
    over = ["chip.dsp.mode=fixed", "chip.dsp.acc_bits=14", "chip.dsp.acc_overflow=SAT"]
    s = load_scenario(small_toml, over)
    warnings = scenario_warnings(s)
    assert len(warnings) == 1 and "chip.dsp.acc_bits = 14 is too narrow" in warnings[0]
    assert main(["validate", str(small_toml), *sum((["--set", o] for o in over), [])]) == 0
    assert "too narrow" in capsys.readouterr().err
    summary = run(s).summary
    assert summary["dsp"]["overflow"]["average.acc"]["sat"] > 0
    assert summary["warnings"] == warnings
    wide = run(load_scenario(small_toml, ["chip.dsp.mode=fixed", "chip.dsp.acc_bits=24"]))
    assert wide.summary["dsp"]["overflow_total"] == {"sat": 0, "wrap": 0}
    assert scenario_warnings(wide.scenario) == []


def test_dsp_report_command(small_toml, tmp_path, capsys):
    path = tmp_path / "report.json"
    assert main(["dsp-report", str(small_toml), "--json", str(path)]) == 0
    report = json.loads(path.read_text())
    assert report["all_bounds_ok"] is True
    assert {"cms", "background", "average", "fir 8-tap", "wiener", "kinetics"} <= set(
        report["cases"])
    assert any(label.startswith("stress: ") for label in report["cases"])
    assert "all bounds met: True" in capsys.readouterr().out
