"""Calibrations run end to end: known values recovered inside their intervals, a pair the data
cannot separate named, every output written, the store replayed on a rerun, and the same
numbers from a local pool as in this process.

Targets are twin-made: the twin at known values, with other seeds than the fit's common random
numbers (:func:`twin_table`), or, for a light curve, the kinetics' own curve with measurement
noise from a seeded generator (:func:`light_curve`).
"""

from __future__ import annotations

import dataclasses
import json
import sqlite3
import tomllib
from pathlib import Path

import numpy as np
import pytest

from chiptwin.config import ScenarioError, load_scenario
from chiptwin.study import load_study, run_study
from chiptwin.study.calibrate_eval import model_of, simulate
from chiptwin.study.outputs import write_study_outputs
from chiptwin.study.store import Store
from tests.study.test_calibrate_spec import STUDY, TABLE, X, write_study

#: The light curve's scenario: ATP glow at one site (eq. 12), light from 20 s.
ATP = """
[scenario]
name = "atp_small"
seed = 4

[assay]
kind = "atp"
atp_fmol = 0.001
turnover_per_s = 0.1
quantum_yield = 0.88
start_s = 20.0

[sites]
at_pixels = [[1, 1]]

[chip]
rows = 2
cols = 2

[run]
duration_s = 80.0
"""

LIGHT_STUDY = """
[study]
name = "cal_light"
kind = "calibrate"
scenario = "tiny.toml"
seed = 5
optimiser = { popsize = 6, generations = 8 }

[[study.parameter]]
key = "assay.turnover_per_s"
range = [0.01, 1.0]
why = "glow (0.01 1/s) to flash (1 1/s) luciferase kinetics"

[[study.parameter]]
key = "assay.atp_fmol"
range = [1.0e-4, 1.0e-2]
why = "0.1 to 10 amol of ATP per well"

[study.target]
kind = "table"
path = "target.csv"
x = "time"
y = "light"
"""

TIMES = np.arange(21.0, 80.0, 3.0)


def light_curve(folder: Path, rng: np.random.Generator, rel_se: float = 0.02) -> str:
    """The kinetics' light at :data:`TIMES` (turnover 0.1 1/s, 1 amol), each value with a
    standard error of ``rel_se`` of it and drawn with that noise."""
    (folder / "tiny.toml").write_text(ATP, encoding="utf-8")
    (folder / "target.csv").write_text("time [s], light [photons/s]\n0.0, 0.0\n")
    study = load_study(write_study(folder, LIGHT_STUDY, "time [s], light [photons/s]\n"
                                   + "".join(f"{t}, 1.0\n" for t in TIMES), ATP))
    model = dataclasses.replace(model_of(study), x_values=tuple(TIMES))
    true, _ = simulate(model, {"assay.turnover_per_s": 0.1, "assay.atp_fmol": 0.001})
    se = rel_se * true
    measured = true + se * rng.standard_normal(true.size)
    return "time [s], light [photons/s], light_se [photons/s]\n" + "".join(
        f"{float(t)!r}, {float(v)!r}, {float(s)!r}\n" for t, v, s in zip(TIMES, measured, se,
                                                                   strict=True))


def twin_table(folder: Path, qe: float, seed: int, replicates: int = 4) -> str:
    """The tiny chip's SNR table at ``qe``: each point the mean of ``replicates`` runs with the
    seeds of study seed ``seed`` (not the fit's), and its standard error."""
    study = load_study(write_study(folder))
    model = dataclasses.replace(model_of(study), seed=seed, replicates=replicates)
    values, se = simulate(model, {"chip.pixel.qe": qe})
    rows = "".join(f"{x}, {float(v)!r}, {float(s)!r}\n"
                   for x, v, s in zip(model.x_values, values, se, strict=True))
    return f"{X} [photons/s/um2], snr_power [1], snr_power_se [1]\n" + rows


def test_a_light_curve_gives_back_the_kinetics_within_the_intervals(tmp_path):
    table = light_curve(tmp_path, np.random.default_rng(7))
    result = run_study(load_study(write_study(tmp_path, LIGHT_STUDY, table, ATP)), workers=1)
    s = result.summary
    fitted = {p["key"]: p for p in s["parameters"]}
    for key, true in (("assay.turnover_per_s", 0.1), ("assay.atp_fmol", 0.001)):
        lo, hi = fitted[key]["interval"]
        assert lo < true < hi and not any(fitted[key]["open"]), (key, lo, hi)
        assert hi / lo < 1.1  # 2 % points pin both to a few per cent
    assert s["objective"]["kind"] == "chi2" and s["objective"]["dof"] == len(TIMES) - 2
    assert s["correlation"]["inseparable"] == []


def test_a_pair_the_data_cannot_separate_is_named_and_left_open(tmp_path):
    """ATP amount and quantum yield enter the light only as their product."""
    table = light_curve(tmp_path, np.random.default_rng(8))
    text = LIGHT_STUDY.replace('key = "assay.turnover_per_s"\nrange = [0.01, 1.0]',
                               'key = "assay.quantum_yield"\nrange = [0.2, 1.0]')
    s = run_study(load_study(write_study(tmp_path, text, table, ATP)), workers=1).summary
    (pair,) = s["correlation"]["inseparable"]
    assert set(pair["keys"]) == {"assay.quantum_yield", "assay.atp_fmol"}
    assert pair["rho"] < -0.95 and "cannot separate" in s["answer"][0]["statement"]
    qy = next(p for p in s["parameters"] if p["key"] == "assay.quantum_yield")
    assert qy["interval"][1] == pytest.approx(1.0) and qy["open"][1]  # to the range's end


