"""``auto`` fidelity against the reference: wall-time ratio and the error actually incurred.

For each scenario (default: pyro_1fmol) every ``[run.fidelity]`` key is set to ``auto`` with the
budget given (default ``snr_rel = 0.01``), and the levels ``auto`` picks are run side by side
with the reference (the ladder's most faithful levels; the DSP at ``fixed``, which the RTL
equals bit for bit, unless ``--rtl``; the photons at ``binned``, which has the events level's
law, unless ``--events``: the events level over the cascade takes 16-100 ms a window) on the
same seeds, warm, in this process. The speed-up is against the most faithful levels (events
photons, timed once warm) where their run is estimated within :data:`MAX_REFERENCE_S`.

Printed per scenario: the levels picked, the median warm wall time of each and their ratio, the
time ``auto`` itself took (its calibrations, first and cached), the estimated error, and the
error measured against the reference on the same seeds: per site the ratio of the means over
the seeds minus 1 (signal and power SNR), with its 95 % delta-method Student-t half-width
(:mod:`chiptwin.fidelity.compare`; never a mean of per-seed ratios, which a noisy reference
biases upward by its squared coefficient of variation), for the site whose interval reaches
furthest; and whether that shows auto's estimate bounds the error ("holds", "exceeds"), or
"unresolved at N seeds" with the count that would decide.

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
from chiptwin.fidelity.compare import RESOLUTION, Difference, ratio_of_means, worst
from chiptwin.fidelity.ladder import LEVELS, reference_levels, with_levels
from chiptwin.twin.levels import SEEN_SNR_POWER

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"
#: ``--quick``: a scene whose reference runs in about a second (atp_glow, closed-form kinetics,
#: cut to 30 frames), 2 replicates; the same code path. A pyrosequencing scene's reference runs
#: the cascade over at least the 8 key flows (seconds a run), too slow for a smoke run.
QUICK = ("atp_glow", ["run.duration_s=30.0"])


#: The most faithful levels are timed (once, warm) for the speed-up only when their run is
#: estimated within this (``chiptwin.config.cost``; pyro_array_256's would take hours). Unit: s.
MAX_REFERENCE_S = 300.0


def _unlimited(s):
    return replace(s, run=replace(s.run, max_wall_s=1e7))


def bench(name: str, budget: dict[str, float], replicates: int, rtl: bool,
          smaller: list[str] = (), photons: str = "binned") -> dict:
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
    reference = with_levels(s, {**ref_levels, "photons": photons})
    faithful = with_levels(s, ref_levels)
    run(resolved), run(reference)  # warm-up: numba caches, RTL build
    walls = {"auto": [], "reference": []}
    values = {"auto": [], "reference": []}
    for seed in range(replicates):
        for side, sv in (("auto", resolved), ("reference", reference)):
            sm = run(sv, seed=seed).summary
            walls[side].append(sm["wall_time_s"])
            values[side].append([[y["signal_e"], y["snr_power"]] for y in sm["sites"]])
    wa, wr = statistics.median(walls["auto"]), statistics.median(walls["reference"])
    if photons != ref_levels["photons"]:  # the speed-up against the most faithful levels
        wr = math.nan
        if wall_seconds(_unlimited(faithful)) <= MAX_REFERENCE_S:
            run(_unlimited(faithful))
            wr = run(_unlimited(faithful)).summary["wall_time_s"]
    estimate = choice.summary()["fidelity_error_estimate"]
    print(f"\n{name}{' (' + ' '.join(smaller) + ')' if smaller else ''}: budget {budget}")
    print(f"  auto picks    {choice.levels}")
    print(f"  reference     {ref_levels}")
    print(f"  wall (warm median of {replicates}): reference {wr:.3f} s, auto {wa:.3f} s, "
          f"speed-up {wr / wa:.1f}x; resolving auto {first:.2f} s first, {cached:.2f} s cached")
    print(f"  estimated error {estimate}")
    a, r = np.array(values["auto"]), np.array(values["reference"])  # seeds × sites × 2
    seen = r[:, :, 1].mean(axis=0) >= SEEN_SNR_POWER
    label = f"{name} ({', '.join(smaller)})" if smaller else name
    row = {"scene": label, "levels": choice.levels, "speedup": wr / wa, "n": replicates}
    for k, (figure, key) in enumerate((("signal", "signal_rel"), ("snr_power", "snr_rel"))):
        d = worst(ratio_of_means(a[:, seen, k], r[:, seen, k], family=True))
        if d is None:
            continue
        print(f"  measured {figure:9s} {verdict(d, estimate.get(key))}")
        row[key] = (d, estimate.get(key))
    return row


SHORT = {"closed_form": "cf", "cascade": "casc", "expected": "exp", "binned": "bin",
         "events": "ev", "gaussian": "gauss", "poisson": "pois", "as_built": "built"}


def markdown(rows: list[dict]) -> str:
    """The coverage table: per scene auto's levels, its estimated power-SNR error, the measured
    one with its interval, whether the measurement resolves the estimate's bound, the speed-up."""
    lines = ["| scene | auto's levels (kinetics, photons, optics, shot, dsp, adc) | estimate "
             "snr_rel | measured snr_rel (95 % t) | bound | speed-up |",
             "|---|---|---|---|---|---|"]
    for r in rows:
        levels = ", ".join(SHORT.get(v, v) for v in r["levels"].values())
        if "snr_rel" not in r:
            lines.append(f"| {r['scene']} | {levels} | – | no site seen | – | "
                         f"{_speedup(r['speedup'])} |")
            continue
        d, est = r["snr_rel"]
        v = d.bounded_by(est)
        bound = v if v != "unresolved" else f"unresolved at {d.n} seeds ({_needed(d, est)})"
        lines.append(f"| {r['scene']} | {levels} | {est:.2%} | {d.value:+.2%} ± {d.half:.2%} | "
                     f"{bound} | {_speedup(r['speedup'])} |")
    return "\n".join(lines)


