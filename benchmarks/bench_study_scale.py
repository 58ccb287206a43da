"""A 100,000-row study through the process pool and a Dask LocalCluster: rows/s, the engine's
overhead per row, client memory, SQLite's write rate, and the same table either way.

    python benchmarks/bench_study_scale.py [--rows 100000] [--small 10000] [--workers 2] [--quick]

``--quick``: 1,000 and 300 rows, the same code path in well under a minute.

The scene is the cheapest study row at hand (≈ 8 ms): the test suite's 4 × 6 chip sequencing
a 10-base template, cut to the 8 flows that read the key, 4 s apart (38 s, 152 frames). The
study sweeps ``chip.adc.bits`` over 10 depths, with replicates making up the rows.

For each executor (``--workers`` local processes; a LocalCluster of as many single-threaded
worker processes) and each size (``--small`` and ``--rows``):

- **rows/s**: rows over the study's wall time (workers' start included, the scene's validation
  and the final summary too: what a user waits for);
- **overhead per row**: the study's wall time × workers against the sum of the rows' own times
  (each row's ``wall_s``, measured in the worker): ``wall × workers / Σ wall_s − 1``. It holds
  the workers' start (≈ 4 s each on this machine, paid once), the client, the store, the
  scheduler and any idle worker;
- **marginal overhead**: the same between the two sizes, ``(wall_L − wall_S) × workers /
  (Σ wall_s_L − Σ wall_s_S) − 1``: what each further row costs beyond its own time, the
  workers' start (paid once) cancelled;
- **client CPU per row**: this process's CPU time over the study, per row (unpickling,
  storing, the summary; a LocalCluster's scheduler runs here too): on 2 cores it competes
  with the workers, on a cluster it bounds the rows/s one client can take;
- **client memory**: tracemalloc's peak of the study (this process; workers are other
  processes) and the process's peak RSS growth, per row, at both sizes: flat bookkeeping
  shows as equal bytes per row (the table itself, returned whole, is O(rows)); tracemalloc
  slows the client's allocations, so the client's figures are if anything pessimistic;
- **SQLite writes**: the finished table re-inserted into a fresh store, one transaction per
  ``rows_per_task`` rows (as the engine writes) and one transaction per row (as before):
  rows/s;
- **the same table**: pool and Dask tables compared row for row (seeds, values, status).

The machine is shared (2 cores, other jobs running): figures are noisy; pool and Dask run side
by side at each size. Numbers only; nothing is asserted but the tables' equality.
"""

from __future__ import annotations

import argparse
import resource
import tempfile
import time
import tracemalloc
from pathlib import Path

from chiptwin.study import run_study
from chiptwin.study.execute import rows_per_task
from chiptwin.study.store import Store

SCENE = """
[scenario]
name = "tiny"
seed = 7

[assay]
kind = "pyrosequencing"
template = "TCAGGTTCCA"
n_flows = 8
flow_period_s = 4.0
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
duration_s = 38.0
"""

STUDY = """
[study]
name = "scale_{rows}"
scenario = "tiny.toml"
seed = 3
replicates = {replicates}

[[study.axis]]
key = "chip.adc.bits"
values = [6, 7, 8, 9, 10, 11, 12, 13, 14, 16]

[[study.metric]]
name = "memory_peak_frames"

[[study.metric]]
name = "snr_power"
"""
POINTS = 10


