"""``auto`` fidelity against the reference: wall-time ratio and the error actually incurred.

For each scenario (default: pyro_1fmol) every ``[run.fidelity]`` key is set to ``auto`` with the
budget given (default ``snr_rel = 0.01``) and the levels ``auto`` picks are measured against the
reference (the ladder's most faithful levels; the DSP at ``fixed``, which the RTL equals bit for
bit, unless ``--rtl``), warm, in this process.

The error is measured in two parts whose sum is auto's against the reference:

* **on common random numbers**: auto's levels against the reference's levels at auto's shot
  level, on the same seeds. These runs share every draw where the levels allow it
  (:func:`chiptwin.fidelity.ladder.common_draws`: the normals always; the counts under the
  gaussian shot level whatever the light, and binned against events), so a few seeds resolve
  a 0.1 % difference: per site the ratio of the means over the seeds minus 1 (power SNR), with
  its 95 % delta-method Student-t half-width, Bonferroni over the sites
  (:mod:`chiptwin.fidelity.compare`; never a mean of per-seed ratios), for the site whose
  interval reaches furthest, against the estimate's share of every stage but the shot level;
* **the shot level** (``gaussian`` against ``poisson``), which cannot share draws with the
  Poisson counts: its share of the estimate is the rounded normal's moment bounds carried to
  the figures, a law checked by Monte Carlo (``tests/fidelity/test_shot_bound.py``), not by
  this scene's seeds.

"holds" when the first part's interval lies within the estimate less the shot level's share;
"agrees" when that estimate lies inside an interval of at most ±0.1 % (a calibrated stage's
estimate is its error on the expected level, not a bound with room); "exceeds" when the
interval lies beyond it; else "unresolved at N seeds" with the count that would decide.
The speed-up is against the reference, timed warm where estimated within
:data:`MAX_REFERENCE_S`.

    python benchmarks/bench_auto.py [SCENARIO ... | all] [--replicates N] [--budget snr_rel=0.01]
    python benchmarks/bench_auto.py --quick    # atp_glow cut to 30 frames, 2 replicates
    python benchmarks/bench_auto.py pyro_array_256 --set assay.n_flows=8 \
        --set run.duration_s=500   # a slow scene shortened (its key flows); the row says so

Ends with the coverage table (markdown) of every scene run.
"""

from __future__ import annotations

import argparse
import math
import statistics
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from chiptwin.config import load_scenario
from chiptwin.config.cost import wall_seconds
from chiptwin.fidelity import resolve, run
from chiptwin.fidelity.auto import Calibrations
from chiptwin.fidelity.compare import Difference, ratio_of_means, worst
from chiptwin.fidelity.ladder import LEVELS, common_draws, reference_levels, with_levels
from chiptwin.twin.levels import SEEN_SNR_POWER

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"
#: ``--quick``: a scene whose reference runs in about a second (atp_glow, closed-form kinetics,
#: cut to 30 frames), 2 replicates; the same code path. A pyrosequencing scene's reference runs
#: the cascade over at least the 8 key flows (seconds a run), too slow for a smoke run.
QUICK = ("atp_glow", ["run.duration_s=30.0"])


#: The reference is timed (three seeds, warm) for the speed-up only when its run is
#: estimated within this (``chiptwin.config.cost``; pyro_array_256's would take hours). Unit: s.
MAX_REFERENCE_S = 300.0


def _unlimited(s):
    return replace(s, run=replace(s.run, max_wall_s=1e7))