@pytest.mark.slow
def test_a_twin_made_table_is_fitted_and_every_output_written(tmp_path):
    table = twin_table(tmp_path, qe=0.5, seed=1234)
    path = write_study(tmp_path, table=table)
    result = run_study(load_study(path), workers=1)
    out = tmp_path / "out"
    out.mkdir()
    write_study_outputs(result, out)
    names = {p.name for p in out.iterdir()}
    assert {"study.json", "calibrated.toml", "convergence.png", "residuals.png", "report.md",
            "results.csv"} <= names
    s = json.loads((out / "study.json").read_text())
    (p,) = s["parameters"]
    assert p["interval"][0] < 0.5 < p["interval"][1]
    assert s["runs"]["total"] == s["evaluations"]["total"] == len(result.table)
    assert set(s["methods"]) >= {"optimiser", "interval", "stopping", "objective"}
    calibrated = load_scenario(out / "calibrated.toml")  # the fitted scenario loads
    assert calibrated.chip.pixel.qe == pytest.approx(p["value"])
    line = next(x for x in (out / "calibrated.toml").read_text().splitlines()
                if x.startswith("qe ="))
    assert "95% interval [" in line and "was 0.4" in line
    assert len((out / "results.csv").read_text().splitlines()) == len(result.table) + 1
    report = (out / "report.md").read_text()
    assert "chip.pixel.qe" in report and "](residuals.png)" in report


@pytest.mark.slow
def test_a_rerun_takes_every_stored_evaluation_and_an_interrupted_one_resumes(tmp_path):
    path = write_study(tmp_path, table=twin_table(tmp_path, qe=0.45, seed=99))
    db = tmp_path / "results.sqlite"
    first = run_study(load_study(path), workers=1, db=db)
    again = run_study(load_study(path), workers=1, db=db)
    assert again.summary["runs"]["computed"] == 0
    assert again.summary["parameters"] == first.summary["parameters"]
    with sqlite3.connect(db) as con:  # as if killed: the last 15 evaluations never stored
        keys = [r[0] for r in con.execute("SELECT candidate FROM evaluations")]
        lost = keys[-15:]
        con.executemany("DELETE FROM evaluations WHERE candidate = ?", [(k,) for k in lost])
    resumed = run_study(load_study(path), workers=1, db=db)
    assert resumed.summary["runs"]["computed"] == len(lost)
    assert resumed.summary["parameters"] == first.summary["parameters"]


def test_a_changed_target_is_refused_for_resumption(tmp_path):
    path = write_study(tmp_path)
    db = tmp_path / "results.sqlite"
    Store(db, load_study(path)).close()
    (tmp_path / "target.csv").write_text(TABLE.replace("5650.0", "5600.0"))
    with pytest.raises(ScenarioError) as info:
        Store(db, load_study(path))
    assert "the measured data of study.target" in info.value.allowed
    assert "target.csv" in info.value.allowed


@pytest.mark.slow
def test_a_local_pool_gives_the_same_fit_as_one_process(tmp_path):
    study = load_study(write_study(tmp_path, table=twin_table(tmp_path, qe=0.55, seed=5)))
    one = run_study(study, workers=1).summary
    two = run_study(study, workers=2).summary
    assert two["executor"] == {"kind": "pool", "workers": 2}
    assert two["parameters"] == one["parameters"]
    assert two["convergence"] == one["convergence"]


def test_the_cli_runs_and_validates_a_calibration(tmp_path, capsys):
    from chiptwin.cli import main

    table = light_curve(tmp_path, np.random.default_rng(9))
    path = write_study(tmp_path, LIGHT_STUDY, table, ATP)
    assert main(["validate", str(path)]) == 0
    assert "cal_light: ok" in capsys.readouterr().out
    out = tmp_path / "out"
    assert main(["study", str(path), "--out", str(out), "--workers", "1", "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "assay.turnover_per_s = " in printed and "profile-likelihood" in printed
    assert tomllib.loads((out / "calibrated.toml").read_text())["assay"]["atp_fmol"] > 0
    assert json.loads((out / "study.json").read_text())["kind"] == "calibrate"


def test_a_range_where_no_candidate_runs_is_refused_after_the_search(tmp_path):
    """Every integration time of [1.5, 2] s is longer than the 1 s frame: each candidate is an
    inconsistent scenario (recorded invalid), and the study ends in one clean refusal."""
    text = STUDY.replace('key = "chip.pixel.qe"\nrange = [0.2, 0.8]',
                         'key = "chip.timing.t_int_s"\nrange = [1.5, 2.0]')
    with pytest.raises(ScenarioError) as info:
        run_study(load_study(write_study(tmp_path, text)), workers=1)
    assert info.value.key == "study.parameter" and "no candidate" in info.value.allowed
    assert "frame_period_s" in info.value.allowed  # the scenario's own refusal, quoted
