"""The engine: rows equal run() for their seed; serial, pool and Dask give identical tables; a
killed study resumes to the same tables; a changed study is refused for resumption."""

from __future__ import annotations

import contextlib
import io
import json
import signal
import sqlite3
import subprocess
import sys
import time
from dataclasses import replace

import numpy as np
import pytest

from chiptwin.cli import main, resolve_scenario
from chiptwin.config import ScenarioError
from chiptwin.fidelity import run
from chiptwin.study import load_study, run_study
from chiptwin.study.metrics import measure, row_metrics
from chiptwin.study.rows import chip_seed
from chiptwin.study.spec import point_scenario
from tests.study.conftest import STUDY, comparable, write_study


def test_a_row_is_run_with_its_seed(small_study):
    """Sharing per-point work changes nothing: each row's metrics equal those of a plain run()
    of the point with the row's seed and the study's chip."""
    study = load_study(small_study, resolve_scenario)
    result = run_study(study, workers=1)
    for row in [r for r in result.table if r["kind"] == "point"][:4]:
        s = point_scenario(study, row["params"], study.seed, chip_seed(study.seed))
        plain = run(replace(s, scenario=replace(s.scenario, seed=row["seed"])))
        assert measure(plain, row_metrics(study.metrics)) == row["metrics"]


def test_rows_differ_between_replicates_and_vary_chip_redraws_the_chip(tmp_path):
    one = run_study(write_study(tmp_path, STUDY), workers=1).table
    seeds = {r["seed"] for r in one}
    assert len(seeds) == len(one)  # every (point, replicate) its own seed
    varied = run_study(write_study(tmp_path, STUDY.replace("seed = 11", "seed = 11\n"
                                                           "vary_chip = true")), workers=1).table
    same_seed = {r["seed"]: r["metrics"] for r in one}
    assert any(same_seed[r["seed"]] != r["metrics"] for r in varied if r["seed"] in same_seed)


def test_serial_pool_and_dask_give_identical_tables(small_study):
    # distributed is in the test extra: without it this fails with the [dask] hint, never skips
    serial = run_study(small_study, workers=1)
    pool = run_study(small_study, workers=2)  # rows spread over two processes, out of order
    # one Dask worker process: the rows still go to another process and back through Dask's
    # futures (a second worker adds ≈ 5 CPU-s of start-up and nothing the pool does not test)
    dask = run_study(small_study, workers=1, scheduler="local")
    assert comparable(serial.table) == comparable(pool.table) == comparable(dask.table)
    assert serial.answer == pool.answer == dask.answer
    assert dask.summary["executor"]["kind"] == "dask"


def test_answer_statistics_and_outputs(small_study, tmp_path):
    out = tmp_path / "out"
    assert main(["study", str(small_study), "--out", str(out), "--workers", "1", "--quiet"]) == 0
    summary = json.loads((out / "study.json").read_text())
    assert {"answer", "points", "requirement", "runs", "wall_time_s", "chiptwin_version"} <= set(
        summary)
    for p in summary["points"]:
        e = p["metrics"]["base_error_rate"]
        assert "3 runs < 10: the design effect not measured" in e["method"]
        assert e["n"] == 3 and e["upper"] > 0
        assert "snr_loss_db" in p["metrics"] and p["metrics"]["snr_loss_db"]["n"] == 3
    # the design effects measured at the points with 0 < k < n, said beside the bounds
    # 3 runs a point: no design effect is measured, and the statistics say none
    assert summary["statistics"]["design_effect"] is None
    answer = summary["answer"][0]
    if answer["point"] is not None:  # the cheapest passing point, nothing cheaper passes
        cheaper = [p for p in summary["points"]
                   if p["params"]["chip.adc.bits"] < answer["point"]["chip.adc.bits"]]
        assert all(p["status"] != "pass" for p in cheaper)
    lines = (out / "results.csv").read_text().splitlines()
    assert len(lines) == 1 + summary["runs"]["total"]
    assert "base_error_rate_k" in lines[0]
    assert "![" in (out / "report.md").read_text()
    assert list(out.glob("*.png"))


def test_killed_study_resumes_to_the_same_tables(tmp_path):
    """SIGKILL mid-study, then the same command: same rows as an uninterrupted run, no
    duplicate (point, replicate), finished rows not recomputed."""
    path = write_study(tmp_path, STUDY.replace("replicates = 3", "replicates = 8"))
    whole = run_study(path, workers=1)
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "chiptwin", "study", str(path), "--out", str(out),
           "--workers", "1", "--quiet"]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    db = out / "results.sqlite"
    deadline = time.monotonic() + 120
    stored = 0
    while time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.05)
        if db.exists():
            try:
                stored = sqlite3.connect(db).execute("SELECT count(*) FROM runs").fetchone()[0]
            except sqlite3.OperationalError:
                continue
            if stored >= 5:
                break
    assert proc.poll() is None, "the study finished before it could be killed"
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert not (out / "study.json").exists()  # not complete, and does not look it
    # the same command, in this process: what is tested of it is the store it resumes
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        assert main(cmd[3:]) == 0, err.getvalue()
    con = sqlite3.connect(out / "results.sqlite")
    rows = con.execute("SELECT point, replicate FROM runs").fetchall()
    assert len(rows) == len(set(rows)) == len(whole.table)
    summary = json.loads((out / "study.json").read_text())
    assert summary["runs"]["resumed"] >= stored and summary["runs"]["computed"] == len(
        whole.table) - summary["runs"]["resumed"]
    from chiptwin.study.store import Store

    again = Store(out / "results.sqlite", load_study(path, resolve_scenario)).rows()
    assert comparable(again) == comparable(whole.table)


