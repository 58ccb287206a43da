"""``auto`` fidelity against the reference: wall-time ratio and the error actually incurred.

For each scenario (default: pyro_1fmol) every ``[run.fidelity]`` key is set to ``auto`` with the
budget given (default ``snr_rel = 0.01``, issue 9's aim), and the levels ``auto`` picks are run
side by side with the reference (the ladder's most faithful levels; the DSP at ``fixed``, which
the RTL equals bit for bit, unless ``--rtl``) on the same seeds, warm, in this process.

Printed per scenario: the levels picked, the median warm wall time of each and their ratio, the
time ``auto`` itself took (its calibrations, first and cached), the estimated error, and the
error measured against the reference on the same seeds: per site the ratio of the means over
the seeds minus 1 (signal and power SNR), with its 95 % delta-method Student-t half-width
(:mod:`chiptwin.fidelity.compare`; never a mean of per-seed ratios, which a noisy reference
biases upward by its squared coefficient of variation), for the site whose interval reaches
furthest; and whether that shows auto's estimate bounds the error ("holds", "exceeds"), or
"unresolved at N seeds" with the count that would decide.

    python benchmarks/bench_auto.py [SCENARIO ...] [--replicates N] [--budget snr_rel=0.01]
    python benchmarks/bench_auto.py --quick    # atp_glow cut to 30 frames, 2 replicates
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from chiptwin.config import load_scenario
from chiptwin.fidelity import resolve, run
from chiptwin.fidelity.compare import Difference, ratio_of_means, worst
from chiptwin.fidelity.ladder import LEVELS, reference_levels, with_levels
from chiptwin.twin.levels import SEEN_SNR_POWER

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"
#: ``--quick``: a scene whose reference runs in about a second (atp_glow, closed-form kinetics,
#: cut to 30 frames), 2 replicates; the same code path. A pyrosequencing scene's reference runs
#: the cascade over at least the 8 key flows (seconds a run), too slow for a smoke run.
QUICK = ("atp_glow", ["run.duration_s=30.0"])


def bench(name: str, budget: dict[str, float], replicates: int, rtl: bool,
          smaller: list[str] = ()) -> None:
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
    reference = with_levels(s, ref_levels)
    run(resolved), run(reference)  # warm-up: numba caches, RTL build
    walls = {"auto": [], "reference": []}
    values = {"auto": [], "reference": []}
    for seed in range(replicates):
        for side, sv in (("auto", resolved), ("reference", reference)):
            sm = run(sv, seed=seed).summary
            walls[side].append(sm["wall_time_s"])
            values[side].append([[y["signal_e"], y["snr_power"]] for y in sm["sites"]])
    wa, wr = statistics.median(walls["auto"]), statistics.median(walls["reference"])
    estimate = choice.summary()["fidelity_error_estimate"]
    print(f"\n{name}{' (' + ' '.join(smaller) + ')' if smaller else ''}: budget {budget}")
    print(f"  auto picks    {choice.levels}")
    print(f"  reference     {ref_levels}")
    print(f"  wall (warm median of {replicates}): reference {wr:.3f} s, auto {wa:.3f} s, "
          f"speed-up {wr / wa:.1f}x; resolving auto {first:.2f} s first, {cached:.2f} s cached")
    print(f"  estimated error {estimate}")
    a, r = np.array(values["auto"]), np.array(values["reference"])  # seeds × sites × 2
    seen = r[:, :, 1].mean(axis=0) >= SEEN_SNR_POWER
    for k, (figure, key) in enumerate((("signal", "signal_rel"), ("snr_power", "snr_rel"))):
        d = worst(ratio_of_means(a[:, seen, k], r[:, seen, k]))
        if d is None:
            continue
        print(f"  measured {figure:9s} {verdict(d, estimate.get(key))}")


def verdict(d: Difference, estimate: float | None) -> str:
    """The measured difference, its interval and what it shows of the estimate."""
    text = (f"{d.value:+.4f} ± {d.half:.4f} (ratio of means, 95 % t, n = {d.n}, the site "
            "reaching furthest)")
    if estimate is None:
        return text
    v = d.bounded_by(estimate)
    if v == "unresolved":
        need = d.seeds_to_decide(estimate)
        return (f"{text}: unresolved at {d.n} seeds against the estimate {estimate:.4g} "
                f"(≈ {need if need else '?'} seeds would decide)")
    return f"{text}: estimate {estimate:.4g} {'bounds it' if v == 'holds' else 'EXCEEDED'}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenarios", nargs="*", default=["pyro_1fmol"])
    ap.add_argument("--quick", action="store_true", help="atp_glow, 30 frames, 2 replicates")
    ap.add_argument("--replicates", type=int, default=8)
    ap.add_argument("--budget", action="append", default=[],
                    help="figure=value (default snr_rel=0.01)")
    ap.add_argument("--rtl", action="store_true", help="reference DSP at rtl (Verilator)")
    args = ap.parse_args(argv)
    budget = {k: float(v) for k, v in (b.split("=") for b in args.budget)} or {"snr_rel": 0.01}
    if args.quick:
        bench(QUICK[0], budget, 2, args.rtl, QUICK[1])
        return 0
    for name in args.scenarios:
        bench(name, budget, args.replicates, args.rtl)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
