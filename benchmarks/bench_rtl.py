"""Benchmark: RTL co-simulation build times and simulation throughput, Verilator vs Icarus.

Run from the repository root::

    python benchmarks/bench_rtl.py [--kinds fir,average] [--beats 1000000] [--icarus-beats 20000]
                                   [--json out.json]
    python benchmarks/bench_rtl.py --quick    # average bank, 10,000 / 1,000 beats, no builds timed

Build times of each block kind's bank (``rtl_ref.suite``), in fresh build directories:

* ``cold``: empty ``ccache`` directory, the Verilator runtime library compiled too (as on a fresh
  CI machine; the runtime is shared by every later build and reported apart);
* ``ccache``: the same build again in an empty build directory, ``ccache`` warm (a CI machine
  that keeps ``~/.cache/ccache``);
* ``no ccache``: ``CHIPTWIN_RTL_CCACHE=0``, runtime library present;
* ``cached``: the build directory kept: the hash lookup only (every later test session).

Simulation: the kind's default config on ``--beats`` input beats (Verilator) and
``--icarus-beats`` (Icarus), full rate and with back-pressure (p_valid 0.9, p_ready 0.8); the
wall time of the simulator process (file I/O included), and the fixed-point model on the same
inputs for scale. The anchors measured earlier (docs/background/sources.md A4): a Verilator C++
testbench reading 1e6 vectors from a file builds in 0.15 s with ccache and simulates in 0.1–0.2 s;
Icarus takes 16 s. Nothing here is asserted.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rtl_ref import build, suite, tools, vectors  # noqa: E402


def _fresh_env(**env: str) -> None:
    os.environ.update(env)
    tools.ccache.cache_clear()


def build_times(kinds: list[str]) -> list[dict]:
    """Seconds per build variant and kind (see the module docstring)."""
    rows = []
    with tempfile.TemporaryDirectory() as cc, tempfile.TemporaryDirectory() as root:
        _fresh_env(CCACHE_DIR=cc, CHIPTWIN_RTL_BUILD=root, CHIPTWIN_RTL_CCACHE="1")
        t0 = time.perf_counter()
        build.runtime_library(trace=False)
        runtime = time.perf_counter() - t0
        for kind in kinds:
            bank = suite.bank(kind)
            row = {"kind": kind, "configs": len(bank.blocks)}
            with tempfile.TemporaryDirectory() as d1:
                _fresh_env(CHIPTWIN_RTL_BUILD=d1)
                build.runtime_library(trace=False)  # ccache hits: not timed with the model
                row["verilator_cold_s"] = build.build_verilator(bank.instances).seconds
            with tempfile.TemporaryDirectory() as d2:
                _fresh_env(CHIPTWIN_RTL_BUILD=d2)
                build.runtime_library(trace=False)
                row["verilator_ccache_s"] = build.build_verilator(bank.instances).seconds
                t0 = time.perf_counter()
                build.build_verilator(bank.instances)
                row["verilator_cached_s"] = time.perf_counter() - t0
                _fresh_env(CHIPTWIN_RTL_CCACHE="0")
                row["verilator_no_ccache_s"] = build.build_verilator(
                    bank.instances, defines=("CT_BENCH_NO_CCACHE",)).seconds
                _fresh_env(CHIPTWIN_RTL_CCACHE="1")
                row["icarus_s"] = build.build_icarus(bank.instances).seconds
            rows.append(row)
    return [{"runtime_library_cold_s": runtime}] + rows


def sim_times(kinds: list[str], beats: int, icarus_beats: int) -> list[dict]:
    """Throughput of the default config of each kind."""
    rows = []
    for kind in kinds:
        bank = suite.bank(kind)
        blk = bank.blocks[0]
        for simulator, n in (("verilator", beats), ("icarus", icarus_beats)):
            inputs = vectors.for_block(blk, n, np.random.default_rng(1))
            bank.build(simulator)
            for pv, pr in ((1.0, 1.0), (0.9, 0.8)):
                r = bank.run(0, inputs, simulator, pv, pr)
                assert r.ok, r.text()
                rows.append({
                    "kind": kind, "simulator": simulator, "p_valid": pv, "p_ready": pr,
                    "beats": r.n_beats, "cycles": r.cycles, "sim_s": r.sim_seconds,
                    "mbeats_per_s": r.n_beats / r.sim_seconds / 1e6, "model_s": r.model_seconds,
                })
    return rows


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--quick", action="store_true",
                   help="simulation of the average bank only, 10,000 / 1,000 beats; no build "
                        "timings (cold builds take minutes)")
    p.add_argument("--kinds", default=",".join(suite.KINDS))
    p.add_argument("--beats", type=int, default=1_000_000)
    p.add_argument("--icarus-beats", type=int, default=20_000)
    p.add_argument("--skip-builds", action="store_true")
    p.add_argument("--json", type=Path)
    args = p.parse_args(argv)
    if args.quick:
        args.kinds, args.beats, args.icarus_beats, args.skip_builds = "average", 10_000, 1_000, True
    kinds = args.kinds.split(",")
    print(f"verilator {tools.require('verilator').version}, icarus "
          f"{tools.require('icarus').version}, ccache {'yes' if tools.ccache() else 'no'}, "
          f"{os.cpu_count()} cores")
    out: dict = {}
    if not args.skip_builds:
        out["builds"] = build_times(kinds)
        runtime = out["builds"][0]["runtime_library_cold_s"]
        print(f"\nVerilator runtime library, cold: {runtime:.1f} s")
        print(f"{'bank':<12}{'cfgs':>5}{'cold':>8}{'ccache':>8}{'no cc':>8}{'cached':>8}"
              f"{'icarus':>8}   (s)")
        for r in out["builds"][1:]:
            print(f"{r['kind']:<12}{r['configs']:>5}{r['verilator_cold_s']:>8.1f}"
                  f"{r['verilator_ccache_s']:>8.1f}{r['verilator_no_ccache_s']:>8.1f}"
                  f"{r['verilator_cached_s']:>8.3f}{r['icarus_s']:>8.2f}")
    out["simulation"] = sim_times(kinds, args.beats, args.icarus_beats)
    print(f"\n{'kind':<12}{'simulator':<11}{'p_v/p_r':>9}{'beats':>10}{'cycles':>10}"
          f"{'sim s':>8}{'Mbeat/s':>9}{'model s':>9}")
    for r in out["simulation"]:
        print(f"{r['kind']:<12}{r['simulator']:<11}{r['p_valid']:>4}/{r['p_ready']:<4}"
              f"{r['beats']:>10}{r['cycles']:>10}{r['sim_s']:>8.3f}{r['mbeats_per_s']:>9.3f}"
              f"{r['model_s']:>9.4f}")
    if args.json:
        args.json.write_text(json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
