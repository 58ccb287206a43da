"""What each DSP program costs on the reference chip (pyro_1fmol): frame memory it holds, frames
of memory left, DSP time per frame and utilisation, and the run's wall time (fixed level).

Run: ``python benchmarks/bench_program.py``. Wall times are medians of 3 runs on a shared
machine; the memory and DSP figures are exact (the schedule's).
"""

from __future__ import annotations

import statistics
import time
from pathlib import Path

from chiptwin.fidelity import run

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "pyro_1fmol.toml"
PROGRAMS = {
    "chain (default)": '["cms","dark","background","average"]',
    "kinetics": '["cms","dark","background","kinetics"]',
    "bin_rows": '["cms","dark","background","average","bin_rows"]',
    "bin_rows+fir8": '["cms","dark","background","average","bin_rows","fir8"]',
    "wiener": '["cms","dark","background","average","wiener"]',
    "bin_rows+fir8+wiener": '["cms","dark","background","average","bin_rows","fir8","wiener"]',
}


def main() -> None:
    print(f"{'program':24s} {'held bits':>10s} {'frames':>6s} {'DSP us/frame':>12s} "
          f"{'utilisation':>11s} {'wall s':>7s} {'SNR site 0':>10s}")
    for name, prog in PROGRAMS.items():
        sets = [f"chip.dsp.program={prog}", "chip.dsp.mode=fixed", "chip.dsp.bin_factor=2"]
        walls, r = [], None
        for _ in range(3):
            t0 = time.perf_counter()
            r = run(SCENARIO, sets)
            walls.append(time.perf_counter() - t0)
        c, p = r.summary["chip"], r.summary["dsp_program"]
        print(f"{name:24s} {p['resident_bits']:10d} {c['memory_capacity_frames']:6d} "
              f"{c['dsp_time_per_frame_s'] * 1e6:12.2f} {c['dsp_utilization']:11.3e} "
              f"{statistics.median(walls):7.3f} {r.summary['sites'][0]['snr_power']:10.4g}")


if __name__ == "__main__":
    main()
