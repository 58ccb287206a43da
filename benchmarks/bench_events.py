"""The ``events`` level's filling times: the order statistic on binned's count against drawing
every arrival, side by side on the same windows.

Until 2026-11-28 the ``events`` level drew every arrival of a site pixel's window of up to
20,000 expected electrons (:func:`chiptwin.photons.arrival_times`: the light's cumulative cut
into cells refined over the cascade's dense output, one draw an arrival, QE thinning and dark
electrons merged) to count the electrons and time the well's filling. Now it takes the count the
pixel kernel draws for ``binned`` and, where the well fills, the filling time
``Λ⁻¹(Λ(T)·B)``, ``B ~ Beta(W, N − W + 1)`` (:meth:`chiptwin.twin.stages.EventPixels.fill`).
Both paths run here on one prepared scene's site pixels and windows, alternating round by round
(the baseline through the public functions, as the level used them), and print the time a
window, their ratio, and both paths' mean count a window against the light's integral.

    python benchmarks/bench_events.py [SCENARIO] [--windows 40] [--rounds 2] [--set KEY=VALUE]
    python benchmarks/bench_events.py --quick   # 5 windows, 1 round: both paths run and agree

Default: ``ccd_two_wells`` at its reference kinetics (the cascade), whose run at the events
level once did not finish in 6 minutes.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np

from chiptwin import photons
from chiptwin.config import load_scenario
from chiptwin.fidelity.ladder import reference_levels, with_levels
from chiptwin.twin import stages
from chiptwin.twin.runner import prepare

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"


def arrivals(ev: stages.EventPixels, t0: float, t1: float, rng: np.random.Generator
             ) -> np.ndarray:
    """The baseline: every arrival drawn, thinned and merged with dark electrons; the count."""
    tol = max(1e-9, 10.0 * getattr(ev.source, "accuracy_rel", 0.0))
    drawn = photons.arrival_times(ev.source, t0, t1, rng, weights=ev.weights, rel_tol=tol)
    el = photons.detected_electrons(drawn, rng, qe=ev.qe, dark_e_per_s=ev.dark)
    photons.saturation_time(el, ev.need, rng)
    return np.diff(el.offsets).astype(float)


def order_statistic(ev: stages.EventPixels, t0: float, t1: float, rng: np.random.Generator
                    ) -> np.ndarray:
    """Today's path: the count (the kernel's Poisson draw, here NumPy's of the same mean) and
    the filling time of the wells that fill."""
    counts = rng.poisson(ev.electrons_until(t0, np.full(len(ev.pixels), t1))).astype(float)
    ev.fill(t0, t1, counts)
    return counts


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenario", nargs="?", default="ccd_two_wells")
    ap.add_argument("--windows", type=int, default=40, help="windows timed per round")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--set", action="append", default=[], dest="sets")
    ap.add_argument("--quick", action="store_true", help="5 windows, 1 round (a check, not a "
                    "measure)")
    args = ap.parse_args(argv)
    if args.quick:
        args.windows, args.rounds = 5, 1
    s = load_scenario(SCENARIOS / f"{args.scenario}.toml", args.sets)
    s = with_levels(s, {**reference_levels(s), "photons": "events", "dsp": "fixed"})
    scene = prepare(s)
    ev = stages.EventPixels(scene.source, scene.coupling, stages.site_pixel_indices(s),
                            scene.sensor, np.random.default_rng(0))
    every = [scene.sch.window_s(k) for k in range(scene.sch.n_frames)]
    windows = [(a, b) for a, b in every
               if ev.electrons_until(a, np.full(len(ev.pixels), b)).sum() > 0][: args.windows]
    paths = {"every arrival": arrivals, "order statistic": order_statistic}
    took = {name: [] for name in paths}
    counts = {name: [] for name in paths}
    for r in range(args.rounds):
        for name, path in paths.items():
            rng = np.random.default_rng(r)
            t0 = time.perf_counter()
            counts[name].append([path(ev, a, b, rng) for a, b in windows])
            took[name].append((time.perf_counter() - t0) / len(windows))
    expected = np.array([ev.electrons_until(a, np.full(len(ev.pixels), b)) for a, b in windows])
    print(f"{args.scenario} {' '.join(args.sets)}: {len(ev.pixels)} site pixels, "
          f"{len(windows)} lit windows (mean {expected.sum(axis=1).mean():.4g} e⁻ a window), "
          f"{args.rounds} alternating rounds, kinetics {s.run.fidelity.kinetics}")
    for name in paths:
        c = np.array(counts[name])
        print(f"  {name:16s} {statistics.median(took[name]) * 1e3:9.3f} ms a window; mean count "
              f"{c.mean():.6g} e⁻ a pixel-window (the light's integral: {expected.mean():.6g})")
    ratio = statistics.median(took["every arrival"]) / statistics.median(took["order statistic"])
    print(f"  ratio (every arrival / order statistic): {ratio:.1f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
