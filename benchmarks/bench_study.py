"""A study against a plain loop of run() over the same rows, and bisect against the grid.

    python benchmarks/bench_study.py [--points 10] [--replicates 100] [--loop-rows 100]
                                     [--floor-rows 30] [--row-only] [--quick]

``--quick``: 2 points × 3 replicates, 3 loop rows, 5 floor rows, no ``lod_pyro``: the same code
path in seconds. ``--row-only``: the row against its floor (0.) alone.

0. One study row of the bundled ``pyro_1fmol`` (``run_prepared(..., frame_steps=False)``, as
   :func:`chiptwin.study.rows.run_row` runs it) against its *floor*: the row's random draws made
   bare with NumPy, one Poisson count per pixel-frame at the row's own expected charge and
   ``1 + 2M`` standard normals (kTC and M reset + M signal read noise), timed in turn with the
   rows (median of ``--floor-rows``, after two of each to warm up); with the row's stage split
   (``summary['stage_time_s']``; ``rest``: the row's wall time outside the stages) and the row
   but its pixel stage (the chip model, the DSP, the detection and the rest) against the floor.

1. A ``pyro_1fmol`` study (binned photons, float DSP): ``--points`` DNA amounts × ``--replicates``,
   run with 1 and with 2 workers (the scaling), against a plain loop of ``run()`` over the first
   ``--loop-rows`` of the same rows in this process (its per-run time × rows / 2 cores is the
   loop's 2-core time; run fewer loop rows to keep the script short, the figure says how many).
2. The store's overhead: inserting the study's rows into a fresh SQLite file, one transaction
   each, against the rows' own run time.
3. ``lod_pyro``: runs and wall time of its bisection against the same axis as a grid at the same
   cap (the grid's runs are counted exactly; its time is runs × the bisection's time per run).

Numbers only; nothing is asserted (speed never lives in the tests).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from chiptwin.cli import bundled_studies, resolve_scenario
from chiptwin.config import load_scenario
from chiptwin.fidelity import resolve, run
from chiptwin.study import load_study, run_study
from chiptwin.study.rows import chip_seed
from chiptwin.study.spec import point_scenario
from chiptwin.study.store import Store
from chiptwin.twin.runner import prepare, run_prepared

STUDY = """
[study]
name = "bench"
scenario = "pyro_1fmol"
seed = 5
replicates = {replicates}

[[study.axis]]
key = "assay.dna_fmol"
range = [0.1, 1.0]
scale = "log"
n = {points}

[[study.metric]]
name = "calls_correct"

