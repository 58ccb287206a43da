"""Benchmark: one replicate of a study point, warm, in one process, against a frame-by-frame reader.

A budget study prepares a point once (``chiptwin.twin.prepare``) and runs thousands of replicates
(``run_prepared`` with another ``scenario.seed``). This times, for ``pyro_1fmol`` (binned photons,
float DSP, 8 × 16 pixels, 1520 frames):

* ``run()`` (prepare + run_prepared) and ``run_prepared`` on one prepared scene, as they are
  (the chip model's reader draws a block of frames' codes in one ``pixel.binned_codes`` call;
  its counts and noise on one stream per chunk here, as the public functions draw them);
* the same two with a frame-by-frame reader patched in (the "frame" rows): the reader of
  ``chiptwin.twin.runner`` with its draw replaced by the public, checked ``sample_frame`` →
  ``to_volts`` → ``adc_convert`` called once per frame on the same stream, the path
  ``binned_codes`` replaced. It needs one stream (at most ``pixel.CHUNK_PIXELS`` pixels) and
  Poisson shot noise (other scenes are refused) and the ideal ADC (a converter as built fails
  the bit-for-bit check below).

Both paths run the same seeds in interleaved rounds (the machine is shared; medians are reported),
and every pair is checked bit for bit (summary without timings, every array, the trace).

Usage: ``python benchmarks/bench_replicate.py [--quick] [--repeat 7] [--scenario PATH]``;
``--quick``: 2 seeds of pyro_1fmol cut to 8 flows (500 s), the same code path.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import statistics
import time
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import numpy as np

import chiptwin.twin.runner as run_module
from chiptwin import pixel
from chiptwin.config import load_scenario
from chiptwin.fidelity import run
from chiptwin.twin.runner import prepare, run_prepared

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "pyro_1fmol.toml"
#: ``--quick``: the same scene cut to 8 flows (tests/conftest.py's REDUCED), 2 seeds.
QUICK = ["assay.n_flows=8", "run.duration_s=500.0"]
STAGES = ("kinetics", "optics", "pixel", "adc", "dsp", "memory", "detection")


# --- the frame-by-frame reader, patched in for the "frame" rows ----------------------------


class OneStream(run_module.FrameReader):
    """The chip model's reader with the counts and the noise on one stream per chunk, as the
    public per-frame functions draw them (the runner gives the kTC, read and comparator normals
    a stream of their own so that fidelity levels share them; off here, for the bit-for-bit
    check: the kernels and their cost are the same)."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.normal_streams = None


class FrameByFrame(OneStream):
    """The chip model's reader, its codes drawn one frame at a time by the public functions."""

    def _draw(self, k: int, stop: int) -> np.ndarray:
        sensor, adc = self.scene.sensor, self.s.chip.adc
        photons = self.scene.photons_block(k, stop)
        dark_e = sensor.dark_e_per_s * self.s.chip.timing.t_int_s
        frames = []
        for j in range(stop - k):
            reset, signal = pixel.sample_frame(
                self.streams[0], photons[j], sensor.qe, sensor.gain_map, dark_e,
                sensor.full_well_e, sensor.ktc_e, sensor.read_noise_e, sensor.cms_samples,
                sensor.true_cds)
            volts = pixel.to_volts(np.concatenate([reset, signal]),
                                   sensor.conversion_gain_uV_per_e, sensor.pedestal_V)
            frames.append(pixel.adc_convert(volts, adc.bits, adc.v_min_V, adc.v_max_V,
                                            adc.offset_error_lsb, adc.gain_error))
        return np.array(frames)


def check_scene(s) -> None:
    """Refuse a scene the frame-by-frame reader cannot draw bit for bit."""
    why = []
    if s.run.fidelity.photons != "binned":
        why.append(f"photons={s.run.fidelity.photons} (needs binned)")
    if s.chip.n_pixels > pixel.CHUNK_PIXELS:
        why.append(f"{s.chip.n_pixels} pixels (one stream: at most {pixel.CHUNK_PIXELS})")
    if s.chip.adc.as_built_keys and s.run.fidelity.adc != "ideal":
        why.append("a converter as built (needs run.fidelity.adc = \"ideal\")")
    if s.run.fidelity.shot != "poisson":
        why.append(f"shot={s.run.fidelity.shot} (needs poisson)")
    if why:
        raise SystemExit(f"{s.scenario.name}: the frame-by-frame reader needs " + ", ".join(why))