def bench(name: str, budget: dict[str, float], replicates: int, rtl: bool,
          smaller: list[str] = (), max_replicates: int = 0) -> dict:
    sets = [*smaller] + [f'run.fidelity.{st}="auto"' for st in LEVELS]
    sets += [f"run.error_budget.{f}={v}" for f, v in budget.items()]
    s = load_scenario(SCENARIOS / f"{name}.toml", sets)
    with tempfile.TemporaryDirectory() as cache:
        t0 = time.perf_counter()
        resolved, choice = resolve(s, Path(cache) / "fid.sqlite")
        first = time.perf_counter() - t0
        t0 = time.perf_counter()
        resolve(s, Path(cache) / "fid.sqlite")
        cached = time.perf_counter() - t0
        ref_levels = reference_levels(s)
        if not rtl and ref_levels["dsp"] == "rtl":
            ref_levels["dsp"] = "fixed"
        shot = choice.levels["shot"]
        shot_share = {} if shot == ref_levels["shot"] else Calibrations(
            s, ref_levels, Path(cache) / "fid.sqlite").estimate("shot", shot, choice.levels).errors
    reference = _unlimited(with_levels(s, ref_levels))
    paired = reference if not shot_share else _unlimited(
        with_levels(s, {**ref_levels, "shot": shot}))
    common = common_draws(choice.levels, {**ref_levels, "shot": shot})
    run(resolved), run(paired)  # warm-up: numba caches, RTL build
    walls = {"auto": [], "paired": []}
    values = {"auto": [], "paired": []}
    rest = max(0.0, choice.estimate.get("snr_rel", math.inf) - float(
        shot_share.get("snr_rel", 0.0)))  # the estimate's share of every stage but the shot's

    def measure(seeds: range) -> Difference | None:
        for seed in seeds:
            for side, sv in (("auto", resolved), ("paired", paired)):
                sm = run(sv, seed=seed).summary
                walls[side].append(sm["wall_time_s"])
                values[side].append([y["snr_power"] for y in sm["sites"]])
        a, r = np.array(values["auto"]), np.array(values["paired"])  # seeds × sites
        seen = r.mean(axis=0) >= SEEN_SNR_POWER
        return worst(ratio_of_means(a[:, seen], r[:, seen], family=True))

    d = measure(range(replicates))
    # a pilot of `replicates` seeds sizes the run that decides (two-stage, Stein 1945): the
    # interval is then the ordinary one over all seeds
    if (d is not None and max_replicates > replicates and math.isfinite(rest)
            and d.bounded_by(rest) == "unresolved"):
        need = d.seeds_to_decide(rest)
        if need is not None and need <= max_replicates:
            d = measure(range(replicates, math.ceil(1.2 * need)))
    wa = statistics.median(walls["auto"])
    wr = statistics.median(walls["paired"]) if paired is reference else math.nan
    if paired is not reference and wall_seconds(reference) <= MAX_REFERENCE_S:
        run(reference)
        wr = statistics.median(run(reference, seed=k).summary["wall_time_s"] for k in range(3))
    estimate = choice.summary()["fidelity_error_estimate"]
    print(f"\n{name}{' (' + ' '.join(smaller) + ')' if smaller else ''}: budget {budget}")
    print(f"  auto picks    {choice.levels}")
    print(f"  reference     {ref_levels}")
    print(f"  wall (warm median): reference {wr:.3f} s, auto {wa:.3f} s, speed-up "
          f"{wr / wa:.1f}x; resolving auto {first:.2f} s first, {cached:.2f} s cached")
    print(f"  estimated error {estimate}; the shot level's share {shot_share.get('snr_rel', 0)}")
    label = f"{name} ({', '.join(smaller)})" if smaller else name
    row = {"scene": label, "levels": choice.levels, "speedup": wr / wa,
           "n": len(values["auto"]), "common": common,
           "shot_share": float(shot_share.get("snr_rel", 0.0))}
    if d is not None and math.isfinite(rest):
        print(f"  measured snr_power against the reference at auto's shot level "
              f"({'common' if common else 'independent'} draws): {verdict(d, rest)}")
        row["snr_rel"] = (d, choice.estimate["snr_rel"], rest)
    return row


