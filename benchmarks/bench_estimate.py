"""Benchmark: the wall-time estimate before a run (``chiptwin.config.cost``) against the measured.

Runs bundled scenes (some made smaller by ``--set`` keys, printed with the scene), each warm: one
untimed run first (numba kernels compiled or loaded, imports done), then the median of
``--repeat`` runs' ``wall_time_s``; beside it the estimate (``cost.wall_seconds``), its largest
term, and the ratio estimate / measured. The estimate is a planning figure held within
``cost.ESTIMATE_FACTOR`` either way (``tests/config/test_cost.py`` checks two scenes); the
constants in ``chiptwin/config/cost.py`` were calibrated on these scenes.

Usage: ``python benchmarks/bench_estimate.py [--quick] [--repeat 3] [NAME ...]``; NAME is a row
of :data:`SCENES` (default: all). ``--quick``: the fastest row, one timed run.
"""

from __future__ import annotations

import argparse
import statistics

from chiptwin.config import cost, load_scenario
from chiptwin.config.catalog import resolve_scenario
from chiptwin.fidelity import run
from chiptwin.twin import stages

#: Row name: (bundled scenario, ``--set`` keys). The scenes the constants were measured on.
SCENES: dict[str, tuple[str, list[str]]] = {
    "pyro_1fmol": ("pyro_1fmol", []),
    "crosstalk_microarray": ("crosstalk_microarray", []),
    "ccd_two_wells": ("ccd_two_wells", []),
    "pyro_array_256 (500 frames)": ("pyro_array_256", ["assay.n_flows=8",
                                                       "run.duration_s=500.0"]),
    "pyro_1fmol events (116 frames)": ("pyro_1fmol", ["assay.n_flows=8", "assay.flow_period_s=12.0",
                                                      "run.duration_s=116.0",
                                                      'run.fidelity.photons="events"']),
    "pyro_1fmol cascade (8 flows)": ("pyro_1fmol", ["assay.n_flows=8", "run.duration_s=500.0",
                                                    'run.fidelity.kinetics="cascade"']),
}
#: ``--quick``: the row that takes well under a second (the same code path as every row).
QUICK = ("pyro_1fmol",)


def measure(name: str, repeat: int) -> dict:
    scenario, sets = SCENES[name]
    s = load_scenario(resolve_scenario(scenario), sets)
    run(s)  # warm: imports done, numba kernels compiled or loaded
    walls = []
    for _ in range(repeat):
        # what a `chiptwin run` process computes once and then keeps (the cascade's yield fit,
        # ~1 s) is computed again for every timed run, as that process would
        stages._fitted_yield.cache_clear()
        walls.append(run(s).summary["wall_time_s"])
    terms = cost.wall_estimate(s)
    big = max(terms, key=lambda t: t.seconds)
    estimate = sum(t.seconds for t in terms)
    measured = statistics.median(walls)
    return {"name": name, "sets": sets, "measured_s": measured, "estimate_s": estimate,
            "ratio": estimate / measured, "largest": big.what}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("names", nargs="*", help="rows of SCENES (default: all)")
    p.add_argument("--quick", action="store_true", help="the fastest row, one run")
    p.add_argument("--repeat", type=int, default=3)
    args = p.parse_args(argv)
    names = args.names or (QUICK if args.quick else list(SCENES))
    repeat = 1 if args.quick else max(args.repeat, 1)
    unknown = [n for n in names if n not in SCENES]
    if unknown:
        p.error(f"unknown rows {unknown}; choose from {list(SCENES)}")
    print(f"estimate vs measured wall time (warm, median of {repeat}; held within "
          f"{cost.ESTIMATE_FACTOR:g}x either way)")
    print(f"{'scene':32s}{'measured s':>11s}{'estimate s':>11s}{'ratio':>8s}  largest term")
    for name in names:
        r = measure(name, repeat)
        print(f"{name:32s}{r['measured_s']:11.3f}{r['estimate_s']:11.3f}{r['ratio']:7.2f}x  "
              f"{r['largest']}", flush=True)
        if r["sets"]:
            print(f"{'':32s}--set {' '.join(r['sets'])}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