def study_file(folder: Path, rows: int) -> Path:
    (folder / "tiny.toml").write_text(SCENE)
    path = folder / f"scale_{rows}.toml"
    path.write_text(STUDY.format(rows=rows, replicates=rows // POINTS))
    return path


def rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # Linux: KiB


def cpu_s() -> float:
    """This process's CPU seconds so far (every thread: the client, the pool's manager, and a
    LocalCluster's scheduler, which runs in the client's process)."""
    use = resource.getrusage(resource.RUSAGE_SELF)
    return use.ru_utime + use.ru_stime


def measure(path: Path, workers: int, scheduler: str | None) -> dict:
    rss0, cpu0 = rss_mb(), cpu_s()
    tracemalloc.start()
    t0 = time.perf_counter()
    result = run_study(path, workers=workers, scheduler=scheduler)
    wall = time.perf_counter() - t0
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    rows = len(result.table)
    row_s = sum(r["wall_s"] for r in result.table) / rows
    return {"table": result.table, "rows": rows, "wall_s": wall, "rows_per_s": rows / wall,
            "row_ms": 1e3 * row_s, "overhead": wall * workers / (row_s * rows) - 1,
            "client_cpu_ms": 1e3 * (cpu_s() - cpu0) / rows, "peak_mb": peak / 2**20,
            "rss_growth_mb": rss_mb() - rss0, "study": result.study}


def sqlite_rates(folder: Path, study, table: list[dict], per_task: int) -> tuple[float, float]:
    """Rows/s into a fresh store: ``per_task`` rows a transaction, and one row a transaction."""
    rates = []
    for size in (per_task, 1):
        db = folder / f"write_{size}.sqlite"
        store = Store(db, study, fresh=True)
        t0 = time.perf_counter()
        for i in range(0, len(table), size):
            store.add(table[i:i + size])
        rates.append(len(table) / (time.perf_counter() - t0))
        store.close()
    return rates[0], rates[1]


def same(a: list[dict], b: list[dict]) -> bool:
    def key(t):
        return sorted((r["point"], r["replicate"], r["seed"], repr(r["metrics"]), r["status"])
                      for r in t)
    return key(a) == key(b)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rows", type=int, default=100_000)
    ap.add_argument("--small", type=int, default=10_000)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    if args.quick:
        args.rows, args.small = 1_000, 300
    folder = Path(tempfile.mkdtemp(prefix="bench_study_scale_"))
    print(f"study of a tiny scene (8 flows, 4 × 6 pixels), {args.workers} workers "
          "(2 cores, shared machine: noisy)")
    import distributed  # noqa: F401  (the client's imports, not measured)

    run_study(study_file(folder, POINTS), workers=1)
    print("| rows | executor | wall s | rows/s | row ms | overhead | client CPU ms/row | "
          "client peak MB | peak B/row | RSS growth MB |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    last, first = {}, {}
    for rows in (args.small, args.rows):
        path = study_file(folder, rows)
        for name, scheduler in (("pool", None), ("dask", "local")):
            m = measure(path, args.workers, scheduler)
            first.setdefault(name, m)
            last[name] = m
            print(f"| {m['rows']} | {name} | {m['wall_s']:.1f} s | {m['rows_per_s']:.0f} | "
                  f"{m['row_ms']:.2f} ms | {100 * m['overhead']:.1f} % | "
                  f"{m['client_cpu_ms']:.3f} ms | "
                  f"{m['peak_mb']:.1f} MB | {2**20 * m['peak_mb'] / m['rows']:.0f} | "
                  f"{m['rss_growth_mb']:.0f} MB |", flush=True)
        assert same(last["pool"]["table"], last["dask"]["table"]), "pool and Dask tables differ"
        print(f"  {rows} rows: pool and Dask tables identical row for row")
    for name, large in last.items():
        small = first[name]
        busy = (large["row_ms"] * large["rows"] - small["row_ms"] * small["rows"]) / 1e3
        marginal = (large["wall_s"] - small["wall_s"]) * args.workers / busy - 1
        print(f"{name}: marginal overhead {100 * marginal:.1f} % per row from {small['rows']} "
              f"to {large['rows']} rows (the workers' start cancelled)")
    m = last["pool"]
    per_task = rows_per_task(m["row_ms"] / 1e3, m["rows"], args.workers)
    batched, single = sqlite_rates(folder, m["study"], m["table"], per_task)
    print(f"SQLite writes: {batched:,.0f} rows/s at {per_task} rows a transaction, "
          f"{single:,.0f} rows/s at one a transaction ({len(m['table'])} rows)")


if __name__ == "__main__":
    main()