SHORT = {"closed_form": "cf", "cascade": "casc", "expected": "exp", "binned": "bin",
         "events": "ev", "gaussian": "gauss", "poisson": "pois", "as_built": "built"}


def markdown(rows: list[dict]) -> str:
    """The coverage table: per scene auto's levels, its estimated power-SNR error and the shot
    level's share of it (a law), the rest measured on common numbers with its interval, whether
    that resolves the estimate's bound, the speed-up."""
    lines = ["| scene | auto's levels (kinetics, photons, optics, shot, dsp, adc) | estimate "
             "snr_rel | of it the shot level (law) | measured, auto vs the reference at "
             "auto's shot level (95 % t, Bonferroni) | bound | speed-up |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        levels = ", ".join(SHORT.get(v, v) for v in r["levels"].values())
        if "snr_rel" not in r:
            lines.append(f"| {r['scene']} | {levels} | – | – | no site seen | – | "
                         f"{_speedup(r['speedup'])} |")
            continue
        d, est, rest = r["snr_rel"]
        v = d.bounded_by(rest)
        bound = v if v != "unresolved" else f"unresolved at {d.n} seeds ({_needed(d, rest)})"
        how = "" if r["common"] else " (independent draws)"
        lines.append(f"| {r['scene']} | {levels} | {est:.2g} | {r['shot_share']:.2g} | "
                     f"{d.value:+.3%} ± {d.half:.3%}{how} | {bound} | "
                     f"{_speedup(r['speedup'])} |")
    return "\n".join(lines)


def _needed(d: Difference, estimate: float) -> str:
    """The seeds that would settle an unresolved row at this mean and spread (to decide against
    the estimate, or to narrow the interval to the 0.1 % resolution)."""
    return f"≈ {d.seeds_to_decide(estimate) or '?'} would decide"


def _speedup(x: float) -> str:
    return f"{x:.3g}×" if math.isfinite(x) else f"not timed (reference > {MAX_REFERENCE_S:g} s)"


def verdict(d: Difference, estimate: float | None) -> str:
    """The measured difference, its interval and what it shows of the estimate."""
    text = (f"{d.value:+.4f} ± {d.half:.4f} ({d.method}, n = {d.n}, the site reaching "
            "furthest)")
    if estimate is None:
        return text
    v = d.bounded_by(estimate)
    if v == "unresolved":
        return (f"{text}: unresolved at {d.n} seeds against the estimate {estimate:.4g} "
                f"({_needed(d, estimate)})")
    said = {"holds": "bounds it", "agrees": "lies inside the interval (agrees)",
            "exceeds": "EXCEEDED"}[v]
    return f"{text}: estimate {estimate:.4g} {said}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenarios", nargs="*", default=["pyro_1fmol"])
    ap.add_argument("--quick", action="store_true", help="atp_glow, 30 frames, 2 replicates")
    ap.add_argument("--replicates", type=int, default=8)
    ap.add_argument("--max-replicates", type=int, default=0,
                    help="an unresolved scene runs on to the seeds that decide, up to this many")
    ap.add_argument("--budget", action="append", default=[],
                    help="figure=value (default snr_rel=0.01)")
    ap.add_argument("--rtl", action="store_true", help="reference DSP at rtl (Verilator)")
    ap.add_argument("--set", action="append", default=[], dest="sets",
                    help="KEY=VALUE applied to every scene named (a slow scene shortened)")
    args = ap.parse_args(argv)
    budget = {k: float(v) for k, v in (b.split("=") for b in args.budget)} or {"snr_rel": 0.01}
    if args.quick:
        print("\n" + markdown([bench(QUICK[0], budget, 2, args.rtl, QUICK[1])]))
        return 0
    names = args.scenarios if args.scenarios != ["all"] else sorted(
        p.stem for p in SCENARIOS.glob("*.toml"))
    print("\n" + markdown([bench(name, budget, args.replicates, args.rtl, args.sets,
                                  args.max_replicates) for name in names]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
