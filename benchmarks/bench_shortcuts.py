"""Speed and error of the "model only what the scene needs" shortcuts
(:mod:`chiptwin.twin.shortcuts`,
and the trace without frame steps, :class:`chiptwin.chip.trace.Recorder`).

For each bundled scenario where a shortcut applies, the full path and the shortcut run side by
side on one prepared scene, warm (one untimed run of each first, so numba's cache and the
scene's memo are loaded), in the same process: the median wall time of the chip model and the
detection (``simulate`` + ``results.detect``, what :func:`chiptwin.twin.run_prepared` times), the
ratio, and the error the shortcut actually incurs on the headline figures. The carried-dark-pixels
shortcut draws other numbers for the sites (an equality in law), so its error on a figure is shown
beside the seed-to-seed spread of the full path (full at seed s against full at seed s + 1), each
averaged over ``--seeds`` pairs: an error of that size is the Monte Carlo noise of one run, not a
bias.

    python benchmarks/bench_shortcuts.py                      # every scenario where it applies
    python benchmarks/bench_shortcuts.py pyro_1fmol --seeds 5
    python benchmarks/bench_shortcuts.py --profile             # warm stage times, before/after
    python benchmarks/bench_shortcuts.py --quick               # pyro_1fmol, 500 frames, 2 seeds

The trace without frame steps changes no number: it is timed on the same seed (simulate alone,
the chip model's share) and its outputs are checked identical.

Figures: ``signal`` median over sites of |Δ signal_e| / noise_e (in units of the site's noise);
``noise`` max relative |Δ noise_e| (moments: must be ~0); ``snr`` relative Δ of the median power
SNR; ``called`` Δ of the fraction of sites called right (pyrosequencing) or detected.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np

from chiptwin.config import load_scenario
from chiptwin.twin import shortcuts, stages
from chiptwin.twin.results import detect
from chiptwin.twin.runner import Recorder, StageTimer, prepare, simulate, stage_rng

ROOT = Path(__file__).resolve().parents[1] / "scenarios"
ALL = ("pyro_1fmol", "pyro_array_256", "pyro_paper_yield_fast", "ccd_100fmol", "atp_glow",
       "atp_dose_response", "luciferase_label", "pyro_paper_yield", "crosstalk_microarray",
       "ccd_two_wells", "snr10_requirement")
#: ``--quick``: one scene cut to 8 flows (tests/conftest.py's REDUCED), 2 seeds; the same code path.
QUICK = ("pyro_1fmol", ["assay.n_flows=8", "run.duration_s=500.0"])


def _once(s, scene, seed: int, carry: bool) -> tuple[float, dict]:
    t0 = time.perf_counter()
    out = simulate(s, scene, s.run.fidelity.photons, stage_rng(seed, "pixel"), Recorder(),
                   sites=stages.site_pixel_indices(s), carry_dark=carry)
    summary, _ = detect(s, scene, out)
    return time.perf_counter() - t0, summary


def _figures(a: dict, b: dict) -> dict[str, float]:
    sa, sb = a["sites"], b["sites"]
    noise = np.array([x["noise_e"] for x in sa])
    sig = np.abs(np.array([x["signal_e"] for x in sa]) - [x["signal_e"] for x in sb])
    called = "fraction_called_right" if "fraction_called_right" in a["array"] else (
        "fraction_detected")
    snr_a, snr_b = (statistics.median(x["snr_power"] for x in s) for s in (sa, sb))
    return {
        "signal": float(np.median(sig / noise)),
        "noise": float(np.max(np.abs(noise - [x["noise_e"] for x in sb]) / noise)),
        "snr": abs(snr_b - snr_a) / abs(snr_a) if snr_a else 0.0,
        "called": abs(b["array"][called] - a["array"][called]),
    }


def bench(name: str, seeds: int, sets: list[str] = ()) -> None:
    s = load_scenario(ROOT / f"{name}.toml", sets)
    scene = prepare(s)
    idx = np.unique(stages.site_pixel_indices(s))
    if not shortcuts.applies(s, s.run.fidelity.photons, idx, False, False):
        print(f"{name:24s} carried dark pixels: does not apply "
              f"(photons={s.run.fidelity.photons}, program={list(s.chip.dsp.program)})")
        return
    split = shortcuts.split_dark(s, scene, idx)
    if split is None:
        print(f"{name:24s} carried dark pixels: no pixel to carry ({scene.n_pixels} pixels)")
        return
    seed = s.scenario.seed
    for carry in (False, True):  # warm-up: numba cache, scene memo
        _once(s, scene, seed, carry)
    full = [_once(s, scene, seed + i, False) for i in range(seeds + 1)]
    cut = [_once(s, scene, seed + i, True) for i in range(seeds)]
    t_full = statistics.median(t for t, _ in full)
    t_cut = statistics.median(t for t, _ in cut)
    err = [_figures(full[i][1], cut[i][1]) for i in range(seeds)]
    spread = [_figures(full[i][1], full[i + 1][1]) for i in range(seeds)]
    print(f"{name:24s} drawn {len(split.drawn):6d}/{scene.n_pixels:<6d} full {t_full:8.3f} s  "
          f"carried {t_cut:7.3f} s  ratio {t_full / t_cut:6.2f}x")
    for label, rows in (("error ", err), ("seed±1", spread)):
        means = {k: statistics.fmean(r[k] for r in rows) for k in rows[0]}
        print(f"    {label}  " + "  ".join(f"{k} {v:.3g}" for k, v in means.items()))


def _chip(s, scene, steps: bool):
    t0 = time.perf_counter()
    rec = Recorder(frame_steps=steps)
    out = simulate(s, scene, s.run.fidelity.photons, stage_rng(s.scenario.seed, "pixel"), rec,
                   sites=stages.site_pixel_indices(s))
    return time.perf_counter() - t0, out, rec


def bench_steps(name: str, seeds: int, sets: list[str] = ()) -> None:
    """The trace without frame steps: the same run (same seed), full trace against compact."""
    s = load_scenario(ROOT / f"{name}.toml", sets)
    scene = prepare(s)
    for steps in (True, False):
        _chip(s, scene, steps)
    full = [_chip(s, scene, True) for _ in range(seeds)]
    cut = [_chip(s, scene, False) for _ in range(seeds)]
    t_full = statistics.median(r[0] for r in full)
    t_cut = statistics.median(r[0] for r in cut)
    (_, a, rec_a), (_, b, rec_b) = full[0], cut[0]
    same = (a.chip.occupancy == b.chip.occupancy and a.chip.dropped == b.chip.dropped
            and a.chip.end_ns == b.chip.end_ns and np.array_equal(a.value_e, b.value_e))
    print(f"{name:24s} frame steps: events {len(rec_a):8d} -> {len(rec_b):8d}  "
          f"full {t_full:8.3f} s  compact {t_cut:7.3f} s  ratio {t_full / t_cut:5.2f}x  "
          f"outputs {'identical' if same else 'DIFFER'}")


def profile(name: str, repeats: int, sets: list[str] = ()) -> None:
    """Warm ``stage_time_s`` of the run's stages (the median of ``repeats`` runs), full path
    against every shortcut that applies (carried dark pixels where it does, the trace without
    frame steps everywhere)."""
    s = load_scenario(ROOT / f"{name}.toml", sets)
    rows = {}
    for label, carry, steps in (("full", False, True), ("shortcuts", True, False)):
        runs = []
        for _ in range(1 + repeats):  # the first (cold) run is dropped
            timer = StageTimer()
            t0 = time.perf_counter()
            scene = prepare(s, timer)
            out = simulate(s, scene, s.run.fidelity.photons,
                           stage_rng(s.scenario.seed, "pixel"), Recorder(frame_steps=steps),
                           timer, sites=stages.site_pixel_indices(s), carry_dark=carry)
            with timer("detection"):
                detect(s, scene, out)
            runs.append((time.perf_counter() - t0, dict(timer.seconds)))
        rows[label] = sorted(runs[1:], key=lambda r: r[0])[len(runs[1:]) // 2]  # the median
    for label, (wall, st) in rows.items():
        stages_s = "  ".join(f"{k} {v:.3f}" for k, v in st.items())
        print(f"{name:24s} {label:9s} {wall:8.3f} s   {stages_s}")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("scenarios", nargs="*", default=list(ALL))
    p.add_argument("--quick", action="store_true", help="pyro_1fmol, 500 frames, 2 seeds")
    p.add_argument("--seeds", type=int, default=3,
                   help="pairs (full, carried) at seeds s … s + N − 1; times are their medians")
    p.add_argument("--only", choices=("carried", "steps"), help="one shortcut only")
    p.add_argument("--profile", action="store_true",
                   help="warm stage times (prepare, simulate, detect), full against shortcuts")
    args = p.parse_args(argv)
    sets: list[str] = []
    if args.quick:
        args.scenarios, sets, args.seeds = [QUICK[0]], QUICK[1], 2
        print(f"quick: {QUICK[0]} --set {' '.join(sets)}")
    for name in args.scenarios:
        if args.profile:
            profile(name, args.seeds, sets)
            continue
        if args.only != "steps":
            bench(name, args.seeds, sets)
        if args.only != "carried":
            bench_steps(name, args.seeds, sets)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
