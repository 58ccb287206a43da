"""Long reads: the cost of a 400-flow read on every site of the reference chip, the dephasing
caller against its first version side by side, and how far the closed-form light is from the
cascade's on a long template.

    python benchmarks/bench_long_reads.py [--flows 400] [--cascade-flows 120] [--quick]

Prints the warm wall time of ``pyro_long_read`` by stage and per flow; the caller alone on that
run's flow values, one thread, timed with its kernels as they are and as first written
(``tests/detection/naive_caller.py``: the whole flowgram predicted for every sweep step and
hill-climb candidate on the phasing model's first flow step, every phasing neighbour's posterior
computed, the read always called again without phasing), in turns, best of three each, with the
ratio and whether the calls are the same;
and the flow-by-flow light of the closed-form phased model against the multi-enzyme cascade
(Agah et al., Nucleic Acids Res. 32:e166, 2004) on the scene's template for one site, as the
relative difference of each flow's photons (the cascade with the same incomplete extension and
carry-forward; droop and the per-site DNA spread are closed-form only).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from chiptwin.config import load_scenario
from chiptwin.detection import reads
from chiptwin.twin import reads as twin_reads
from chiptwin.twin import results, run, stages

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # the naive kernels live with the tests, as their oracle
from tests.detection import naive_caller  # noqa: E402

SCENE = "scenarios/pyro_long_read.toml"


def caller_inputs(flows: int) -> tuple:
    """The scenario and the arguments of its ``call_reads``, from one run."""
    seen = {}
    real = results.call_reads

    def spy(s, *args):
        seen["args"] = (s, *args)
        return real(s, *args)

    results.call_reads = spy
    try:
        run(load_scenario(SCENE, [f"assay.n_flows={flows}", f"run.duration_s={20 + 60 * flows}"]))
    finally:
        results.call_reads = real
    return seen["args"]


def caller(flows: int, repeats: int = 3) -> None:
    """The caller on the run's 128 reads, one thread: naive and incremental kernels in turns."""
    args = caller_inputs(flows)
    cores = twin_reads.available_cores
    twin_reads.available_cores = lambda: 1
    best = {"naive": np.inf, "incremental": np.inf}
    calls = {}
    try:
        for _ in range(repeats):
            for label in best:
                old = naive_caller.use_naive(reads) if label == "naive" else None
                t0 = time.perf_counter()
                out = twin_reads.call_reads(*args)
                best[label] = min(best[label], time.perf_counter() - t0)
                calls[label] = np.array([r.calls for r in out])
                if old is not None:
                    naive_caller.restore(reads, old)
    finally:
        twin_reads.available_cores = cores
    n = calls["naive"].size
    print(f"dephasing caller, {len(calls['naive'])} reads x {flows} flows, one thread, best of "
          f"{repeats}: naive {best['naive']:.2f} s ({1e3 * best['naive'] / n:.3f} ms per "
          f"site-flow), incremental {best['incremental']:.2f} s "
          f"({1e3 * best['incremental'] / n:.3f} ms per site-flow): "
          f"{best['naive'] / best['incremental']:.1f}x; same calls: "
          f"{np.array_equal(calls['naive'], calls['incremental'])}")


def wall(flows: int) -> None:
    over = [f"assay.n_flows={flows}", f"run.duration_s={20 + 60 * flows}"]
    run(load_scenario(SCENE, over))  # compile and cache
    t0 = time.perf_counter()
    r = run(load_scenario(SCENE, over))
    total = time.perf_counter() - t0
    print(f"pyro_long_read, 128 sites x {flows} flows, warm: {total:.2f} s "
          f"({1e3 * total / flows:.1f} ms per flow, {1e3 * total / flows / 128:.3f} ms per "
          "site-flow)")
    for stage, sec in r.summary["stage_time_s"].items():
        print(f"  {stage:10s} {sec:8.3f} s")
    print(f"  Q20 read length median {r.summary['reads']['q20_read_length']['median']:.0f}")


def kinetics_levels(flows: int) -> None:
    over = [f"assay.n_flows={flows}", f"run.duration_s={20 + 60 * flows}",
            "sites.at_pixels=[[4, 8]]", "assay.droop_per_flow=0", "assay.dna_cv=0"]
    s_cf = load_scenario(SCENE, over)
    s_cas = load_scenario(SCENE, over + ["run.fidelity.kinetics=cascade"])
    edges = s_cf.assay.start_s + s_cf.assay.flow_period_s * np.arange(flows + 1)
    t0 = time.perf_counter()
    cf = stages.light_source(s_cf).photons(edges)[0]
    t1 = time.perf_counter()
    cas = stages.light_source(s_cas).photons(edges)[0]
    t2 = time.perf_counter()
    one = cf[cf > 0].max() / max(stages.expected_incorporations(s_cf).max(), 1)
    diff = np.abs(cas - cf) / one  # in 1-mers of light
    print(f"closed form {t1 - t0:.2f} s, cascade {t2 - t1:.2f} s for 1 site x {flows} flows")
    print(f"|cascade - closed form| per flow, in 1-mers: median {np.median(diff):.4f}, "
          f"max {diff.max():.4f} (flow {int(diff.argmax())}); total photons ratio "
          f"{cas.sum() / cf.sum():.4f}")
    for lo in range(0, flows, max(flows // 4, 1)):
        seg = diff[lo:lo + flows // 4]
        print(f"  flows {lo:4d}-{lo + len(seg) - 1:4d}: max {seg.max():.4f} 1-mers")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--flows", type=int, default=400)
    ap.add_argument("--cascade-flows", type=int, default=120)
    ap.add_argument("--quick", action="store_true", help="40 flows, 16 for the cascade")
    args = ap.parse_args()
    if args.quick:
        args.flows, args.cascade_flows = 40, 16
    wall(args.flows)
    caller(args.flows)
    kinetics_levels(args.cascade_flows)


if __name__ == "__main__":
    main()
