"""Rows run in tasks: the table does not depend on how rows are batched or where they run; a
task's rows are stored together or not at all; a killed Dask worker's tasks run again elsewhere;
a Dask scheduler file, and the refusals of the executor's flags (exit 2 naming the flag)."""

from __future__ import annotations

import json
import os
import signal
import sqlite3

import pytest

from chiptwin.cli import main
from chiptwin.config.cost import MAX_ROWS_PER_TASK, TASK_TARGET_S
from chiptwin.study import load_study, run_study
from chiptwin.study.execute import batches, rows_per_task
from chiptwin.study.store import Store
from tests.study.conftest import STUDY, comparable, write_study

#: The small study at 10 replicates: 4 points (3 ADC depths and the 14-bit reference), 40 rows.
STUDY_40 = STUDY.replace("replicates = 3", "replicates = 10")


@pytest.fixture(scope="module")
def study_40(tmp_path_factory):
    return write_study(tmp_path_factory.mktemp("study_40"), STUDY_40)


@pytest.fixture(scope="module")
def serial_40(study_40):
    """The 40-row study one row a task, in this process: what every other way must give."""
    return run_study(study_40, workers=1, task_rows=1)


@pytest.fixture(scope="module")
def cluster():
    """A Dask LocalCluster of two worker processes (a nanny each: a killed worker restarts)."""
    from distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as c:
        yield c


def test_rows_per_task_aims_at_the_target_and_spreads_over_the_workers():
    assert rows_per_task(0.01, 100_000, 2) == int(TASK_TARGET_S / 0.01)  # 200 rows of 10 ms
    assert rows_per_task(0.01, 40, 2) == 10  # 40 rows: 4 tasks, two per worker
    assert rows_per_task(60.0, 100_000, 2) == 1  # a row longer than the target: one a task
    assert rows_per_task(0.0, 10**6, 1) == MAX_ROWS_PER_TASK
    tasks = list(range(7))
    assert list(batches(tasks, 3)) == [[0, 1, 2], [3, 4, 5], [6]]  # consecutive, in order


def test_the_table_does_not_depend_on_batching_or_executor(study_40, serial_40, cluster):
    ways = {"serial, 7 a task": run_study(study_40, workers=1, task_rows=7),
            "pool, default tasks": run_study(study_40, workers=2),
            "pool, 3 a task, 1 in flight": run_study(study_40, workers=2, task_rows=3,
                                                      in_flight=1),
            "dask, 4 a task, 3 in flight": run_study(study_40, scheduler=cluster.scheduler_address,
                                                      task_rows=4, in_flight=3)}
    for way, result in ways.items():
        assert comparable(result.table) == comparable(serial_40.table), way
        assert result.answer == serial_40.answer, way


def test_an_interrupted_study_keeps_whole_tasks_and_runs_no_stored_row_again(
        study_40, serial_40, tmp_path):
    db = tmp_path / "results.sqlite"
    calls = []

    def interrupt(done: int, total: int) -> None:  # called once a task's rows are stored
        calls.append(done)
        if len(calls) == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_study(study_40, workers=2, task_rows=5, db=db, progress=interrupt)
    kept = Store(db, load_study(study_40)).rows()
    assert len(kept) == calls[-1] == 10  # two whole tasks of 5, nothing of those in flight
    by_point: dict[str, list[int]] = {}
    for r in kept:
        by_point.setdefault(r["point"], []).append(r["replicate"])
    # a task is 5 consecutive rows of a point (10 replicates a point): whole tasks only
    assert all(sorted(reps) in ([0, 1, 2, 3, 4], [5, 6, 7, 8, 9], list(range(10)))
               for reps in by_point.values()), by_point

    resumed = run_study(study_40, workers=1, db=db)
    assert resumed.summary["runs"]["resumed"] == 10
    assert resumed.summary["runs"]["computed"] == 30  # only the 30 missing rows ran
    assert comparable(resumed.table) == comparable(serial_40.table)


