"""A design search's cost: the bundled ``optimize_assay_size`` (four keys, two objectives, one
constraint on pyro_1fmol with a site on every pixel) cut to N evaluations, on the process pool.

    python benchmarks/bench_optimize.py [--evaluations 20] [--workers 2] [--quick]

Prints the search's wall time, its seconds per evaluation and the 200-evaluation study that
extrapolates to (the team's goal: ≤ 30 min on 2 cores), and beside it the baseline run side by
side: the same distinct points' rows alone, through the same executor without Optuna (a fresh
pool, no store). Their ratio is what the search adds: Optuna's asks and tells, its SQLite
storage, the batches' waits for their slowest point. ``--quick``: a small 4 × 6 chip, 8
evaluations in one process (the same code path).

Numbers only; nothing is asserted (speed never lives in the tests).
"""

from __future__ import annotations

import argparse
import tempfile
import time
import tomllib
from pathlib import Path

from chiptwin.cli import bundled_studies, resolve_scenario
from chiptwin.study import run_study
from chiptwin.study.spec import study_from_dict

#: The suite's small scene (tests/conftest.py SMALL): a 10-base template in 14 short flows.
SMALL = """
[scenario]
name = "small"
seed = 7

[assay]
kind = "pyrosequencing"
template = "TCAGGTTCCA"
n_flows = 14
flow_period_s = 20.0
start_s = 4.0
k_a_per_s = 0.25
photons_per_incorporation = 0.01

[sites]
at_pixels = [[1, 1], [2, 4]]

[chip]
rows = 4
cols = 6

[chip.dsp]
n_dark_frames = 4
cms_samples = 2
average_frames = 4

[run]
duration_s = 284.0
"""
QUICK = """
[study]
name = "bench_optimize_quick"
kind = "optimize"
scenario = "small.toml"
seed = 1
replicates = 2
evaluations = 8
batch = 4

[[study.parameter]]
key = "chip.adc.bits"
range = [6, 13]
why = "bench"

[[study.parameter]]
key = "chip.pixel.read_noise_e"
range = [20.0, 2000.0]
why = "bench"

[[study.objective]]
metric = "adc_power_w"
direction = "minimize"

[[study.objective]]
metric = "snr_power"
direction = "maximize"
"""


def study_of(folder: Path, quick: bool, evaluations: int):
    if quick:
        (folder / "small.toml").write_text(SMALL)
        path, raw = folder / "opt.toml", tomllib.loads(QUICK)
        return study_from_dict(raw, str(path), QUICK, folder)
    path = bundled_studies()["optimize_assay_size"]
    raw = tomllib.loads(path.read_text(encoding="utf-8"))
    raw["study"]["evaluations"] = evaluations
    raw["study"].pop("stop", None)  # the budget alone: N evaluations timed
    return study_from_dict(raw, str(path), None, path.parent, resolve_scenario)


def _cold() -> None:
    """Forget this process's prepared scenes, so neither side inherits the other's."""
    from chiptwin.study import rows

    rows._SCENES.clear()


def warm(study) -> None:
    """One row of the base scenario in this process: numba's compiled kernels loaded before
    either side is timed (the pool's workers load their own, on both sides alike)."""
    from chiptwin.study.optimize import fixed_pattern_seed, point_tasks
    from chiptwin.study.rows import run_row

    run_row(point_tasks(study, {}, fixed_pattern_seed(study))[0])


def storage_s(folder: Path) -> float:
    """Seconds of Optuna's import and its SQLite storage's set-up (SQLAlchemy, the schema):
    paid once per study, timed apart from the evaluations."""
    t0 = time.perf_counter()
    from chiptwin.study.optimize import optuna_module

    optuna_module().storages.RDBStorage(f"sqlite:///{folder / 'warm.sqlite'}")
    return time.perf_counter() - t0


def rows_alone(study, points: list[dict], workers: int) -> float:
    """Seconds of the points' rows through a fresh executor, without Optuna or a store."""
    from chiptwin.study.execute import batches, make_executor
    from chiptwin.study.optimize import fixed_pattern_seed, point_tasks

    _cold()
    t0 = time.perf_counter()
    executor = make_executor(workers)
    try:
        fps = fixed_pattern_seed(study)
        tasks = [t for p in points for t in point_tasks(study, p, fps)]
        for _ in executor.run(batches(tasks, study.replicates)):
            pass
    finally:
        executor.close()
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--evaluations", type=int, default=20)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    workers = 1 if args.quick else args.workers
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        study = study_of(folder, args.quick, args.evaluations)
        warm(study)
        once = storage_s(folder)
        _cold()
        t0 = time.perf_counter()
        result = run_study(study, workers=workers, db=folder / "results.sqlite")
        wall = time.perf_counter() - t0
        s = result.summary
        distinct = {t["id"]: t["params"] for t in s["trials"]}
        base = rows_alone(study, list(distinct.values()), workers)
    n = s["evaluations"]["done"]
    per = wall / n
    print(f"{study.name}: {n} evaluations ({len(distinct)} distinct points) × "
          f"{study.replicates} replicates on {workers} worker(s)")
    print(f"  search: {wall:.1f} s, {per:.2f} s per evaluation; 200 evaluations ≈ "
          f"{200 * per / 60:.1f} min (goal ≤ 30 min)")
    print(f"  once per study (not in the above): Optuna's import and SQLite storage {once:.1f} s")
    print(f"  baseline, the same rows alone: {base:.1f} s; search / baseline = "
          f"{wall / base:.2f}x")
    print(f"  front: {len(s['front'])} point(s), {s['evaluations']['feasible']} feasible, "
          f"{s['evaluations']['failed']} failed (inconsistent scenes)")


if __name__ == "__main__":
    main()
