"""Benchmark: the wall-time estimate (``chiptwin.config.cost``) against the measured, for every
bundled scene at the levels ``auto`` picks and at its reference levels.

Each row: the scene with every ``[run.fidelity]`` stage ``auto`` at ``run.error_budget.snr_rel
= 0.01`` (resolved first, so its calibrations are cached and the row times the run of the levels
picked), or at the ladder's reference levels (the DSP at ``fixed``, which the RTL equals bit for
bit, unless ``--rtl``). One warm-up run, then the median of ``--repeat`` runs' ``wall_time_s``,
beside ``cost.wall_seconds`` of the scenario that ran and the ratio estimate / measured (the aim:
within 3× either way). A row estimated past ``--max-s`` is not run: its estimate is printed with
"not run".

    python benchmarks/bench_estimates.py [NAME ...] [--levels auto reference] [--repeat 1]
    python benchmarks/bench_estimates.py --quick   # atp_glow at auto, one run
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
from dataclasses import replace
from pathlib import Path

from chiptwin.config import cost, load_scenario
from chiptwin.fidelity import resolve, run
from chiptwin.fidelity.ladder import LEVELS, reference_levels, with_levels

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"
QUICK = ("atp_glow", "auto")


def scenario_at(name: str, levels: str, rtl: bool, cache: Path, extra: list[str] = ()):
    """The scene at ``levels`` ("auto" resolved, or "reference"), with no wall-time limit."""
    sets = [*extra] + [f'run.fidelity.{st}="auto"' for st in LEVELS] + [
        "run.error_budget.snr_rel=0.01", "run.max_wall_s=1e7"]
    s = load_scenario(SCENARIOS / f"{name}.toml", sets)
    if levels == "auto":
        return resolve(s, cache)[0]
    ref = reference_levels(s)
    if not rtl and ref["dsp"] == "rtl":
        ref["dsp"] = "fixed"
    sv = with_levels(s, ref)
    return replace(sv, run=replace(sv.run, error_budget=type(sv.run.error_budget)()))


def measure(name: str, levels: str, repeat: int, rtl: bool, max_s: float, cache: Path,
            extra: list[str] = ()) -> dict:
    s = scenario_at(name, levels, rtl, cache, extra)
    terms = cost.wall_estimate(s)
    estimate = sum(t.seconds for t in terms)
    big = max(terms, key=lambda t: t.seconds).what
    row = {"name": name, "levels": levels, "estimate_s": estimate, "largest": big,
           "fidelity": {st: (s.dsp_level if st == "dsp" else getattr(s.run.fidelity, st))
                        for st in LEVELS}}
    if estimate > max_s:
        return {**row, "measured_s": None}
    run(s)  # warm: kernels compiled or loaded, the cascade's yield fit made
    from chiptwin.twin import stages

    walls = []
    for _ in range(repeat):
        stages._fitted_yield.cache_clear()  # a `chiptwin run` process fits it once
        walls.append(run(s).summary["wall_time_s"])
    measured = statistics.median(walls)
    return {**row, "measured_s": measured, "ratio": estimate / measured}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("names", nargs="*", help="bundled scenarios (default: all)")
    p.add_argument("--levels", nargs="+", default=["auto", "reference"],
                   choices=["auto", "reference"])
    p.add_argument("--repeat", type=int, default=1)
    p.add_argument("--max-s", type=float, default=600.0, help="skip rows estimated past this")
    p.add_argument("--rtl", action="store_true")
    p.add_argument("--set", action="append", default=[], dest="sets",
                   help="KEY=VALUE applied to every scene named")
    p.add_argument("--quick", action="store_true", help="atp_glow at auto, one run")
    args = p.parse_args(argv)
    if args.quick:
        pairs = [QUICK]
    else:
        names = args.names or sorted(x.stem for x in SCENARIOS.glob("*.toml"))
        pairs = [(n, lv) for n in names for lv in args.levels]
    print("estimate vs measured wall time (warm; the aim: within 3x either way)")
    print(f"{'scene':24s}{'levels':>10s}{'measured s':>11s}{'estimate s':>11s}{'ratio':>8s}"
          "  largest term")
    with tempfile.TemporaryDirectory() as tmp:
        for name, levels in pairs:
            r = measure(name, levels, max(args.repeat, 1), args.rtl, args.max_s,
                        Path(tmp) / "fid.sqlite", args.sets)
            if r["measured_s"] is None:
                print(f"{name:24s}{levels:>10s}{'not run':>11s}{r['estimate_s']:11.3g}"
                      f"{'':>8s}  {r['largest']}", flush=True)
                continue
            print(f"{name:24s}{levels:>10s}{r['measured_s']:11.3f}{r['estimate_s']:11.3f}"
                  f"{r['ratio']:7.2f}x  {r['largest']}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
