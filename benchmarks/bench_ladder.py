"""The fidelity ladder of every bundled scenario and of the hard cases, with ``auto``'s row.

Each scenario runs through :func:`chiptwin.fidelity.run_ladder` with every stage left to ``auto``
under the budget given (default ``snr_rel = 0.01``), so its table holds the reference, each
stage's other levels, the cheapest combination and the levels ``auto`` picks, each with its warm
wall time, speed-up and measured errors. Scenes whose reference (events photons, cascade
kinetics) would take hours are made smaller by the ``--set`` keys in :data:`SMALLER`, stated in
the output. The hard cases (:data:`chiptwin.fidelity.ladder.HARD_CASES`) run with their own budgets.

    python benchmarks/bench_ladder.py [NAME ...] [--replicates N] [--budget snr_rel=0.01]
        [--rtl] [--out FILE.md]
    python benchmarks/bench_ladder.py --quick    # atp_glow cut to 30 frames, 2 replicates

NAME is a bundled scenario or a hard case; default: all of both. The DSP reference is ``fixed``
(which the RTL equals bit for bit) unless ``--rtl``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from chiptwin.config import load_scenario
from chiptwin.fidelity.ladder import HARD_CASES, LEVELS, run_ladder, table

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"

#: Bundled scenes made smaller for the ladder: their reference runs photons at the events level
#: (cost grows with the photons) and, for pyrosequencing, the cascade; 8 flows read the key.
SMALLER = {
    "ccd_100fmol": ["assay.n_flows=8", "run.duration_s=496.0"],
    "pyro_array_256": ["assay.n_flows=8", "run.duration_s=500.0", "chip.rows=16",
                       "chip.cols=16", "sites.at_pixels=[[2, 2], [2, 6], [6, 2], [6, 6]]"],
    "pyro_paper_yield": ["assay.n_flows=8", "run.duration_s=500.0"],
    "pyro_paper_yield_fast": ["assay.n_flows=8", "assay.flow_period_s=4.0",
                              "run.duration_s=34.0"],
}


#: ``--quick``: one scene whose ladder (events reference included) runs in seconds, the same code
#: path.
QUICK = ("atp_glow", ["run.duration_s=30.0"])

#: Scenes left out of the default list, and why.
#: (ccd_two_wells was left out while its events rows took hours: the arrival times' cells were
#: refined past the cascade solver's own tolerance; now its reference runs in 10-33 s.)
SKIP: dict[str, str] = {}


def ladder_of(name: str, budget: dict[str, float], replicates: int, rtl: bool,
              smaller: list[str] | None = None) -> str:
    if name in HARD_CASES:
        hc = HARD_CASES[name]
        scenario, sets, budget = hc.scenario, list(hc.overrides), hc.budget
        autos = [f'run.fidelity.{hc.stage}="auto"']
        title = f"hard case {name} ({hc.scenario}): {hc.why}"
    else:
        scenario, sets = name, SMALLER.get(name, []) if smaller is None else smaller
        autos = [f'run.fidelity.{st}="auto"' for st in LEVELS]
        title = f"{name}" + (f" (smaller: {' '.join(sets)})" if sets else "")
    sets = sets + autos + [f"run.error_budget.{f}={v}" for f, v in budget.items()]
    s = load_scenario(SCENARIOS / f"{scenario}.toml", sets)
    t0 = time.perf_counter()
    pins = {} if rtl else {"dsp": "fixed"}
    ladder = run_ladder(s, replicates, pins)
    took = time.perf_counter() - t0
    return (f"## {title}\n\nbudget {budget}; reference pins {pins}; {replicates} replicates; "
            f"the ladder took "
            f"{took:.0f} s\n\n```\n{table(ladder)}\n```\n")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("names", nargs="*")
    ap.add_argument("--quick", action="store_true", help="atp_glow, 30 frames, 2 replicates")
    ap.add_argument("--replicates", type=int, default=3)
    ap.add_argument("--budget", action="append", default=[], help="figure=value")
    ap.add_argument("--rtl", action="store_true", help="reference DSP at rtl (Verilator)")
    ap.add_argument("--out", help="also append each table to this markdown file")
    args = ap.parse_args(argv)
    budget = {k: float(v) for k, v in (b.split("=") for b in args.budget)} or {"snr_rel": 0.01}
    if args.quick:
        print(ladder_of(QUICK[0], budget, 2, args.rtl, QUICK[1]))
        return 0
    names = args.names or [p.stem for p in sorted(SCENARIOS.glob("*.toml"))
                           if p.stem not in SKIP] + sorted(HARD_CASES)
    for name, why in SKIP.items():
        if name not in names:
            print(f"## {name}: not run ({why}); name it to run it anyway\n")
    for name in names:
        text = ladder_of(name, budget, args.replicates, args.rtl)
        print(text, flush=True)
        if args.out:
            with open(args.out, "a") as f:
                f.write(text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