def test_changed_study_is_refused_for_resumption(small_study, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    run_study(small_study, workers=1, db=out / "results.sqlite")  # a study's store, as the CLI's
    small_study.write_text(STUDY.replace("replicates = 3", "replicates = 4"))
    with pytest.raises(ScenarioError, match=r"replicates: 3 → 4.*--fresh"):
        run_study(small_study, workers=1, db=out / "results.sqlite")
    assert main(["study", str(small_study), "--out", str(out), "--workers", "1", "--quiet",
                 "--fresh"]) == 0


def test_rows_of_another_chiptwin_version_are_refused_for_resumption(small_study, tmp_path):
    """A store whose rows another version of chiptwin made is not resumed into this one's table
    (it was: the rows mixed, study.json stating one version for all)."""
    import sqlite3

    db = tmp_path / "results.sqlite"
    run_study(small_study, workers=1, db=db)
    with sqlite3.connect(db) as con:
        con.execute("UPDATE study SET chiptwin_version = '0.0.1-old-model'")
    with pytest.raises(ScenarioError, match=r"made by chiptwin 0.0.1-old-model.*--fresh"):
        run_study(small_study, workers=1, db=db)


def test_study_refuses_a_folder_that_is_not_a_chiptwin_output(small_study, tmp_path, capsys):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("keep me")
    assert main(["study", str(small_study), "--out", str(out), "--quiet"]) == 2
    assert (out / "notes.txt").read_text() == "keep me" and len(list(out.iterdir())) == 1


def test_scheduler_without_the_dask_extra_names_the_extra(small_study, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "distributed", None)  # as if not installed
    out = small_study.parent / "out"
    assert main(["study", str(small_study), "--out", str(out), "--scheduler", "local",
                 "--quiet"]) == 2
    assert "chiptwin[dask]" in capsys.readouterr().err
    assert not out.exists()


def test_a_changed_datasheet_is_refused_for_resumption(tmp_path):
    """A scenario configured from an EMVA 1288 datasheet: the datasheet is part of the study's
    identity, so editing it cannot resume onto rows of the old chip."""
    from chiptwin.cli import bundled_scenarios_folder

    sheet = tmp_path / "sheet.json"
    sheet.write_text((bundled_scenarios_folder() / "datasheets" / "pyro_1fmol_chip.json")
                     .read_text())
    text = STUDY.replace("replicates = 3", "replicates = 1").replace(
        'reference = { "chip.adc.bits" = 14 }', "").replace(
        'key = "chip.adc.bits"\nvalues = [6, 8, 10]', 'key = "chip.dsp.cms_samples"\n'
        "values = [2, 4]").replace('name = "snr_loss_db"', 'name = "snr_power"')
    path = write_study(tmp_path, text)
    scen = tmp_path / "small.toml"
    scen.write_text(scen.read_text() + '\n[chip.pixel]\nfrom_datasheet = "sheet.json"\n')
    db = tmp_path / "results.sqlite"
    first = run_study(path, workers=1, db=db)
    assert all(r["status"] == "ok" for r in first.table)
    data = json.loads(sheet.read_text())
    sheet.write_text(json.dumps(data, indent=2) + "\n")  # same content, new text: still new
    with pytest.raises(ScenarioError, match="datasheet"):
        run_study(path, workers=1, db=db)


def test_a_bisections_bands_are_labelled_at_their_per_look_level(tmp_path):
    """A bisection decides each point at 1 − (1 − c)/looks (Bonferroni over its looks); the
    plots' band and caption say that level (0.9667 for 0.9 over 3 looks), not the study's 0.9,
    which they once printed over intervals drawn at the per-look level."""
    from chiptwin.study.outputs import write_study_outputs
    from tests.study.conftest import STUDY, write_study

    text = STUDY.replace("replicates = 3", 'replicates = 6\nsearch = "bisect"\nbatch = 2')
    text = text.replace("values = [6, 8, 10]", "values = [6, 7, 8, 9, 10, 11]")
    text = text.replace('"<= 0.2"', '"<= 0.01"')
    result = run_study(load_study(write_study(tmp_path, text)), workers=1)
    levels = {p["confidence"] for p in result.summary["points"] if p["confidence"]}
    assert len(levels) == 1 and levels.pop() == pytest.approx(1 - 0.1 / 3)
    out = tmp_path / "out"
    out.mkdir()
    write_study_outputs(result, out)
    report = (out / "report.md").read_text()
    assert "interval at 0.9667 confidence" in report and "at 0.9 confidence" not in report


def test_design_effects_are_said_where_they_were_measured():
    """study.json's statistics.design_effect: per rate metric the measured range over the points
    with 0 < k < n and a Korn–Graubard estimate (10 runs or more); points with k = 0, or too few
    runs to measure it, are not in it."""
    from chiptwin.detection.stats import rate_estimate
    from chiptwin.study.engine import _design_effects

    def point(k, runs):
        e = rate_estimate(np.array(k), np.full(runs, 36), 0.95)
        return {"metrics": {"base_error_rate": e.as_dict()}}

    points = [point([4, 0, 0, 0, 0, 0, 0, 0, 0, 0], 10), point([1] * 10, 10),
              point([0] * 10, 10), point([5, 0, 0], 3)]
    d0 = points[0]["metrics"]["base_error_rate"]["design_effect"]
    assert d0 > 1
    assert _design_effects(points) == (
        f"base_error_rate 1–{d0:.3g} at the 2 point(s) with 0 < k < n (a point with k = 0 or "
        "k = n takes 1: nothing to measure it from)")
    assert _design_effects(points[2:]) is None
