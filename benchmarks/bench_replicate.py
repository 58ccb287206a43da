"""Benchmark: one replicate of a study point, warm, in one process, against the path it replaced.

A budget study prepares a point once (``chiptwin.twin.prepare``) and runs thousands of replicates
(``run_prepared`` with another ``scenario.seed``). This times, for ``pyro_1fmol`` (binned photons,
float DSP, 8 × 16 pixels, 1520 frames):

* ``run()`` (prepare + run_prepared) and ``run_prepared`` on one prepared scene, as they are;
* the same two on the frame-by-frame path they replaced, kept runnable here side by side
  (``old_simulate``, patched in for the "old" rows): the pixel stage calling the public, checked
  ``expected_frame``, ``mean_electrons``, ``sample_frame``, ``to_volts`` and ``adc_convert`` once
  per frame, from the chip model's ``read_frame``.

Both paths run the same seeds in interleaved rounds (the machine is shared; medians are reported),
and every old/new pair is checked bit for bit (summary without timings, every array, the trace).

Usage: ``python benchmarks/bench_replicate.py [--repeat 7] [--scenario PATH]``.
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
from chiptwin.chip import simulate_chip
from chiptwin.config import load_scenario
from chiptwin.dsp.pipeline import Frame
from chiptwin.fidelity import run
from chiptwin.twin import stages
from chiptwin.twin.runner import prepare, run_prepared
from chiptwin.twin.scene import StageTimer, stage_rng

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "pyro_1fmol.toml"
STAGES = ("kinetics", "optics", "pixel", "adc", "dsp", "memory", "detection")


# --- the replaced path, kept runnable -----------------------------------------------------


def old_simulate(s, scene, photons_level, rng, rec, timer=None, progress=None, keep_codes=False):
    """``chiptwin.twin.simulate`` as it was: every pixel function called, and checked, per frame."""
    timer = timer or StageTimer()
    sch, sensor, pix_photons = scene.sch, scene.sensor, scene.pix_photons
    adc = s.chip.adc
    t_int = s.chip.timing.t_int_s
    to_lsb = (1.0 + adc.gain_error) / sensor.e_per_lsb
    read_lsb = sensor.read_noise_e / sensor.e_per_lsb * (1.0 + adc.gain_error)
    quant_var = 2.0 * pixel.quantization_var_of_mean(sensor.cms_samples, read_lsb)
    args = (sensor.qe, sensor.gain_map, sensor.dark_e_per_s * t_int, sensor.full_well_e,
            sensor.ktc_e, sensor.read_noise_e, sensor.cms_samples, sensor.true_cds)
    events = None
    if photons_level == "events":
        events = stages.EventPixels(scene.source, scene.coupling, stages.site_pixel_indices(s),
                                    sensor, stage_rng(s.scenario.seed, "events"))
    clipped, full = [0], [0]

    def read_frame(k: int) -> Frame:
        photons = pix_photons[:, k]
        with timer("pixel"):
            mean_e, var_e = pixel.expected_frame(photons, *args)
            lam = pixel.mean_electrons(photons, sensor.qe, sensor.gain_map, args[2])
            full[0] += int(np.count_nonzero(lam >= sensor.full_well_e))
            samples = None
            if photons_level == "binned":
                samples = pixel.sample_frame(rng, photons, *args)
            elif events is not None:
                collected = np.minimum(rng.poisson(lam), sensor.full_well_e)
                collected[events.pixels] = events.collect(*sch.window_s(k))
                samples = pixel.read_out(rng, collected, *args[4:])
        with timer("adc"):
            codes = None
            if samples is not None:
                volts = pixel.to_volts(np.concatenate(samples), sensor.conversion_gain_uV_per_e,
                                       sensor.pedestal_V)
                codes = pixel.adc_convert(volts, adc.bits, adc.v_min_V, adc.v_max_V,
                                          adc.offset_error_lsb, adc.gain_error)
                clipped[0] += int(np.count_nonzero((codes == 0) | (codes == 2**adc.bits - 1)))
        return Frame(codes=codes, mean=mean_e * to_lsb, var=var_e * to_lsb**2 + quant_var)

    pipeline = run_module._TimedPipeline(run_module._dsp_level(s, keep_codes), timer)
    t0 = time.perf_counter()
    chip = simulate_chip(sch, read_frame, pipeline, rec, progress)
    inner = sum(timer.seconds[k] for k in ("pixel", "adc", "dsp"))
    timer.seconds["memory"] += time.perf_counter() - t0 - inner
    out = run_module._chain_output(chip, sch, pipeline.inner, sensor.e_per_lsb)
    out.adc_clipped_samples, out.full_well_pixel_frames = clipped[0], full[0]
    if events is not None:
        out.saturation_s = np.array(events.saturation_s).reshape(-1, len(events.pixels))
    return out


@contextlib.contextmanager
def old_path() -> Iterator[None]:
    """Run ``run``/``run_prepared`` on the replaced path while inside."""
    saved = run_module.simulate
    run_module.simulate = old_simulate
    try:
        yield
    finally:
        run_module.simulate = saved


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


def measure(path: Path, repeat: int) -> dict[str, list]:
    """Interleaved rounds of the four contenders; each round one seed for all four."""
    s = load_scenario(path)
    scene = prepare(s)
    rows: dict[str, list] = {"run": [], "run_prepared": [], "old run": [], "old run_prepared": []}
    for warm in (True, False):  # one untimed round first: numba caches loaded, imports done
        for i in range(1 if warm else repeat):
            seed = s.scenario.seed + i
            rep = replace(s, scenario=replace(s.scenario, seed=seed))
            new = (_timed(run, s, seed=seed), _timed(run_prepared, rep, scene))
            with old_path():
                old = (_timed(run, s, seed=seed), _timed(run_prepared, rep, scene))
            for got, ref in zip(new, old, strict=True):
                if not _same(got[2], ref[2]):
                    raise SystemExit(f"seed {seed}: new and old paths differ")
            if not warm:
                for name, timing in zip(rows, (*new, *old), strict=True):
                    rows[name].append(timing[:2])
    return rows


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeat", type=int, default=7)
    p.add_argument("--scenario", type=Path, default=SCENARIO)
    args = p.parse_args()
    rows = measure(args.scenario, max(args.repeat, 1))
    med = {name: statistics.median(w for w, _ in r) for name, r in rows.items()}
    print(f"{args.scenario.stem}, warm, one process, median of {args.repeat} seeds "
          "(old and new bit-identical for every seed)")
    print(f"{'':18s}{'wall s':>9s}" + "".join(f"{st:>10s}" for st in STAGES))
    for name, r in rows.items():
        stage = {st: statistics.median(t.get(st, 0.0) for _, t in r) for st in STAGES}
        print(f"{name:18s}{med[name]:9.4f}" + "".join(f"{stage[st]:10.4f}" for st in STAGES))
    print(f"speed-up: run() {med['old run'] / med['run']:.1f}x, "
          f"run_prepared {med['old run_prepared'] / med['run_prepared']:.1f}x "
          "(stage seconds are medians per stage, so they need not add up to the wall time)")


if __name__ == "__main__":
    main()
