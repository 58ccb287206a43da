"""Benchmark: the sensor chain on 1024 × 1024 pixels × 10 frames, side by side in one run.

Shot noise (one merged Poisson draw per pixel of QE·PRNU·photons + DSNU·dark), full-well clip,
read noise, conversion gain, 12-bit ADC; one read per frame (Pyxel's CMOS chain). Contenders,
timed in interleaved rounds (this machine is shared and noisy; medians are reported):

(a) floor: one bare ``Generator.poisson`` call drawing all 1.05e7 counts at the same means
    (and the same on NumPy's SFC64 bit generator, which the fast path's streams use);
(b) plain numpy, frame by frame: the same physics with whole-array numpy calls;
(c) ``chiptwin.pixel.sensor_chain``, exact Poisson, all cores (and on one thread, for scaling);
(d) ``sensor_chain(shot_noise="gaussian")``: a named approximation, with its error measured.

Peak memory is measured separately with tracemalloc (NumPy's allocations are traced). Reference,
not run here: Pyxel 3.0.2 takes 7.7 s and 1.5 GB for this workload (REFERENCE §6).

Usage: ``python benchmarks/bench_sensor_chain.py [--side 1024] [--frames 10] [--rounds 5]``.
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import sys
import time
import tracemalloc
from collections.abc import Callable

import numba
import numpy as np
from scipy.special import ndtr
from scipy.stats import poisson

from chiptwin.pixel import adc_convert, fixed_pattern_maps, sensor_chain, to_volts
from chiptwin.pixel.chain import available_cores

PYXEL_S, PYXEL_GB = 7.7, 1.5  # REFERENCE §6, Pyxel 3.0.2, same workload, 2-core machine

CHIP = dict(
    qe=0.6,
    full_well_e=20_000.0,
    read_noise_e=5.0,
    conversion_gain_uV_per_e=40.0,
    pedestal_V=0.05,
    bits=12,
    v_min_V=0.0,
    v_max_V=1.0,
)


def make_scene(side: int, seed: int = 2024) -> dict[str, np.ndarray]:
    """A fixed non-flat scene: photons 500–5000 per pixel per frame, 1 % PRNU, 10 % DSNU."""
    rng = np.random.default_rng(seed)
    photons = rng.uniform(500.0, 5000.0, (side, side))
    gain, dark = fixed_pattern_maps(rng, side * side, 0.01, 0.1)
    gain, dark_e = gain.reshape(side, side), 50.0 * dark.reshape(side, side)
    lam = CHIP["qe"] * gain * photons + dark_e
    return {"photons": photons, "gain": gain, "dark_e": dark_e, "lam": lam}


def floor(rng: np.random.Generator, scene: dict, n_frames: int) -> None:
    """(a) One bare Poisson draw over all n_frames × pixels values (default PCG64 generator)."""
    rng.poisson(scene["lam"], size=(n_frames, *scene["lam"].shape))


def floor_sfc64(rng: np.random.Generator, scene: dict, n_frames: int) -> None:
    """(a') The same with NumPy's SFC64 bit generator, the one the fast path's streams use."""
    floor(np.random.Generator(np.random.SFC64(rng.integers(2**63))), scene, n_frames)


def plain_numpy(rng: np.random.Generator, scene: dict, n_frames: int) -> None:
    """(b) The same physics with whole-array numpy calls, frame by frame."""
    for _ in range(n_frames):
        lam = CHIP["qe"] * scene["gain"] * scene["photons"] + scene["dark_e"]
        electrons = np.minimum(rng.poisson(lam), CHIP["full_well_e"])
        electrons = electrons + CHIP["read_noise_e"] * rng.standard_normal(lam.shape)
        volts = to_volts(electrons, CHIP["conversion_gain_uV_per_e"], CHIP["pedestal_V"])
        adc_convert(volts, CHIP["bits"], CHIP["v_min_V"], CHIP["v_max_V"])


def fast(n_threads: int | None, shot_noise: str = "poisson") -> Callable:
    """(c)/(d) sensor_chain into reused buffers."""

    def run(rng: np.random.Generator, scene: dict, n_frames: int) -> None:
        shape = (1, *scene["photons"].shape)
        out = (np.empty((0, *shape[1:]), np.int64), np.empty(shape, np.int64))
        frames = sensor_chain(
            rng,
            scene["photons"],
            n_frames=n_frames,
            gain_map=scene["gain"],
            dark_e=scene["dark_e"],
            n_threads=n_threads,
            shot_noise=shot_noise,
            out=out,
            **CHIP,
        )
        for _ in frames:
            pass

    return run


def time_rounds(methods: dict[str, Callable], scene: dict, n_frames: int, rounds: int) -> dict:
    """Median wall time per method over interleaved rounds."""
    times: dict[str, list[float]] = {name: [] for name in methods}
    rng = np.random.default_rng(7)
    for _ in range(rounds):
        for name, run in methods.items():
            t0 = time.perf_counter()
            run(rng, scene, n_frames)
            times[name].append(time.perf_counter() - t0)
    return {name: statistics.median(ts) for name, ts in times.items()}


def peak_memory_mb(run: Callable, scene: dict, n_frames: int) -> float:
    """Peak traced allocation of one run, beyond what existed before it. Unit: MB."""
    tracemalloc.start()
    run(np.random.default_rng(8), scene, n_frames)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return peak / 1e6


def gaussian_error(lam: float) -> dict[str, float]:
    """Total-variation distance between Poisson(λ) and max(0, rint(λ + √λ·z)), exactly, and the
    skewness the approximation drops (Poisson: 1/√λ)."""
    sd = np.sqrt(lam)
    k = np.arange(max(0, int(lam - 40 * sd)), int(lam + 40 * sd) + 1)
    q = ndtr((k + 0.5 - lam) / sd) - ndtr((k - 0.5 - lam) / sd)
    q[k == 0] = ndtr((0.5 - lam) / sd)
    tv = 0.5 * np.abs(poisson.pmf(k, lam) - q).sum()
    return {"lam": lam, "tv_distance": float(tv), "poisson_skewness": float(1 / sd)}


def sampled_moments(shot_noise: str, lam: float, n: int = 2_000_000) -> list[float]:
    """Mean, variance and skewness of n drawn counts (via codes at 1 e⁻ per LSB, no read noise)."""
    chip = CHIP | {
        "read_noise_e": 0.0,
        "conversion_gain_uV_per_e": 1.0,
        "pedestal_V": 0.0,
        "bits": 24,
        "v_max_V": 2.0**24 * 1e-6,
        "full_well_e": 1e9,
    }
    _, codes = next(
        sensor_chain(
            np.random.default_rng(9),
            np.full(n, lam / chip["qe"]),
            n_frames=1,
            dark_e=0.0,
            shot_noise=shot_noise,
            gaussian_min_mean_e=100.0,
            **chip,
        )
    )
    x = codes.ravel().astype(float)
    d = x - x.mean()
    return [float(x.mean()), float(x.var()), float((d**3).mean() / x.var() ** 1.5)]


def report(times: dict, memory: dict, n_values: int, cold_s: float) -> dict:
    """Print the comparison table; return it as a dict."""
    a, b = times["a_floor"], times["b_plain_numpy"]
    print(f"{'contender':28s} {'median s':>9s} {'vs (a)':>7s} {'vs (b)':>7s} {'peak MB':>8s}")
    for name, t in times.items():
        print(f"{name:28s} {t:9.3f} {t / a:7.2f} {t / b:7.2f} {memory[name]:8.1f}")
    c = times["c_sensor_chain"]
    print(
        f"{'Pyxel 3.0.2 (REFERENCE §6)':28s} {PYXEL_S:9.3f} {'':7s} {'':7s} {PYXEL_GB * 1e3:8.0f}"
    )
    print(
        f"(c) vs Pyxel: {PYXEL_S / c:.1f}x faster, {PYXEL_GB * 1e3 / memory['c_sensor_chain']:.0f}x"
        f" less memory; aim (c) ≤ 1.3 × (a): {'met' if c <= 1.3 * a else 'NOT met'}"
        f" ({c / a:.2f}); {n_values / c / 1e6:.1f} M pixel-frames/s"
    )
    print(f"first call of sensor_chain (JIT load or compile): {cold_s:.2f} s")
    return {
        "median_s": times,
        "peak_MB": memory,
        "ratio_c_vs_a": c / a,
        "ratio_c_vs_b": c / b,
        "cold_call_s": cold_s,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--side", type=int, default=1024)
    parser.add_argument("--frames", type=int, default=10)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--json", help="also write the results here")
    args = parser.parse_args(argv)
    print(
        f"cores available: {available_cores()}; numpy {np.__version__}; numba {numba.__version__}"
    )
    scene = make_scene(args.side)
    t0 = time.perf_counter()
    fast(None)(np.random.default_rng(0), make_scene(8), 1)
    cold_s = time.perf_counter() - t0
    methods = {
        "a_floor": floor,
        "a2_floor_sfc64": floor_sfc64,
        "b_plain_numpy": plain_numpy,
        "c_sensor_chain": fast(None),
        "c1_sensor_chain_1_thread": fast(1),
        "d_sensor_chain_gaussian": fast(None, "gaussian"),
    }
    print(f"{args.side}×{args.side} pixels × {args.frames} frames, {args.rounds} rounds")
    times = time_rounds(methods, scene, args.frames, args.rounds)
    memory = {name: peak_memory_mb(run, scene, args.frames) for name, run in methods.items()}
    result = report(times, memory, args.side**2 * args.frames, cold_s)
    errors = [gaussian_error(lam) for lam in (1000.0, 1e4)]
    moments = {lv: sampled_moments(lv, 1000.0) for lv in ("poisson", "gaussian")}
    for e in errors:
        print(
            f"gaussian level at λ = {e['lam']:g}: total-variation distance {e['tv_distance']:.4f}"
            f" (drops skewness {e['poisson_skewness']:.4f})"
        )
    for lv, (m, v, s) in moments.items():
        print(f"  2e6 draws at λ = 1000, {lv:8s}: mean {m:.2f}, variance {v:.1f}, skewness {s:.4f}")
    result |= {
        "gaussian_error": errors,
        "gaussian_sampled_moments": moments,
        "max_rss_MB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3,
    }
    print(f"process peak RSS: {result['max_rss_MB']:.0f} MB")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump(result, fh, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
