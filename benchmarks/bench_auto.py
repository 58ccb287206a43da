"""``auto`` fidelity against the reference: wall-time ratio and the error actually incurred.

For each scenario (default: pyro_1fmol) every ``[run.fidelity]`` key is set to ``auto`` with the
budget given (default ``snr_rel = 0.01``, issue 9's aim), and the levels ``auto`` picks are run
side by side with the reference (the ladder's most faithful levels; the DSP at ``fixed``, which
the RTL equals bit for bit, unless ``--rtl``) on the same seeds, warm, in this process.

Printed per scenario: the levels picked, the median warm wall time of each and their ratio, the
time ``auto`` itself took (its calibrations, first and cached), the estimated error, and the
error measured against the reference: the mean over seeds of each site's relative difference
(systematic, with its 95 % half-width; the two sides may draw differently, so each seed's
difference holds noise) and the largest per-seed difference (noise included).

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
from chiptwin.fidelity.ladder import LEVELS, reference_levels, with_levels

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
    diffs = {"signal": [], "snr_power": []}
    seen = None  # the sites the first reference run detects (power SNR ≥ 10)
    for seed in range(replicates):
        a = run(resolved, seed=seed).summary
        r = run(reference, seed=seed).summary
        walls["auto"].append(a["wall_time_s"])
        walls["reference"].append(r["wall_time_s"])
        seen = seen or [i for i, y in enumerate(r["sites"]) if y["snr_power"] >= 10]
        for key, out in (("signal_e", "signal"), ("snr_power", "snr_power")):
            diffs[out].append([a["sites"][i][key] / r["sites"][i][key] - 1 for i in seen])
    wa, wr = statistics.median(walls["auto"]), statistics.median(walls["reference"])
    print(f"\n{name}{' (' + ' '.join(smaller) + ')' if smaller else ''}: budget {budget}")
    print(f"  auto picks    {choice.levels}")
    print(f"  reference     {ref_levels}")
    print(f"  wall (warm median of {replicates}): reference {wr:.3f} s, auto {wa:.3f} s, "
          f"speed-up {wr / wa:.1f}x; resolving auto {first:.2f} s first, {cached:.2f} s cached")
    print(f"  estimated error {choice.summary()['fidelity_error_estimate']}")
    for figure, d in diffs.items():
        d = np.array(d)
        if d.size == 0:
            continue
        mean = d.mean(axis=0)
        half = 1.96 * d.std(axis=0, ddof=1) / np.sqrt(len(d))
        worst = int(np.argmax(np.abs(mean)))
        print(f"  measured {figure:9s} systematic {mean[worst]:+.4f} ± {half[worst]:.4f} "
              f"(worst site), largest single-seed |diff| {np.max(np.abs(d)):.4f}")


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
