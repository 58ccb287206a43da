"""What each DSP program costs on the reference chip (pyro_1fmol): frame memory it holds, frames
of memory left, DSP time per frame and utilisation, and the run's wall time (fixed level).

Run: ``python benchmarks/bench_program.py [--quick]``. Wall times are medians of 3 runs on a
shared machine; the memory and DSP figures are exact (the schedule's). ``--quick``: the scene cut
to 8 flows (500 frames), one run per program, the same code path.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

from chiptwin.fidelity import run

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "pyro_1fmol.toml"
QUICK = ["assay.n_flows=8", "run.duration_s=500.0"]
PROGRAMS = {
    "chain (default)": '["cms","dark","background","average"]',
    "kinetics": '["cms","dark","background","kinetics"]',
    "bin_rows": '["cms","dark","background","average","bin_rows"]',
    "bin_rows+fir8": '["cms","dark","background","average","bin_rows","fir8"]',
    "wiener": '["cms","dark","background","average","wiener"]',
    "bin_rows+fir8+wiener": '["cms","dark","background","average","bin_rows","fir8","wiener"]',
}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="500 frames, one run per program")
    args = ap.parse_args(argv)
    rounds, smaller = (1, QUICK) if args.quick else (3, [])
    if smaller:
        print(f"pyro_1fmol (quick: {' '.join(smaller)})")
    print(f"{'program':24s} {'held bits':>10s} {'frames':>6s} {'DSP us/frame':>12s} "
          f"{'utilisation':>11s} {'wall s':>7s} {'SNR site 0':>10s}")
    for name, prog in PROGRAMS.items():
        sets = [*smaller, f"chip.dsp.program={prog}", "chip.dsp.mode=fixed",
                "chip.dsp.bin_factor=2"]
        walls, r = [], None
        for _ in range(rounds):
            t0 = time.perf_counter()
            r = run(SCENARIO, sets)
            walls.append(time.perf_counter() - t0)
        c, p = r.summary["chip"], r.summary["dsp_program"]
        print(f"{name:24s} {p['resident_bits']:10d} {c['memory_capacity_frames']:6d} "
              f"{c['dsp_time_per_frame_s'] * 1e6:12.2f} {c['dsp_utilization']:11.3e} "
              f"{statistics.median(walls):7.3f} {r.summary['sites'][0]['snr_power']:10.4g}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
