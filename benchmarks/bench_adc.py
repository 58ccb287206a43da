"""Benchmark: the cost of the converter as built against today's ideal converter (aim: ≤ 15 %).

256 × 256 pixels, 13 bits (JSSC 2006), M = 4 reset and 4 signal samples per frame (8 conversions
per pixel per frame). Both paths that convert: the multi-core sensor chain
(:func:`chiptwin.pixel.sensor_chain`) and the run's ``binned`` path
(:func:`chiptwin.pixel.binned_codes`, chunk streams on threads). Contenders, timed in interleaved
rounds in one process (this machine is shared and noisy; medians are reported):

* ``ideal``: today's converter (``bits``, ``v_min_V`` …);
* ``chip``: one ramp for the chip (the single-slope array's own layout, and the default) with an
  INL bow of 2 LSB and DNL 0.2 LSB rms, plus offset and gain mismatch per converter: the
  transition-table lookup (one table, 390 kB with its LUT);
* ``chip+noise``: the same with comparator noise 0.5 LSB (folded into each sample's read-noise
  draw: no more draws);
* ``column``: DNL per column ramp (256 tables, 100 MB with their LUTs), the worst case: each
  conversion reads the table of its column, out of cache when neighbouring pixels' codes differ
  (this scene's are uniform over ~3000 codes).

Scenes (``--scene``): ``uniform`` (default, the worst case for the lookup's cache: 500–20000
photons per pixel, uniform, so neighbouring pixels' signal codes are unrelated) or ``dark`` (0–200
photons: a luminescence chip's usual frame, every code within ~100 LSB of the pedestal).

Usage: ``python benchmarks/bench_adc.py [--quick] [--rounds 7] [--frames 4] [--scene dark]``.
Prints one line per contender: its median and fastest times and their ratios to ``ideal``.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable

import numpy as np

from chiptwin.pixel import AsBuilt, binned_codes, build_converter, chunk_streams, sensor_chain

SIDE, BITS, M = 256, 13, 4
SENSOR = dict(
    full_well_e=2e4, ktc_e=40.0, read_noise_e=100.0, conversion_gain_uV_per_e=40.0, pedestal_V=0.05
)
_CHIP = dict(inl_max_lsb=2.0, dnl_rms_lsb=0.2, offset_sigma_lsb=0.5, gain_sigma=0.005)
SPECS = {
    "ideal": None,
    "chip": AsBuilt(**_CHIP),
    "chip+noise": AsBuilt(**_CHIP, comparator_noise_lsb=0.5),
    "column": AsBuilt(**_CHIP, ramp="column"),
}


def _adc(name: str) -> dict:
    if SPECS[name] is None:
        return dict(bits=BITS, v_min_V=0.0, v_max_V=1.0)
    conv = build_converter(
        np.random.default_rng(1),
        (SIDE, SIDE),
        bits=BITS,
        v_min_V=0.0,
        v_max_V=1.0,
        as_built=SPECS[name],
    )
    return dict(converter=conv)


def chain_run(adc: dict, photons: np.ndarray, n_frames: int) -> Callable[[], None]:
    shape = (M, *photons.shape)
    out = (np.empty(shape, np.int64), np.empty(shape, np.int64))

    def run() -> None:
        for _ in sensor_chain(
            np.random.default_rng(2),
            photons,
            n_frames=n_frames,
            qe=0.5,
            dark_e=50.0,
            n_samples=M,
            read_reset=True,
            out=out,
            **SENSOR,
            **adc,
        ):
            pass

    return run


def binned_run(adc: dict, lam: np.ndarray) -> Callable[[], None]:
    def run() -> None:
        n = lam.shape[1]
        binned_codes(
            chunk_streams(np.random.default_rng(3), n),
            lam,
            n_samples=M,
            true_cds=True,
            **SENSOR,
            **adc,
        )

    return run


def time_rounds(
    methods: dict[str, Callable[[], None]], rounds: int
) -> dict[str, tuple[float, float]]:
    """Median and fastest wall time per method over interleaved rounds (after one warm-up call
    each). On a shared machine the fastest round is the least disturbed one."""
    for run in methods.values():
        run()
    times: dict[str, list[float]] = {name: [] for name in methods}
    for _ in range(rounds):
        for name, run in methods.items():
            t0 = time.perf_counter()
            run()
            times[name].append(time.perf_counter() - t0)
    return {name: (statistics.median(ts), min(ts)) for name, ts in times.items()}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="1 frame, 3 rounds (a smoke run)")
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--frames", type=int, default=4)
    ap.add_argument("--scene", choices=("uniform", "dark"), default="uniform")
    args = ap.parse_args(argv)
    rounds, frames = (3, 1) if args.quick else (args.rounds, args.frames)
    rng = np.random.default_rng(0)
    lo, hi = (500.0, 20000.0) if args.scene == "uniform" else (0.0, 200.0)
    photons = rng.uniform(lo, hi, (SIDE, SIDE))
    lam = 0.5 * photons.reshape(1, -1).repeat(frames, axis=0) + 50.0
    adcs = {name: _adc(name) for name in SPECS}
    for label, make in (
        ("sensor_chain", lambda a: chain_run(a, photons, frames)),
        ("binned_codes", lambda a: binned_run(a, lam)),
    ):
        medians = time_rounds({name: make(adc) for name, adc in adcs.items()}, rounds)
        print(
            f"{label}: {SIDE}x{SIDE} px, {args.scene} scene, {BITS} bits, {frames} frames x "
            f"{2 * M} conversions, "
            f"median of {rounds}"
        )
        med0, min0 = medians["ideal"]
        for name, (med, fast) in medians.items():
            print(
                f"  {name:11s} median {med * 1e3:7.1f} ms (ratio {med / med0:.3f})   "
                f"fastest {fast * 1e3:7.1f} ms (ratio {fast / min0:.3f})"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
