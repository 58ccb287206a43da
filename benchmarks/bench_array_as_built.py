"""``pyro_array_256`` as built: today's path against the one before two speed-ups, side by side.

The converters as built have exact CMS moments that cost about 0.1 ms a pixel and frame; the
run reads them at its 4,096 sites only, and computes them there (``moments_read_at``). The flow
cell's coupling holds 34.6 million entries; its light is made 16 or more frames a product
(``PHOTON_CHUNK_BYTES``). The baseline turns both off in the same process (moments at every
pixel, the light a block of two frames at a time): the two paths run alternating, round by
round, on one prepared scene, and must give the same sites' figures. Full: 8 flows of 12 s,
116 frames; ``--quick``: a 64 × 64 corner with 256 sites, 8 flows of 4 s, 48 frames: a check
that both paths run and agree, not a measure (a scene that small keeps every frame's moments
for its replicates, and its coupling is dense).
Usage: ``python benchmarks/bench_array_as_built.py [--quick] [--rounds 3]``.
"""

from __future__ import annotations

import argparse
import statistics
import time
from contextlib import contextmanager
from unittest import mock

from chiptwin.config import load_scenario
from chiptwin.twin import runner, scene
from chiptwin.twin.runner import prepare, run_prepared

FULL = ["assay.n_flows=8", "assay.flow_period_s=12.0", "run.duration_s=116.0"]
QUICK = ["assay.n_flows=8", "assay.flow_period_s=4.0", "assay.start_s=16.0", "run.duration_s=48.0",
         "chip.rows=64", "chip.cols=64",
         "chip.memory.capacity_bits=16777216",
         "sites.at_pixels=[" + ", ".join(f"[{r}, {c}]" for r in range(2, 64, 4)
                                        for c in range(2, 64, 4)) + "]"]


@contextmanager
def before():
    """Moments at every pixel, the light a block at a time: the path before the speed-ups."""
    with (mock.patch.object(runner, "moments_read_at", lambda *a: None),
          mock.patch.object(scene, "PHOTON_CHUNK_BYTES", 0)):
        yield


@contextmanager
def today():
    yield


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="a 64 × 64 corner, 48 frames, 1 round")
    p.add_argument("--rounds", type=int, default=3)
    a = p.parse_args(argv)
    rounds = 1 if a.quick else a.rounds
    s = load_scenario("pyro_array_256", QUICK if a.quick else FULL)
    prepared = prepare(s)
    paths = {"today": today, "before": before}
    times: dict[str, list[float]] = {k: [] for k in paths}
    sites = {}
    for path in paths.values():  # warm: kernels loaded; a small scene keeps its moments
        with path():
            run_prepared(s, prepared)
    for _ in range(rounds):
        for name, path in paths.items():
            with path():
                t = time.perf_counter()
                result = run_prepared(s, prepared)
                times[name].append(time.perf_counter() - t)
            sites[name] = [(x["signal_e"], x["snr_power"]) for x in result.summary["sites"]]
    same = sites["today"] == sites["before"]
    size = "quick: 64 × 64, 48 frames" if a.quick else "8 flows of 12 s, 116 frames"
    print(f"pyro_array_256 as built ({size}), {s.chip.n_pixels} pixels, "
          f"{len(sites['today'])} sites, {rounds} alternating round(s)")
    for name in paths:
        print(f"  {name:7s} median {statistics.median(times[name]):.2f} s "
              f"(min {min(times[name]):.2f}, max {max(times[name]):.2f})")
    ratio = statistics.median(times["before"]) / statistics.median(times["today"])
    print(f"  before / today: {ratio:.2f}×; the sites' signal and SNR identical: {same}")
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())
