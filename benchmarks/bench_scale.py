"""Benchmark: ``run()`` at chip scale against the fused ``sensor_chain``; its memory.

Three measurements, each warm (numba kernels compiled and cached first):

1. Per pixel-frame cost of ``run()`` on ``pyro_1fmol`` grown to 64², 128², 256² pixels (frame
   memory scaled to hold the same 31 frames), beside ``chiptwin.pixel.sensor_chain`` drawing the
   same pixel-frames with the same samples per frame (M = 4 CMS reset and signal samples, kTC,
   13-bit ADC) in the same process, interleaved. ``run()`` also makes the light, the moments, the
   DSP and the detection; the ratio says what the chip model costs over the bare chain.
2. Peak RSS of ``run()`` at 256² for 1,520 and 3,040 frames, each in a fresh process, and of
   the reference chip (``pyro_1fmol``) after the imports and after one run
   (``VmHWM`` of ``/proc/self/status``: ``ru_maxrss`` survives ``exec`` on Linux, so a child
   started from this process would report this process's peak), to show memory flat in frames.
3. ``pyro_array_256`` end to end (``run()``, then the outputs written), wall time and peak RSS.

Usage: ``python benchmarks/bench_scale.py [--quick] [--sides 64 128 256] [--rounds 3]
[--skip-rss] [--skip-array]``. Prints a table and one JSON line. ``--quick``: measurement 1 at
32² over 500 frames (8 flows), one round; 2 and 3 (fresh processes, large arrays) not run.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numba
import numpy as np

from chiptwin.config import load_scenario
from chiptwin.fidelity import run
from chiptwin.pixel import sensor_chain
from chiptwin.twin.runner import chip_sensor, prepare

ROOT = Path(__file__).resolve().parents[1]
PYRO = ROOT / "scenarios" / "pyro_1fmol.toml"
ARRAY = ROOT / "scenarios" / "pyro_array_256.toml"


def grown(side: int, duration_s: float = 1520.0):
    """``pyro_1fmol`` on a ``side × side`` array, frame memory scaled to 31 frames; below 1,520 s
    its flows cut to the 8 that read the key (which need 500 s)."""
    s = load_scenario(PYRO)
    if duration_s < 1520.0:
        s = replace(s, assay=replace(s.assay, n_flows=8))
    chip = s.chip
    frame_bits = side * side * chip.samples_per_frame * chip.memory.word_bits
    capacity = 31 * frame_bits + side * side * chip.memory.word_bits
    chip = replace(chip, rows=side, cols=side, memory=replace(chip.memory, capacity_bits=capacity))
    return replace(s, chip=chip, run=replace(s.run, duration_s=duration_s))


def time_run(s) -> tuple[float, dict]:
    t0 = time.perf_counter()
    res = run(s)
    return time.perf_counter() - t0, res.summary["stage_time_s"]


def time_chain(s) -> float:
    """sensor_chain over the same pixel-frames: the run's light, M = 4 reset and signal samples."""
    scene = prepare(s)
    sensor = chip_sensor(s)
    n = scene.sch.n_frames
    photons = (scene.photons_block(k, min(k + 64, n)) for k in range(0, n, 64))
    frames = (block[i] for block in photons for i in range(len(block)))
    adc = s.chip.adc
    t0 = time.perf_counter()
    for _ in sensor_chain(
            np.random.default_rng(1), frames, qe=sensor.qe, gain_map=sensor.gain_map,
            dark_e=sensor.dark_e_per_s * s.chip.timing.t_int_s, full_well_e=sensor.full_well_e,
            read_noise_e=sensor.read_noise_e,
            conversion_gain_uV_per_e=sensor.conversion_gain_uV_per_e, ktc_e=sensor.ktc_e,
            true_cds=sensor.true_cds, n_samples=sensor.cms_samples, read_reset=True,
            pedestal_V=sensor.pedestal_V, bits=adc.bits, v_min_V=adc.v_min_V,
            v_max_V=adc.v_max_V):
        pass
    return time.perf_counter() - t0


