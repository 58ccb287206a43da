"""The headline scene as built against the same scene with the ideal converter, side by side.

``pyro_1fmol`` states the reference chip as built (comparator noise, a 1-LSB INL bow, offset and
gain mismatch: chiptwin.config.reference_chip); ``run.fidelity.adc = "ideal"`` zeroes the
converter's effects. Both run warm in one process, alternating round by round so a busy machine
slows both alike; the ratio of their median wall times is the converter's cost. Aim: ≤ 1.5×.
A second pair times one study row (``run_prepared`` on a prepared scene, as a study's replicates
run). Usage: ``python benchmarks/bench_as_built.py [--quick] [--rounds 5]``.
"""

from __future__ import annotations

import argparse
import statistics
import time
from dataclasses import replace

from chiptwin.config import load_scenario
from chiptwin.fidelity import run
from chiptwin.twin.runner import prepare, run_prepared

#: ``--quick``: 8 flows, 500 frames (tests/conftest.py's REDUCED).
QUICK = ["assay.n_flows=8", "run.duration_s=500.0"]
LEVELS = {"as built": [], "ideal": ['run.fidelity.adc="ideal"']}


def _row_seconds(s, scene, seeds: int) -> float:
    """Median wall time of one study row: ``run_prepared`` for a fresh seed on a shared scene."""
    times = []
    for seed in range(seeds):
        t = time.perf_counter()
        run_prepared(replace(s, scenario=replace(s.scenario, seed=seed)), scene)
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="500 frames, 2 rounds")
    p.add_argument("--rounds", type=int, default=5)
    a = p.parse_args(argv)
    rounds = 2 if a.quick else a.rounds
    extra = QUICK if a.quick else []
    scenes = {k: load_scenario("pyro_1fmol", extra + v) for k, v in LEVELS.items()}
    for s in scenes.values():
        run(s)  # warm: kernels loaded, the optics' profiles cached
    runs = {k: [] for k in scenes}
    for _ in range(rounds):
        for k, s in scenes.items():
            t = time.perf_counter()
            run(s)
            runs[k].append(time.perf_counter() - t)
    prepared = {k: prepare(s) for k, s in scenes.items()}
    rows = {k: _row_seconds(s, prepared[k], 1 + rounds) for k, s in scenes.items()}
    print(f"pyro_1fmol{' (quick: 500 frames)' if a.quick else ''}, {rounds} alternating rounds")
    for k in scenes:
        print(f"  {k:9s} run median {statistics.median(runs[k]):.3f} s "
              f"(min {min(runs[k]):.3f}, max {max(runs[k]):.3f}); study row {rows[k]:.4f} s")
    ratio = statistics.median(runs["as built"]) / statistics.median(runs["ideal"])
    print(f"  as built / ideal: run {ratio:.2f}×, study row "
          f"{rows['as built'] / rows['ideal']:.2f}× (aim ≤ 1.5×)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
