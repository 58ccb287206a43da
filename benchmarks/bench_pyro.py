"""pyro_1fmol end to end: the first run in a fresh process (numba compilation or cache load
included) and warm runs, each in its own subprocess so "cold" is honest.

Aim: < 10 s cold, < 1 s warm. Usage: ``python benchmarks/bench_pyro.py [--quick]
[--repeat 5]``. ``--quick``: the scene cut to 8 flows (500 frames), one warm run, and no cold
child (compiling every kernel into an empty numba cache takes tens of seconds): the cached and
warm rows only.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "pyro_1fmol.toml"

CHILD = r"""
import json, sys, time
t0 = time.perf_counter()
from chiptwin.fidelity import run
t_import = time.perf_counter() - t0
sets = sys.argv[3:]
t1 = time.perf_counter(); r = run(sys.argv[1], sets); first = time.perf_counter() - t1
warm = []
for _ in range(int(sys.argv[2])):
    t = time.perf_counter(); run(sys.argv[1], sets); warm.append(time.perf_counter() - t)
print(json.dumps({"import_s": t_import, "first_run_s": first, "warm_s": warm,
                  "stage_time_s": r.summary["stage_time_s"],
                  "called_ok": r.summary["called_sequence"] == r.summary["true_sequence"]}))
"""


#: ``--quick``: fewer frames (tests/conftest.py's REDUCED).
QUICK = ["assay.n_flows=8", "run.duration_s=500.0"]


def child(repeat: int, env: dict | None = None, sets: list[str] = ()) -> dict:
    out = subprocess.run([sys.executable, "-c", CHILD, str(SCENARIO), str(repeat), *sets],
                         capture_output=True, text=True, check=True, env=env)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true",
                   help="500 frames, one warm run, the cold row on the existing numba cache")
    p.add_argument("--repeat", type=int, default=5)
    args = p.parse_args(argv)
    if args.quick:
        cached = child(1, None, QUICK)
        print(f"pyro_1fmol, quick ({' '.join(QUICK)}; no cold row: the numba cache on disk)")
        print(f"  new process, cached   : import {cached['import_s']:.2f} s"
              f" + run {cached['first_run_s']:.2f} s")
        print(f"  warm (1 run)          : {cached['warm_s'][0]:.3f} s")
        print(f"  called sequence right : {cached['called_ok']}")
        return 0
    import os
    import shutil
    import tempfile

    cache = tempfile.mkdtemp(prefix="numba-cache-")
    try:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        cold = child(0, env)          # empty numba cache: compiles every kernel
        cached = child(args.repeat, env)  # cache on disk, new process
    finally:
        shutil.rmtree(cache, ignore_errors=True)
    warm = sorted(cached["warm_s"])
    median = warm[len(warm) // 2] if warm else float("nan")
    print("pyro_1fmol end to end (run() only; writing outputs is separate)")
    print(f"  cold, empty JIT cache : import {cold['import_s']:.2f} s"
          f" + run {cold['first_run_s']:.2f} s")
    print(f"  new process, cached   : import {cached['import_s']:.2f} s"
          f" + run {cached['first_run_s']:.2f} s")
    print(f"  warm (median of {len(warm)})  : {median:.3f} s   [aim < 1 s]")
    print(f"  stage times (last)    : {cached['stage_time_s']}")
    print(f"  called sequence right : {cached['called_ok']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
