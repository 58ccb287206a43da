"""Speed and error of the representative tile (``[run] tile``, :mod:`chiptwin.twin.tile`).

The whole array and the tiled run of one scenario side by side, in one process, alternating
(whole, tiled, whole, …) so that both see the same load of the shared 2-core machine: each a
complete :func:`chiptwin.twin.run` (scene preparation, the chip model, the detection, the
summary), warm (one untimed run of each first: numba's cache loaded). Printed: the median wall
time of each, their ratio, and the chip figures of both at every seed with their difference in
units of its standard error (each run's Monte Carlo standard error over its sites, combined:
the test's yardstick, ``tests/test_tile.py``).

    python benchmarks/bench_tile.py                    # pyro_array_256, 2 seeds
    python benchmarks/bench_tile.py --seeds 3 --tile 64
    python benchmarks/bench_tile.py --quick            # 128 × 128 pixels, 8 flows, 1 seed

Figures: ``called`` the fraction of sites called right, ``detected`` the fraction detected,
``snr`` the mean power SNR; ``z`` = (tiled − whole) / √(se_tiled² + se_whole²).
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np

from chiptwin.config import load_scenario
from chiptwin.twin import run, tile

ROOT = Path(__file__).resolve().parents[1] / "scenarios"
#: ``--quick``: pyro_array_256 on 128 × 128 pixels (32 × 32 sites), 8 flows of 20 s, one seed.
SITES = [f"[{r}, {c}]" for r in range(2, 128, 4) for c in range(2, 128, 4)]
QUICK = ["chip.rows=128", "chip.cols=128", f"sites.at_pixels=[{', '.join(SITES)}]",
         "assay.n_flows=8", "assay.flow_period_s=20.0", "run.duration_s=180.0"]
FIGURES = {"called": "fraction_called_right", "detected": "fraction_detected",
           "snr": "snr_power_mean"}


def _whole_se(summary: dict) -> dict[str, float]:
    """Each figure's standard error over the whole array's sites (equal weights)."""
    sites = summary["sites"]
    w = np.ones(len(sites))
    cols = {"fraction_detected": [x["detected"] for x in sites],
            "snr_power_mean": [x["snr_power"] for x in sites]}
    if "called_sequences" in summary:
        cols["fraction_called_right"] = [c == summary["true_sequence"]
                                         for c in summary["called_sequences"]]
    return {k: tile.weighted_mean(np.asarray(v, dtype=float), w)[1] for k, v in cols.items()}


def _timed(path: Path, sets: list[str], seed: int) -> tuple[float, dict]:
    s = load_scenario(path, sets, seed)
    t0 = time.perf_counter()
    summary = run(s).summary
    return time.perf_counter() - t0, summary


def bench(name: str, seeds: int, tile_value: str, sets: list[str]) -> None:
    path = ROOT / f"{name}.toml"
    tiled_sets = [*sets, f"run.tile={tile_value}"]
    seed0 = load_scenario(path, sets).scenario.seed
    _timed(path, sets, seed0), _timed(path, tiled_sets, seed0)  # warm-up: numba cache
    t_whole, t_tiled = [], []
    for k in range(seeds):
        tw, whole = _timed(path, sets, seed0 + k)
        tt, tiled = _timed(path, tiled_sets, seed0 + k)
        t_whole.append(tw)
        t_tiled.append(tt)
        se_w, se_t = _whole_se(whole), tiled["array"]["standard_error"]
        if k == 0:
            print(f"{name}: {tiled['tiled']['note']} (tiles of {tiled['tiled']['tile_pixels']} "
                  f"pixels, effective sites {tiled['tiled']['effective_sites']}, light error "
                  f"max {tiled['tiled']['light_error_rel']['max']:.3g})")
        row = []
        for label, key in FIGURES.items():
            if key not in tiled["array"]:
                continue
            a, b = whole["array"][key], tiled["array"][key]
            z = (b - a) / np.hypot(se_w[key], se_t[key])
            row.append(f"{label} {a:.4g} / {b:.4g} (z {z:+.2f})")
        print(f"  seed {seed0 + k}: whole {tw:7.2f} s  tiled {tt:6.2f} s   " + "  ".join(row))
    mw, mt = statistics.median(t_whole), statistics.median(t_tiled)
    print(f"  median over {seeds} seed(s): whole {mw:.2f} s, tiled {mt:.2f} s, "
          f"ratio {mw / mt:.1f}x")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("scenario", nargs="?", default="pyro_array_256")
    p.add_argument("--seeds", type=int, default=2, help="seeds s … s + N − 1, alternating")
    p.add_argument("--tile", default='"auto"', help='run.tile of the tiled run ("auto" or pixels)')
    p.add_argument("--quick", action="store_true", help="128 × 128 pixels, 8 flows, 1 seed")
    args = p.parse_args(argv)
    sets: list[str] = []
    if args.quick:
        sets, args.seeds = QUICK, 1
        print("quick: pyro_array_256 on 128 × 128 pixels, 8 flows")
    bench(args.scenario, args.seeds, args.tile, sets)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