@contextlib.contextmanager
def reader(cls: type) -> Iterator[None]:
    """Run ``run``/``run_prepared`` with the reader ``cls`` while inside."""
    saved = run_module.FrameReader
    run_module.FrameReader = cls
    try:
        yield
    finally:
        run_module.FrameReader = saved


# --- timing ---------------------------------------------------------------------------------


def _fingerprint(result) -> tuple:
    timing = ("wall_time_s", "stage_time_s")
    summary = {k: v for k, v in result.summary.items() if k not in timing}
    return (json.dumps(summary, sort_keys=True),
            {k: np.asarray(v) for k, v in result.arrays.items()}, result.trace.events)


def _same(a: tuple, b: tuple) -> bool:
    return (a[0] == b[0] and a[2] == b[2] and a[1].keys() == b[1].keys()
            and all(np.array_equal(a[1][k], b[1][k], equal_nan=True) for k in a[1]))


def _timed(fn, *args, **kwargs) -> tuple[float, dict[str, float], tuple]:
    t0 = time.perf_counter()
    result = fn(*args, **kwargs)
    wall = time.perf_counter() - t0
    return wall, result.summary["stage_time_s"], _fingerprint(result)


def measure(path: Path, repeat: int, sets: list[str]) -> dict[str, list]:
    """Interleaved rounds of the four contenders; each round one seed for all four."""
    s = load_scenario(path, sets)
    check_scene(s)
    scene = prepare(s)
    rows: dict[str, list] = {"run": [], "run_prepared": [], "frame run": [],
                             "frame run_prepared": []}
    for warm in (True, False):  # one untimed round first: numba caches loaded, imports done
        for i in range(1 if warm else repeat):
            seed = s.scenario.seed + i
            rep = replace(s, scenario=replace(s.scenario, seed=seed))
            with reader(OneStream):
                block = (_timed(run, s, seed=seed), _timed(run_prepared, rep, scene))
            with reader(FrameByFrame):
                frame = (_timed(run, s, seed=seed), _timed(run_prepared, rep, scene))
            for got, ref in zip(block, frame, strict=True):
                if not _same(got[2], ref[2]):
                    raise SystemExit(f"seed {seed}: the block and frame-by-frame readers differ")
            if not warm:
                for name, timing in zip(rows, (*block, *frame), strict=True):
                    rows[name].append(timing[:2])
    return rows


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="8 flows, 2 seeds (a smoke run)")
    p.add_argument("--repeat", type=int, default=7)
    p.add_argument("--scenario", type=Path, default=SCENARIO)
    args = p.parse_args(argv)
    repeat, sets = (2, QUICK) if args.quick else (max(args.repeat, 1), [])
    sets = [*sets, 'run.fidelity.adc="ideal"']  # the public reader converts ideally
    rows = measure(args.scenario, repeat, sets)
    med = {name: statistics.median(w for w, _ in r) for name, r in rows.items()}
    print(f"{args.scenario.stem}{' (quick: ' + ' '.join(sets) + ')' if sets else ''}, warm, "
          f"one process, median of {repeat} seeds (block and frame-by-frame readers "
          "bit-identical for every seed)")
    print(f"{'':20s}{'wall s':>9s}" + "".join(f"{st:>10s}" for st in STAGES))
    for name, r in rows.items():
        stage = {st: statistics.median(t.get(st, 0.0) for _, t in r) for st in STAGES}
        print(f"{name:20s}{med[name]:9.4f}" + "".join(f"{stage[st]:10.4f}" for st in STAGES))
    print(f"block reader vs frame by frame: run() {med['frame run'] / med['run']:.1f}x, "
          f"run_prepared {med['frame run_prepared'] / med['run_prepared']:.1f}x "
          "(stage seconds are medians per stage, so they need not add up to the wall time)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
