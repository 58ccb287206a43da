"""Run a built top on input beats: one simulator process, vectors in a file, outputs back.

Both testbenches (``tb/tb_verilator.cpp``, ``tb/tb_icarus.v``) follow one cycle protocol with
one xorshift64 stream for the random bubbles (``p_valid``) and back-pressure (``p_ready``), so
the same seed gives the same cycle numbers on both simulators.
"""

from __future__ import annotations

import os
import subprocess
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rtl_ref.build import Build

VCD_ENV = "CHIPTWIN_RTL_VCD"
"""Set to a directory to make every simulation write a VCD there (Verilator builds with
``--trace`` then)."""


class SimulationError(RuntimeError):
    """The simulator failed, stalled, or (Icarus) saw X/Z after reset."""


@dataclass(frozen=True)
class SimOutput:
    """What one run produced.

    Attributes
    ----------
    d0, d1, flags, cycle : ndarray of int64, one per output beat
        ``out_d0``, ``out_d1``, ``out_flags`` and the cycle (after reset) of the handshake.
    counters : tuple of int
        ``cnt`` for ``cnt_idx`` = 0, 1, … after the run.
    cycles : int
        Cycles from the end of reset to the last handshake.
    seconds : float
        Wall time of the simulator process.
    simulator : str
    """

    d0: np.ndarray
    d1: np.ndarray
    flags: np.ndarray
    cycle: np.ndarray
    counters: tuple[int, ...]
    cycles: int
    seconds: float
    simulator: str


def vcd_path(name: str) -> Path | None:
    """``$CHIPTWIN_RTL_VCD/<name>.vcd`` when the variable is set."""
    folder = os.environ.get(VCD_ENV)
    if not folder:
        return None
    Path(folder).mkdir(parents=True, exist_ok=True)
    return Path(folder) / f"{name}.vcd"


def _p16(p: float) -> int:
    if not 0.0 < p <= 1.0:
        raise ValueError(f"probability {p}: must be in (0, 1]")
    return int(round(p * 65536))


def _parse_stdout(text: str, n_cnt: int) -> tuple[int, tuple[int, ...], list[str]]:
    cycles, counters, problems = -1, [0] * n_cnt, []
    for line in text.splitlines():
        parts = line.split()
        if parts[:1] == ["cycles"]:
            cycles = int(parts[1])
        elif parts[:1] == ["cnt"] and int(parts[1]) < n_cnt:
            counters[int(parts[1])] = int(parts[2])
        elif parts[:1] in (["XCHECK"], ["stalled"]) or line.startswith("tb:"):
            problems.append(line)
    return cycles, tuple(counters), problems


def run(
    build: Build,
    sel: int,
    beats: np.ndarray,
    n_expect: int,
    n_counters: int,
    p_valid: float = 1.0,
    p_ready: float = 1.0,
    seed: int = 1,
    vcd: Path | None = None,
    max_idle: int = 100_000,
) -> SimOutput:
    """Stream ``beats`` (int64 ``(n, 2)``) through instance ``sel`` of ``build``.

    Raises :class:`SimulationError` when the simulator fails, stalls for ``max_idle`` cycles,
    produces more than ``n_expect`` outputs, or (Icarus) reports X/Z after reset.
    """
    beats = np.ascontiguousarray(beats, dtype=np.int64).reshape(-1, 2)
    with tempfile.TemporaryDirectory(prefix="ct-sim-") as d:
        src, dst = Path(d) / "in", Path(d) / "out"
        if build.simulator == "verilator":
            beats.astype("<i8").tofile(src)
            cmd = [str(build.path), "--in", str(src), "--out", str(dst), "--n", str(len(beats)),
                   "--expect", str(n_expect), "--sel", str(sel), "--ncnt", str(n_counters),
                   "--p-valid", repr(p_valid), "--p-ready", repr(p_ready), "--seed", str(seed),
                   "--max-idle", str(max_idle)] + (["--vcd", str(vcd)] if vcd else [])
        else:
            words = beats.view(np.uint64)
            np.savetxt(src, words, fmt="%016x")
            cmd = ["vvp", "-n", str(build.path), f"+in={src}", f"+out={dst}", f"+n={len(beats)}",
                   f"+expect={n_expect}", f"+sel={sel}", f"+ncnt={n_counters}",
                   f"+pvalid={_p16(p_valid)}", f"+pready={_p16(p_ready)}", f"+seed={seed}",
                   f"+maxidle={max_idle}"] + ([f"+vcd={vcd}"] if vcd else [])
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
        seconds = time.perf_counter() - t0
        cycles, counters, problems = _parse_stdout(proc.stdout, n_counters)
        if proc.returncode != 0 or problems or cycles < 0:
            raise SimulationError(
                f"{build.simulator} run of instance {sel} failed (exit {proc.returncode}):\n"
                + "\n".join(problems[:20] or [proc.stdout[-2000:], proc.stderr[-2000:]])
            )
        out = _read_outputs(dst, build.simulator)
    return SimOutput(out[:, 0], out[:, 1], out[:, 2], out[:, 3], counters, cycles, seconds,
                     build.simulator)


def _read_outputs(path: Path, simulator: str) -> np.ndarray:
    if simulator == "verilator":
        return np.fromfile(path, dtype="<i8").astype(np.int64).reshape(-1, 4)
    rows = [line.split() for line in path.read_text().splitlines() if line.strip()]
    out = np.zeros((len(rows), 4), dtype=np.int64)
    for i, (d0, d1, flags, cycle) in enumerate(rows):
        out[i] = [np.uint64(int(d0, 16)).view(np.int64), np.uint64(int(d1, 16)).view(np.int64),
                  int(flags, 16), int(cycle)]
    return out