[[study.metric]]
name = "snr_power"
"""


def row_vs_floor(n_rows: int) -> None:
    """Print a ``pyro_1fmol`` study row's time, its floor, their ratio and the row's stages."""
    s, choice = resolve(load_scenario(resolve_scenario("pyro_1fmol")))
    scene = prepare(s)
    lam = scene.pixel_frames(s.chip.timing.t_int_s, s.chip.adc.gain_error).mean_e
    normals = lam.size * (1 + 2 * s.chip.dsp.cms_samples)
    rng = np.random.default_rng(1)
    rows, floors, stages = [], [], []
    for i in range(n_rows + 2):
        row_s = replace(s, scenario=replace(s.scenario, seed=1000 + i))
        t0 = time.perf_counter()
        result = run_prepared(row_s, scene, choice=choice, frame_steps=False)
        t1 = time.perf_counter()
        rng.poisson(lam)
        rng.standard_normal(normals)
        t2 = time.perf_counter()
        if i >= 2:
            rows.append(t1 - t0)
            floors.append(t2 - t1)
            stages.append(result.summary["stage_time_s"])
    row, floor = float(np.median(rows)), float(np.median(floors))
    split = {k: float(np.median([st.get(k, 0.0) for st in stages])) for k in stages[0]}
    rest = float(np.median([r - sum(st.values()) for r, st in zip(rows, stages, strict=True)]))
    print(f"row vs floor: pyro_1fmol, {lam.shape[0]} frames × {lam.shape[1]} pixels, "
          f"median of {n_rows} rows, interleaved")
    print(f"  row   {row:.4f} s   floor {floor:.4f} s ({lam.size:,} Poisson + {normals:,} "
          f"normal draws, NumPy)   row/floor {row / floor:.2f}×")
    outside = float(np.median([r - st.get("pixel", 0.0)
                               for r, st in zip(rows, stages, strict=True)]))
    parts = "  ".join(f"{k} {v:.4f} s" for k, v in split.items())
    print(f"  stages: {parts}  rest {rest:.4f} s")
    print(f"  all but the pixel stage: {outside:.4f} s = {outside / floor:.2f}× the floor")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--points", type=int, default=10)
    ap.add_argument("--replicates", type=int, default=100)
    ap.add_argument("--loop-rows", type=int, default=100)
    ap.add_argument("--skip-lod", action="store_true")
    ap.add_argument("--floor-rows", type=int, default=30)
    ap.add_argument("--row-only", action="store_true", help="the row against its floor alone")
    ap.add_argument("--quick", action="store_true",
                    help="2 × 3 rows, 3 loop rows, 5 floor rows, no lod_pyro")
    args = ap.parse_args()
    if args.quick:
        args.points, args.replicates, args.loop_rows, args.skip_lod = 2, 3, 3, True
        args.floor_rows = 5
    row_vs_floor(args.floor_rows)
    if args.row_only:
        return
    folder = Path(tempfile.mkdtemp())
    path = folder / "bench.toml"
    path.write_text(STUDY.format(points=args.points, replicates=args.replicates))
    study = load_study(path, resolve_scenario)
    rows = args.points * args.replicates

    run_study(replace(study, replicates=2), workers=1)  # JIT caches warm
    timed = {}
    for workers in (1, 2):
        t0 = time.perf_counter()
        result = run_study(study, workers=workers)
        timed[workers] = time.perf_counter() - t0
    row_time = sum(r["wall_s"] for r in result.table)

    loop = [r for r in result.table][: args.loop_rows]
    t0 = time.perf_counter()
    for r in loop:
        s = point_scenario(study, r["params"], study.seed, chip_seed(study.seed))
        run(replace(s, scenario=replace(s.scenario, seed=r["seed"])))
    per_run = (time.perf_counter() - t0) / len(loop)

    t0 = time.perf_counter()
    store = Store(folder / "results.sqlite", study)
    for r in result.table:
        store.add([r])  # one transaction a row, as the store wrote before tasks batched rows
    store.close()
    store_s = time.perf_counter() - t0

    print(f"study: {rows} runs of pyro_1fmol ({args.points} points × {args.replicates})")
    print(f"  1 worker  {timed[1]:7.1f} s  {rows / timed[1]:6.1f} runs/s")
    print(
        f"  2 workers {timed[2]:7.1f} s  {rows / timed[2]:6.1f} runs/s  "
        f"(scaling {timed[1] / timed[2]:.2f}×)"
    )
    print(
        f"plain run() loop: {per_run:.3f} s per run over {len(loop)} rows; {rows} rows on 2 "
        f"cores ≈ {per_run * rows / 2:.1f} s → the study is {per_run * rows / 2 / timed[2]:.2f}× "
        "faster"
    )
    print(
        f"  per row inside the study: {row_time / rows:.3f} s (shared per-point work: "
        f"{per_run / (row_time / rows):.2f}× less per run)"
    )
    print(
        f"store: {store_s:.3f} s for {rows} rows = {100 * store_s / row_time:.2f} % of the "
        "rows' run time"
    )

    if not args.skip_lod:
        lod = load_study(bundled_studies()["lod_pyro"], resolve_scenario)
        t0 = time.perf_counter()
        res = run_study(lod, workers=2)
        wall = time.perf_counter() - t0
        grid_runs = len(lod.points()) * lod.replicates
        n = res.summary["runs"]["total"]
        print(f"lod_pyro bisect: {n} runs, {wall:.1f} s; answer {res.answer[0]['point']}")
        print(
            f"  as a grid: {grid_runs} runs ≈ {wall * grid_runs / n:.0f} s "
            f"({grid_runs / n:.1f}× the bisection)"
        )


if __name__ == "__main__":
    main()
