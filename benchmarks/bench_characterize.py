"""Benchmark: EMVA 1288 characterisation wall time, the reference chip and a 1024 × 1024 chip.

The whole protocol (``chiptwin.characterize.characterize``: 60 photon-transfer points × 4
images, 2 × 16 spatial images, 6 temperatures × 6 exposures × 2 dark images = 344 images),
evaluation included, outputs (JSON, markdown, 6 plots) timed apart:

(a) the reference chip, ``pyro_1fmol`` as configured: 8 × 16 pixels, M = 4; temporal images are
    mosaics of 128 frames (16,384 values), so 312 of the 344 images hold 16,384 pixel-frames;
(b) the same chip scaled to 1024 × 1024 pixels (every other parameter the reference's): one
    frame per image, 1.05e6 pixels × 8 samples each.

Cold (first call, numba kernels compiled or loaded from cache) and warm (median of ``--rounds``)
runs are reported with the images, the ADC samples drawn and the samples per second. Machines
here are shared and noisy: medians, not minima.

Usage: ``python benchmarks/bench_characterize.py [--quick] [--side 1024] [--rounds 3]
[--skip-large]``. ``--quick``: the reference chip only, temporal images of 1,024 values (8
frames) instead of 16,384, no warm rounds (the cold run is reported as warm too): the same code
path, a smoke run.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

from chiptwin.characterize import characterize
from chiptwin.characterize.protocol import Protocol
from chiptwin.config import load_scenario
from chiptwin.pixel.chain import available_cores

ROOT = Path(__file__).resolve().parents[1]


def scaled(side: int):
    """The reference chip with ``side`` × ``side`` pixels, frame memory sized to match."""
    s = load_scenario(ROOT / "scenarios" / "pyro_1fmol.toml")
    chip = s.chip
    frame_bits = chip.memory.word_bits * side * side * chip.samples_per_frame
    need = max(chip.dsp.n_dark_frames, chip.dsp.average_frames) * frame_bits + 16 * side * side
    mem = dataclasses.replace(chip.memory, capacity_bits=need)
    big = dataclasses.replace(chip, rows=side, cols=side, memory=mem)
    sites = dataclasses.replace(s.sites, at_pixels=[[side // 2, side // 2]])
    return dataclasses.replace(s, chip=big, sites=sites)


def samples(s, protocol: Protocol) -> int:
    """ADC samples the protocol draws on this chip (reset + signal, every image)."""
    n = s.chip.n_pixels
    tiles = protocol.tiles(n)
    per_frame = 2 * s.chip.dsp.cms_samples
    temporal = 4 * protocol.n_points + 2 * protocol.dark_exposures * len(
        protocol.temperature_offsets_C)
    return per_frame * n * (temporal * tiles + 2 * protocol.spatial_frames)


def timed(s, rounds: int, protocol: Protocol | None = None) -> dict:
    protocol = protocol or Protocol()
    t0 = time.perf_counter()
    result = characterize(s, protocol)
    cold = time.perf_counter() - t0
    warm = []
    for _ in range(rounds):
        t0 = time.perf_counter()
        result = characterize(s, protocol)
        warm.append(time.perf_counter() - t0)
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        result.write(Path(tmp) / "out")
        write_s = time.perf_counter() - t0
    n = samples(s, protocol)
    median = statistics.median(warm) if warm else cold
    return {"pixels": s.chip.n_pixels, "cms_samples": s.chip.dsp.cms_samples,
            "adc_samples": n, "cold_s": round(cold, 3), "warm_median_s": round(median, 3),
            "warm_s": [round(w, 3) for w in warm], "samples_per_s": round(n / median),
            "write_outputs_s": round(write_s, 3)}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true",
                   help="reference chip, 1,024-value images, no warm rounds")
    p.add_argument("--side", type=int, default=1024)
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--skip-large", action="store_true")
    args = p.parse_args(argv)
    protocol = Protocol(min_values=1024) if args.quick else Protocol()
    if args.quick:
        args.rounds, args.skip_large = 0, True
    report = {"cores": available_cores(),
              "reference": timed(load_scenario(ROOT / "scenarios" / "pyro_1fmol.toml"),
                                 args.rounds, protocol)}
    print(json.dumps({"reference": report["reference"]}, indent=2), flush=True)
    if not args.skip_large:
        report[f"{args.side}x{args.side}"] = timed(scaled(args.side), max(1, args.rounds - 2))
    json.dump(report, sys.stdout, indent=2)
    print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