def _needed(d: Difference, estimate: float) -> str:
    """The seeds that would settle an unresolved row: to decide against the estimate at this
    mean and spread where the estimate is at least the 0.1 % resolution; below it (levels that
    differ from the reference by a law auto puts near 0) a bound that small cannot be shown on
    draws that differ, and the count is the one that resolves 0.1 %."""
    if estimate >= RESOLUTION:
        need = d.seeds_to_decide(estimate)
        return f"≈ {need or '?'} would decide at this mean"
    return f"≈ {d.seeds_to_resolve(RESOLUTION) or '?'} would resolve 0.1 %"


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
    return f"{text}: estimate {estimate:.4g} {'bounds it' if v == 'holds' else 'EXCEEDED'}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenarios", nargs="*", default=["pyro_1fmol"])
    ap.add_argument("--quick", action="store_true", help="atp_glow, 30 frames, 2 replicates")
    ap.add_argument("--replicates", type=int, default=8)
    ap.add_argument("--budget", action="append", default=[],
                    help="figure=value (default snr_rel=0.01)")
    ap.add_argument("--rtl", action="store_true", help="reference DSP at rtl (Verilator)")
    ap.add_argument("--set", action="append", default=[], dest="sets",
                    help="KEY=VALUE applied to every scene named (a slow scene shortened)")
    ap.add_argument("--events", action="store_true",
                    help="the error's reference at events photons (default binned, its law)")
    args = ap.parse_args(argv)
    budget = {k: float(v) for k, v in (b.split("=") for b in args.budget)} or {"snr_rel": 0.01}
    if args.quick:
        print("\n" + markdown([bench(QUICK[0], budget, 2, args.rtl, QUICK[1])]))
        return 0
    photons = "events" if args.events else "binned"
    names = args.scenarios if args.scenarios != ["all"] else sorted(
        p.stem for p in SCENARIOS.glob("*.toml"))
    print("\n" + markdown([bench(name, budget, args.replicates, args.rtl, args.sets,
                                  photons=photons) for name in names]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
