"""A design search on the suite's small scene: it reaches a full grid's best with a quarter of the
grid's evaluations, resumes an interrupted search to the trials an uninterrupted one asks for,
keeps only feasible non-dominated points on its front, stops by its stated rule, and writes its
outputs. Every test here runs whole searches (the slow tier: tests/conftest.py SLOW)."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from chiptwin.cli import main
from chiptwin.study import load_study, run_study
from chiptwin.study.optimize_front import pareto_mask
from chiptwin.study.spec import study_from_dict
from tests.conftest import require_module
from tests.study.test_optimize_spec import STUDY, write

require_module("optuna", "optimize")  # skips off CI, fails under CI=true

#: The grid's two keys: every bit count of the optimiser's range and 8 read noises, log-spaced
#: over its range: 64 points, against the optimiser's 16 evaluations (a quarter).
GRID = {"study": {
    "name": "grid", "scenario": "small.toml", "seed": 5, "replicates": 3,
    "axis": [{"key": "chip.adc.bits", "range": [6, 13], "scale": "int"},
             {"key": "chip.pixel.read_noise_e", "range": [20.0, 2000.0], "scale": "log",
              "n": 8}],
    "metric": [{"name": "snr_power"}, {"name": "adc_power_w"}]}}
#: The cheapest converter (its power) whose power SNR's one-sided 95 % lower bound reaches 2e4.
CHEAPEST = (STUDY.replace('metric = "snr_power"\ndirection = "maximize"',
                          'metric = "adc_power_w"\ndirection = "minimize"')
            .replace('metric = "adc_power_w"\nop = "<="\nbound = 5e-8\njudged = "estimate"',
                     'metric = "snr_power"\nop = ">="\nbound = 2e4'))


def test_the_optimiser_reaches_the_grids_best_with_a_quarter_of_its_evaluations(tmp_path):
    """The grid (64 points × 3 replicates, the budget study's machinery) and the search (16
    evaluations, TPE) on the same scene and seed, so a point both visit has the same rows: the
    search's chosen point is feasible and its ADC power lies within the grid best's interval.
    The grid's best is 11 bits (12 bits pass at ≈ 4× the power; 10 bits reach 8,100 at most);
    the search found 11 bits at 8 of 8 seeds tried (1 … 8) while writing this test."""
    write(tmp_path, CHEAPEST)
    grid = run_study(study_from_dict(GRID, str(tmp_path / "grid.toml"), None, tmp_path),
                     workers=1)
    feasible = [p for p in grid.summary["points"]
                if p["metrics"]["snr_power"]["lower"] >= 2e4]
    best = min(feasible, key=lambda p: p["metrics"]["adc_power_w"]["value"])
    study = load_study(tmp_path / "opt.toml")
    result = run_study(study, workers=1)
    s = result.summary
    assert s["evaluations"]["done"] <= len(grid.summary["points"]) // 4
    chosen = s["chosen"]["point"]
    assert chosen["feasible"] and chosen["metrics"]["snr_power"]["lower"] >= 2e4
    power, ref = chosen["metrics"]["adc_power_w"], best["metrics"]["adc_power_w"]
    assert ref["lo"] <= power["value"] <= ref["hi"]
    assert chosen["params"]["chip.adc.bits"] == best["params"]["chip.adc.bits"] == 11


def _trials(summary: dict) -> list[tuple]:
    return [(t["trial"], json.dumps(t["params"], sort_keys=True), t["state"])
            for t in summary["trials"]]


def test_an_interrupted_search_resumes_to_the_uninterrupted_trials(tmp_path, monkeypatch):
    """Interrupted after the second batch was asked for and one of its points told (the rest
    left running in Optuna's storage), the same command evaluates the running trials first and
    goes on: the trials, their points and the front are the uninterrupted search's, and no
    stored row is run again."""
    from chiptwin.study import optimize

    path = write(tmp_path, STUDY.replace("evaluations = 16", "evaluations = 12")
                 .replace("replicates = 3", "replicates = 2"))
    whole = run_study(load_study(path), workers=1).summary
    told = []
    real = optimize.Search._tell

    def tell_then_stop(self, trial, params):
        if len(told) == 5:
            raise KeyboardInterrupt
        told.append(trial.number)
        real(self, trial, params)

    monkeypatch.setattr(optimize.Search, "_tell", tell_then_stop)
    db = tmp_path / "out.sqlite"
    with pytest.raises(KeyboardInterrupt):
        run_study(load_study(path), workers=1, db=db)
    monkeypatch.setattr(optimize.Search, "_tell", real)
    resumed = run_study(load_study(path), workers=1, db=db).summary
    assert _trials(resumed) == _trials(whole)
    assert [p["id"] for p in resumed["front"]] == [p["id"] for p in whole["front"]]
    assert resumed["runs"]["resumed"] == 2 * 8  # the two batches' rows, none run again
    assert resumed["runs"]["total"] == whole["runs"]["total"]


def test_two_objectives_keep_only_feasible_non_dominated_points(tmp_path):
    """NSGA-II trading the SNR against the ADC's power under an SNR floor: every front point is
    feasible (its one-sided bound over the floor), none dominates another, and every feasible
    evaluated point is dominated by (or equal to) a front point."""
    text = CHEAPEST + '\n[[study.objective]]\nmetric = "snr_power"\ndirection = "maximize"\n'
    result = run_study(load_study(write(tmp_path, text)), workers=1)
    s = result.summary
    assert s["sampler"]["name"] == "NSGAIISampler"
    signs = np.array([1.0, -1.0])
    def objectives(points):
        return np.array([[p["metrics"]["adc_power_w"]["value"],
                          p["metrics"]["snr_power"]["value"]] for p in points]) * signs
    front = objectives(s["front"])
    assert len(front) >= 2 and all(p["feasible"] for p in s["front"])
    assert all(p["metrics"]["snr_power"]["lower"] >= 2e4 for p in s["front"])
    assert pareto_mask(front).all()
    feasible = [t for t in s["trials"] if t["feasible"]]
    together = np.vstack([front, objectives(feasible)])
    on_front = pareto_mask(together)
    assert not on_front[len(front):].any() or all(
        any(np.array_equal(f, g) for g in front) for f in together[len(front):][
            on_front[len(front):]])
    assert s["hypervolume"]["final"] > 0 and len(s["hypervolume"]["curve"]) == 16


def test_the_stopping_rule_stops_a_stalled_search_and_is_stated(tmp_path):
    """With { gain = 0.5, last = 4 } a search whose front's hypervolume grew by less than half
    over the last 4 evaluations stops before its budget, and says so."""
    text = CHEAPEST.replace("evaluations = 16", "evaluations = 40").replace(
        "batch = 4", "batch = 4\nstop = { gain = 0.5, last = 4 }")
    s = run_study(load_study(write(tmp_path, text)), workers=1).summary
    assert s["stop"]["stopped_by"] == "hypervolume" and s["evaluations"]["done"] < 40
    curve = s["hypervolume"]["curve"]
    assert curve[-1] - curve[-5] < 0.5 * curve[-1]
    assert "grew by less than 0.5 of itself over the last 4 evaluations" in s["stop"]["rule"]


def test_the_command_writes_the_front_the_plots_and_the_report(tmp_path, capsys):
    path = write(tmp_path, CHEAPEST.replace("evaluations = 16", "evaluations = 8")
                 .replace("replicates = 3", "replicates = 2"))
    out = tmp_path / "out"
    assert main(["study", str(path), "--out", str(out), "--workers", "1", "--quiet"]) == 0
    printed = " ".join(capsys.readouterr().out.split())  # as read, not as wrapped
    assert "chosen: chip.adc.bits = " in printed and "stopped by budget" in printed
    for name in ("results.csv", "pareto.csv", "pareto.json", "front.png", "chosen.png",
                 "convergence.png", "report.md", "study.json", "results.sqlite"):
        assert (out / name).is_file(), name
    summary = json.loads((out / "study.json").read_text())
    with open(out / "pareto.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [int(r["trial"]) for r in rows] == [p["trial"] for p in summary["front"]]
    assert all(r["feasible"] == "True" for r in rows)
    assert {"adc_power_w_lo", "adc_power_w_hi", "snr_power_lower"} <= set(rows[0])
    report = (out / "report.md").read_text()
    assert "**Stopping rule**: the budget of evaluations" in report
    assert "reference point adc_power_w = " in report and "Chosen by: " in report
    # the same command again: everything resumed, nothing run
    assert main(["study", str(path), "--out", str(out), "--workers", "1", "--quiet"]) == 0
    assert "(0 computed now" in capsys.readouterr().out


def test_an_inconsistent_point_is_a_failed_trial_not_a_stop(tmp_path):
    """Pitches below the diode's 100 µm are inconsistent scenes: those trials are told failed
    (Optuna samples around them), the search goes on and its front holds consistent points."""
    text = CHEAPEST.replace('key = "chip.pixel.read_noise_e"\nrange = [20.0, 2000.0]',
                            'key = "chip.pitch_um"\nrange = [60.0, 200.0]').replace(
        "evaluations = 16", "evaluations = 8")
    s = run_study(load_study(write(tmp_path, text)), workers=1).summary
    failed = [t for t in s["trials"] if t["state"] == "failed"]
    assert failed and all(t["params"]["chip.pitch_um"] < 100.0 for t in failed)
    assert all("chip.pitch_um" in t["message"] for t in failed)
    assert all(p["params"]["chip.pitch_um"] >= 100.0 for p in s["front"])
    assert s["evaluations"]["done"] == 8


def test_serial_pool_and_dask_ask_for_the_same_trials(tmp_path):
    """The batch is told in trial order and a row depends only on its task: one process, a
    pool of two and a Dask worker give the same trials, metrics and front."""
    path = write(tmp_path, STUDY.replace("evaluations = 16", "evaluations = 8")
                 .replace("replicates = 3", "replicates = 2"))
    runs = [run_study(load_study(path), workers=1).summary,
            run_study(load_study(path), workers=2).summary,
            run_study(load_study(path), workers=1, scheduler="local").summary]
    assert runs[2]["executor"]["kind"] == "dask"
    for s in runs[1:]:
        assert _trials(s) == _trials(runs[0])
        assert [t["metrics"] for t in s["trials"]] == [t["metrics"] for t in runs[0]["trials"]]
        assert s["front"] == runs[0]["front"]
