"""Benchmark: reading a measured EMVA 1288 data set, descriptor to per-step statistics.

Times, on the real reference set ``set001_ccd_12bit_crop128`` (a Basler 12-bit CCD cropped to
128 × 128 pixels: 50 photon-transfer points, each a bright and a dark pair, and a bright and a
dark stack of 50 images; 300 PNG images):

1. ``read_descriptor``: the descriptor parsed and checked, each image's existence checked;
2. every image loaded and checked (``load_image``: Pillow, size, values within the bits);
3. the statistics: ``pair_stats`` of every temporal pair, a ``StackAccumulator`` of each stack;
4. the whole path a user takes, ``characterize_measured`` (read, statistics and the evaluation
   into the datasheet), beside the ``emva1288`` reference implementation's parser, loader and
   ``Results1288`` on the same folder, alternating, as the baseline (when it is installed: the
   test extra).

Minimum and median over ``--rounds`` (the machine is shared and noisy), with images per second.

Usage: ``python benchmarks/bench_measured_read.py [--descriptor PATH] [--rounds 3] [--quick]``.
``--descriptor``: a data-set folder or its ``EMVA1288_Data.txt``; the default is the shared
reference set beside the repository, and a missing set ends the script with a message.
``--quick``: one round; when the default set is absent (a checkout without the shared data), a
small synthetic set written by ``write_descriptor`` (32 × 32 pixels, 12 bits, 5 points, stacks
of 8) is read instead: the same code path, a smoke run.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from chiptwin.characterize.descriptor import Descriptor, load_image, read_descriptor
from chiptwin.characterize.descriptor_write import write_descriptor
from chiptwin.characterize.estimators import StackAccumulator, pair_stats

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("CHIPTWIN_DATA") or ROOT.parent / "shared" / "data" / "real")
DEFAULT = DATA / "emva1288" / "set001_ccd_12bit_crop128"


def load_all(d: Descriptor) -> dict[Path, np.ndarray]:
    """Every image of every step, loaded and checked, by path."""
    return {p: load_image(d, p) for s in d.steps for p in s.images}


def statistics_of(d: Descriptor, images: dict[Path, np.ndarray]) -> int:
    """``pair_stats`` of every temporal step and the accumulated stacks; the steps done."""
    done = 0
    for _, _, bright, dark in d.temporal_points():
        for step in (bright, dark):
            pair_stats(*(images[p] for p in step.images))
            done += 1
    for step in d.spatial() or ():
        acc = StackAccumulator()
        for p in step.images:
            acc.add(images[p])
        acc.result()
        done += 1
    return done


def synthetic(folder: Path) -> Path:
    """A small data set (32 × 32, 12 bits, 5 points, stacks of 8) written for the smoke run."""
    rng = np.random.default_rng(0)

    def imgs(n: int, mean: float) -> list[np.ndarray]:
        return [rng.poisson(mean, (32, 32)).astype(np.uint16) for _ in range(n)]

    steps = []
    for k, t in enumerate((1e5, 2e5, 4e5, 8e5, 1.6e6)):
        steps += [("b", t, 100.0 * (k + 1), imgs(2, 100.0 * (k + 1))), ("d", t, 0.0, imgs(2, 50))]
    steps += [("b", 4e5, 300.0, imgs(8, 300.0)), ("d", 4e5, 0.0, imgs(8, 50.0))]
    return write_descriptor(folder / "synthetic", bits=12, width=32, height=32, steps=steps,
                            header="bench_measured_read --quick: a synthetic set")


def one_round(path: Path) -> tuple[dict[str, float], Descriptor, int]:
    """Seconds of each stage, the descriptor, the images loaded."""
    took = {}
    t0 = time.perf_counter()
    d = read_descriptor(path)
    t1 = time.perf_counter()
    images = load_all(d)
    t2 = time.perf_counter()
    statistics_of(d, images)
    t3 = time.perf_counter()
    took.update(read=t1 - t0, load=t2 - t1, stats=t3 - t2, total=t3 - t0)
    from chiptwin.characterize.measured import characterize_measured

    t4 = time.perf_counter()
    characterize_measured(path)
    took["chiptwin"] = time.perf_counter() - t4
    reference = emva1288_seconds(d)
    if reference is not None:
        took["emva1288"] = reference
    return took, d, len(images)


def emva1288_seconds(d: Descriptor) -> float | None:
    """The reference implementation on the same folder (None when it is not installed)."""
    import logging

    try:
        from emva1288.process import data, loader, parser, results
    except ImportError:
        return None
    name = "asfarray"  # emva1288 1.0.2 calls np.asfarray, which NumPy 2 removed
    added = not hasattr(np, name)
    if added:
        setattr(np, name, lambda a, dtype=np.float64: np.asarray(a, dtype=dtype))
    try:
        t0 = time.perf_counter()
        desc = parser.ParseEmvaDescriptorFile(str(d.path), loglevel=logging.WARNING)
        imgs = loader.LoadImageData(desc.images, loglevel=logging.WARNING)
        r = results.Results1288(data.Data1288(imgs.data).data, pixel_area=None)
        _ = (r.K, r.QE, r.sigma_d, r.u_e_sat, r.DSNU1288, r.PRNU1288, r.LE_min)
        return time.perf_counter() - t0
    finally:
        if added:
            delattr(np, name)


def report(path: Path, rounds: int) -> None:
    runs = [one_round(path) for _ in range(rounds)]
    d, n_images = runs[0][1], runs[0][2]
    spatial = d.spatial()
    stacks = f", stacks of {len(spatial[0].images)}" if spatial else ""
    print(f"{d.path}: {d.width} x {d.height} px, {d.bits} bits, {len(d.steps)} steps "
          f"({len(d.temporal_points())} temporal points{stacks}), {n_images} images; "
          f"{rounds} round(s)")
    for stage, what in (("read", "read_descriptor"), ("load", "load every image"),
                        ("stats", "pair_stats + stacks"), ("total", "total"),
                        ("chiptwin", "read + evaluate"), ("emva1288", "emva1288 (baseline)")):
        times = [r[0][stage] for r in runs if stage in r[0]]
        if not times:
            continue
        print(f"  {what:20s} min {min(times) * 1e3:9.2f} ms   median "
              f"{statistics.median(times) * 1e3:9.2f} ms")
    if "emva1288" in runs[0][0]:
        ratio = statistics.median(r[0]["chiptwin"] / r[0]["emva1288"] for r in runs)
        print(f"  read + evaluate takes {ratio:.2f}x emva1288's time (median of per-round "
              "ratios; chiptwin also computes every standard error from fourth moments)")
    load = statistics.median(r[0]["load"] for r in runs)
    print(f"  {n_images / load:.0f} images/s loaded ({load / n_images * 1e6:.0f} µs an image)")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--descriptor", type=Path, default=None,
                    help="a data-set folder or its EMVA1288_Data.txt (default: the shared set001)")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--quick", action="store_true", help="one round; a synthetic set when the "
                    "default set is absent (a check, not a measure)")
    args = ap.parse_args(argv)
    if args.quick:
        args.rounds = 1
    path = args.descriptor or DEFAULT
    if path.exists():
        report(path, args.rounds)
        return 0
    if args.descriptor is not None or not args.quick:
        sys.exit(f"bench_measured_read: needs {path} (a data-set folder or its "
                 "EMVA1288_Data.txt); give another with --descriptor PATH")
    print(f"{path} is absent: reading a synthetic set instead (--quick)")
    with tempfile.TemporaryDirectory() as tmp:
        report(synthetic(Path(tmp)), args.rounds)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
