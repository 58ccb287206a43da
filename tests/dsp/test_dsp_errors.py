"""The error report (fixed vs float, per routine) and the stress-data generators."""

from __future__ import annotations

import json

import numpy as np
import pytest

from chiptwin.dsp.errors import ROUTINES, Case, compare, error_report, format_error_table
from chiptwin.dsp.fixed import Fmt
from chiptwin.dsp.frame_ops import BackgroundConfig
from chiptwin.dsp.stress import default_cases, default_configs, random_codes, stress_inputs


@pytest.fixture(scope="module")
def report() -> dict:
    return error_report(default_cases(np.random.default_rng(5), n_frames=128))


def test_report_covers_every_routine_and_meets_every_bound(report: dict) -> None:
    assert {row["routine"] for row in report["cases"].values()} == set(ROUTINES)
    assert report["all_bounds_ok"] is True and report["not_checked"] == []
    for label, row in report["cases"].items():
        assert row["bound_ok"] is True, label
        assert row["max_abs_err_in_range_lsb"] <= row["bound_lsb"], label
        assert set(row["overflow"]) <= set(row["registers"]) | {"weights"}, label
        assert row["overflow_total"] == {
            k: sum(r[k] for r in row["overflow"].values()) for k in ("sat", "wrap")
        }


def test_report_is_json(report: dict) -> None:
    text = json.dumps(report, allow_nan=False)
    assert json.loads(text) == report


def test_report_figures(report: dict) -> None:
    rows = report["cases"]
    assert rows["cms M=4"]["exact"] and rows["cms M=4"]["sqnr_db"] is None
    assert rows["accumulate N=64"]["exact"]
    assert rows["background"]["max_abs_err_lsb"] == 0.5  # ties happen: 2 bits dropped
    assert abs(rows["background"]["mean_err_lsb"]) < 0.05  # RND_CONV: no bias
    assert rows["fir 8-tap"]["bound_terms"]["output_rounding"] == 0.5
    assert rows["fir 8-tap"]["bound_terms"]["coefficients"] > 0
    assert rows["fir 8-tap"]["overflow"]["output"]["sat"] > 0  # the tap-sign stress pattern
    for row in rows.values():
        assert row["sqnr_db"] is None or row["sqnr_db"] > 60


def test_table_lists_every_case(report: dict) -> None:
    table = format_error_table(report)
    lines = table.splitlines()
    assert len(lines) == 2 + len(report["cases"]) + 1
    for label in report["cases"]:
        assert any(line.startswith(label) for line in lines)
    assert "inf" in table and "yes" in table


def test_unknown_routine_is_refused() -> None:
    with pytest.raises(ValueError, match="routine 'fft'"):
        compare(Case("fft", BackgroundConfig(), {}))


def test_clipped_outputs_are_counted_not_checked(rng) -> None:
    cfg = BackgroundConfig(out_fmt=Fmt(True, 12, 0))  # ±2047: most differences clip
    row = compare(Case("background", cfg, stress_inputs("background", cfg, rng, 16, 64)))
    assert row["n_clipped"] > 0 and row["overflow"]["output"]["sat"] >= row["n_clipped"]
    assert row["bound_ok"] is True  # in-range outputs still meet 0.5 LSB
    assert row["max_abs_err_lsb"] > 100


def test_stress_data_is_reproducible_and_reaches_the_corners() -> None:
    for label, (routine, cfg) in default_configs().items():
        a = stress_inputs(routine, cfg, np.random.default_rng(11), 32, 128)
        b = stress_inputs(routine, cfg, np.random.default_rng(11), 32, 128)
        assert a.keys() == b.keys()
        for key in a:
            np.testing.assert_array_equal(a[key], b[key], err_msg=label)
        in_fmt = cfg.cfg.in_fmt if routine == "wiener" else cfg.in_fmt
        first = next(iter(a.values()))
        assert first.min() == in_fmt.min_code and first.max() == in_fmt.max_code, label


def test_random_codes_cover_the_range(rng) -> None:
    fmt = Fmt(True, 8, 3)
    codes = random_codes(fmt, (20000,), rng)
    assert codes.dtype == np.int64
    assert codes.min() == -128 and codes.max() == 127
    assert {-128, -127, -1, 0, 1, 127} <= set(codes.tolist())
    wide = random_codes(Fmt(True, 64, 0), (1000,), rng)
    assert wide.min() == -(2**63) and wide.max() == 2**63 - 1