def test_a_task_whose_rows_cannot_all_be_stored_stores_none(study_40, serial_40, tmp_path):
    store = Store(tmp_path / "results.sqlite", load_study(study_40))
    # the second row's seed cannot be bound: executemany fails after inserting the first
    good, bad = serial_40.table[0], {**serial_40.table[1], "seed": object()}
    with pytest.raises(sqlite3.Error):
        store.add([good, bad])
    assert store.rows() == []
    store.add([good])
    assert len(store.rows()) == 1


def test_a_scheduler_file_runs_the_study_on_its_workers(study_40, serial_40, cluster, tmp_path,
                                                        capsys):
    from distributed import Client

    # before the worker is killed below: once a worker has been restarted, distributed
    # 2026.8's write_scheduler_file failed to dump the scheduler's info (a tuple key)
    path = tmp_path / "scheduler.json"
    with Client(cluster.scheduler_address) as client:
        client.write_scheduler_file(str(path))
    out = tmp_path / "out"
    assert main(["study", str(study_40), "--out", str(out), "--scheduler-file", str(path),
                 "--rows-per-task", "6", "--quiet"]) == 0, capsys.readouterr().err
    assert json.loads((out / "study.json").read_text())["executor"]["kind"] == "dask"
    stored = Store(out / "results.sqlite", load_study(study_40)).rows()
    assert comparable(stored) == comparable(serial_40.table)


def test_a_killed_dask_worker_s_tasks_run_again(study_40, serial_40, cluster):
    from distributed import Client

    killed = []

    def kill_a_worker(done: int, total: int) -> None:
        if not killed:  # after the first task: others are running on both workers
            with Client(cluster.scheduler_address) as client:
                pid = next(iter(client.run(os.getpid).values()))
            os.kill(pid, signal.SIGKILL)
            killed.append(pid)

    result = run_study(study_40, scheduler=cluster.scheduler_address, task_rows=2,
                       progress=kill_a_worker)
    assert killed
    assert comparable(result.table) == comparable(serial_40.table)  # complete, the same rows


@pytest.mark.parametrize(("flags", "named"), [
    (["--rows-per-task", "0"], "--rows-per-task"),
    (["--rows-per-task", str(MAX_ROWS_PER_TASK + 1)], "--rows-per-task"),
    (["--in-flight", "0"], "--in-flight"),
    (["--worker-timeout", "0"], "--worker-timeout"),
    (["--worker-timeout", "nan"], "--worker-timeout"),
    (["--scheduler-file", "missing.json"], "--scheduler-file"),
    (["--scheduler-file", "{}"], "--scheduler-file"),
    (["--scheduler-file", "x", "--scheduler", "local"], "--scheduler"),
])
def test_bad_executor_flags_exit_2_naming_the_flag(small_study, tmp_path, capsys, flags, named):
    if flags[-1] == "{}":  # a JSON file that names no scheduler
        (tmp_path / "empty.json").write_text("{}")
        flags = ["--scheduler-file", str(tmp_path / "empty.json")]
    elif flags[-1] == "missing.json":
        flags = ["--scheduler-file", str(tmp_path / "missing.json")]
    out = tmp_path / "out"
    assert main(["study", str(small_study), "--out", str(out), "--quiet", *flags]) == 2
    err = capsys.readouterr().err
    assert named in err, err
    assert not out.exists()  # refused before anything was written


def test_a_cluster_without_workers_exits_2_naming_the_timeout(small_study, tmp_path, capsys):
    from distributed import Client, LocalCluster

    path = tmp_path / "scheduler.json"
    with LocalCluster(n_workers=0, processes=False, dashboard_address=None) as empty:
        with Client(empty.scheduler_address) as client:
            client.write_scheduler_file(str(path))
        out = tmp_path / "out"
        assert main(["study", str(small_study), "--out", str(out), "--quiet",
                     "--scheduler-file", str(path), "--worker-timeout", "1"]) == 2
    err = capsys.readouterr().err
    assert "--worker-timeout" in err and "no Dask worker" in err, err
    assert not out.exists()