def per_pixel_frame(sides: list[int], rounds: int, duration_s: float = 1520.0) -> list[dict]:
    rows = []
    for side in sides:
        s = grown(side, duration_s)
        time_run(s), time_chain(s)  # warm
        runs, chains, stages_s = [], [], []
        for _ in range(rounds):
            wall, st = time_run(s)
            runs.append(wall)
            stages_s.append(st)
            chains.append(time_chain(s))
        pf = side * side * s.run.duration_s / s.chip.timing.frame_period_s
        r, c = statistics.median(runs), statistics.median(chains)
        best = stages_s[int(np.argsort(runs)[len(runs) // 2])]
        rows.append({"side": side, "run_s": r, "run_ns_per_pixel_frame": r / pf * 1e9,
                     "chain_s": c, "chain_ns_per_pixel_frame": c / pf * 1e9, "ratio": r / c,
                     "stage_time_s": best})
    return rows


def vm_hwm_kb() -> int:
    """This process's peak resident set (kB), from ``/proc/self/status``."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1])
    raise RuntimeError("no VmHWM in /proc/self/status")


def peak_rss_mb(side: int, duration_s: float) -> float:
    """``run()`` in a fresh process; its peak resident set (MB)."""
    code = (f"import sys; sys.path.insert(0, {str(ROOT / 'benchmarks')!r}); import bench_scale; "
            f"from chiptwin.fidelity import run; run(bench_scale.grown({side}, {duration_s}));"
            "print(bench_scale.vm_hwm_kb())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return int(out.stdout.split()[-1]) / 1024


def reference_rss_mb() -> tuple[float, float]:
    """Peak RSS (MB) of a fresh process after importing the twin, and after one ``pyro_1fmol``."""
    code = (f"import sys; sys.path.insert(0, {str(ROOT / 'benchmarks')!r}); import bench_scale; "
            "from chiptwin.fidelity import run; a = bench_scale.vm_hwm_kb(); "
            f"run({str(PYRO)!r}); print(a, bench_scale.vm_hwm_kb())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    before, after = (int(v) / 1024 for v in out.stdout.split()[-2:])
    return before, after


def array_end_to_end() -> dict:
    code = (f"import sys; sys.path.insert(0, {str(ROOT / 'benchmarks')!r}); import bench_scale; "
            "import time, tempfile, json; from chiptwin.fidelity import run; "
            "from chiptwin.report.outputs import write_outputs; t0 = time.perf_counter(); "
            f"r = run({str(ARRAY)!r}); t1 = time.perf_counter(); "
            "d = tempfile.mkdtemp(); write_outputs(r, d + '/out'); t2 = time.perf_counter(); "
            "a = r.summary['array']; print(json.dumps({'run_s': t1 - t0, 'write_s': t2 - t1, "
            "'rss_mb': bench_scale.vm_hwm_kb() / 1024, "
            "'stage_time_s': r.summary['stage_time_s'], 'array': a}))")
    subprocess.run([sys.executable, "-c", f"from chiptwin.twin import run; run({str(PYRO)!r})"],
                   check=True)  # compile and cache the kernels first
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="32², 500 frames, 1 round")
    p.add_argument("--sides", type=int, nargs="*", default=[64, 128, 256])
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--skip-rss", action="store_true")
    p.add_argument("--skip-array", action="store_true")
    args = p.parse_args(argv)
    if args.quick:
        args.sides, args.rounds, args.skip_rss, args.skip_array = [32], 1, True, True
    print(f"numba threads: {numba.get_num_threads()}")
    result: dict = {"threads": numba.get_num_threads()}
    rows = per_pixel_frame(args.sides, args.rounds, 500.0 if args.quick else 1520.0)
    print("| array | run() wall | per pixel-frame | sensor_chain | ratio | pixel stage |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['side']}² | {r['run_s']:.2f} s | {r['run_ns_per_pixel_frame']:.0f} ns | "
              f"{r['chain_ns_per_pixel_frame']:.0f} ns | {r['ratio']:.2f}× | "
              f"{r['stage_time_s'].get('pixel', 0):.2f} s |")
    print("stage times (s):", json.dumps([r["stage_time_s"] for r in rows]))
    result["per_pixel_frame"] = rows
    if not args.skip_rss:
        rss = {n: peak_rss_mb(256, float(n)) for n in (1520, 3040)}
        print(f"peak RSS at 256²: 1,520 frames {rss[1520]:.0f} MB, 3,040 frames {rss[3040]:.0f} MB"
              f" (ratio {rss[3040] / rss[1520]:.3f})")
        result["peak_rss_mb_256"] = rss
        before, after = reference_rss_mb()
        print(f"peak RSS, reference chip: {before:.0f} MB after the imports, {after:.0f} MB "
              "after one pyro_1fmol run")
        result["peak_rss_mb_reference"] = {"imported": before, "after_run": after}
    if not args.skip_array:
        arr = array_end_to_end()
        print(f"pyro_array_256: run {arr['run_s']:.1f} s, outputs {arr['write_s']:.1f} s, "
              f"peak RSS {arr['rss_mb']:.0f} MB; stages {json.dumps(arr['stage_time_s'])}")
        print("  " + json.dumps(arr["array"]))
        result["pyro_array_256"] = arr
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
