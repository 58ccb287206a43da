"""Co-simulation: the same inputs through the fixed-point model and the RTL, compared bit for bit.

A :class:`Bank` is a set of blocks built into one top (one build per simulator); :meth:`Bank.run`
streams one block's beats through the RTL and returns a :class:`Report`: every output word
compared with the model's, the overflow counters compared register by register, the corner
coverage of the vectors, and, on a mismatch, the first differing output beats with the cycle of
their handshake and the input beats they came from.
"""

from __future__ import annotations

import os
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rtl_ref import sim
from rtl_ref.block import Block, Expected, Inputs
from rtl_ref.build import Build, build

MAX_REPORTED = 5
"""Differing output beats listed in a report."""


@dataclass(frozen=True)
class Mismatch:
    """One output word the RTL got wrong."""

    index: int
    cycle: int
    word: str
    expected: int
    got: int
    sources: str

    def text(self) -> str:
        """One paragraph: which output, when, what, and from which inputs."""
        return (
            f"  output beat {self.index} at cycle {self.cycle}: {self.word} expected "
            f"{self.expected} (0x{self.expected & (2**64 - 1):x}), RTL {self.got} "
            f"(0x{self.got & (2**64 - 1):x})\n    {self.sources}"
        )


@dataclass
class Report:
    """The comparison of one run. ``ok`` when every word and every counter agrees."""

    label: str
    simulator: str
    n_beats: int
    n_outputs: int
    cycles: int
    sim_seconds: float
    model_seconds: float
    n_mismatches: int
    mismatches: list[Mismatch]
    overflow_model: dict
    overflow_rtl: dict
    coverage: dict[str, int] = field(default_factory=dict)
    count_error: str = ""
    out_cycles: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    @property
    def ok(self) -> bool:
        """No differing word, the right number of outputs, equal overflow counts."""
        return (not self.n_mismatches and not self.count_error
                and self.overflow_model == self.overflow_rtl)

    def text(self) -> str:
        """Summary line, then what differs."""
        head = (
            f"{self.label} on {self.simulator}: {self.n_beats} input beats, {self.n_outputs} "
            f"outputs, {self.cycles} cycles, {self.sim_seconds:.2f} s simulated; "
            f"{self.n_mismatches} differing words"
        )
        lines = [head]
        if self.count_error:
            lines.append("  " + self.count_error)
        if self.overflow_model != self.overflow_rtl:
            lines.append(f"  overflow counts differ: model {self.overflow_model}, "
                         f"RTL {self.overflow_rtl}")
        lines += [m.text() for m in self.mismatches]
        return "\n".join(lines)


def _compare(exp: Expected, out: sim.SimOutput, block: Block, inputs: Inputs,
             max_reported: int) -> tuple[int, list[Mismatch]]:
    n = min(len(exp.d0), len(out.d0))
    bad = np.zeros(n, dtype=bool)
    words = [("out_d0", exp.d0, out.d0, exp.cmp0), ("out_d1", exp.d1, out.d1, exp.cmp1)]
    if exp.tag is not None:
        words.append(("out_tag", exp.tag, out.flags & 1, np.ones(len(exp.tag), bool)))
    diffs = {}
    for name, want, got, cmp in words:
        d = (want[:n] != got[:n]) & cmp[:n]
        diffs[name] = d
        bad |= d
    idx = np.flatnonzero(bad)
    found = []
    for k in idx[:max_reported]:
        for name, want, got, _ in words:
            if diffs[name][k]:
                found.append(Mismatch(int(k), int(out.cycle[k]), name, int(want[k]),
                                      int(got[k]), block.sources(inputs, int(k))))
    return int(bad.sum()), found


def coverage(block: Block, inputs: Inputs, beats: np.ndarray, exp: Expected) -> dict[str, int]:
    """Corner counts of a vector set: ties of both signs at the output rounding, extreme input
    codes, and the model's saturation and wrap events."""
    cov: dict[str, int] = {}
    pre = block.pre_round(inputs)
    if pre is not None and pre[1] > 0:
        v, sh = pre
        tie = (v & ((1 << sh) - 1)) == (1 << (sh - 1))
        cov["ties_pos"] = int(np.count_nonzero(tie & (v > 0)))
        cov["ties_neg"] = int(np.count_nonzero(tie & (v < 0)))
    first = block.instance().inputs[0]
    lo = -(1 << (first.width - 1)) if first.signed else 0
    hi = (1 << (first.width - (1 if first.signed else 0))) - 1
    cov["min_code"] = int(np.count_nonzero(beats[:, 0] == lo))
    cov["max_code"] = int(np.count_nonzero(beats[:, 0] == hi))
    for kind in ("sat", "wrap"):
        cov[kind] = _total(exp.overflow, kind)
    return cov


def _total(overflow: Mapping, kind: str) -> int:
    if kind in overflow:
        return int(overflow[kind])
    return sum(_total(v, kind) for v in overflow.values() if isinstance(v, Mapping))


class Bank:
    """Blocks built into one top, per simulator; ``defines`` select RTL variants (mutants)."""

    def __init__(self, blocks: Sequence[Block], defines: Sequence[str] = ()) -> None:
        self.blocks = list(blocks)
        self.instances = [b.instance() for b in self.blocks]
        self.defines = tuple(defines)
        self._builds: dict[tuple[str, bool], Build] = {}

    def build(self, simulator: str, trace: bool = False) -> Build:
        """Build (or find) this bank's top for ``simulator``."""
        key = (simulator, trace and simulator == "verilator")
        if key not in self._builds:
            self._builds[key] = build(simulator, self.instances, self.defines, key[1])
        return self._builds[key]

    def run(
        self,
        index: int,
        inputs: Inputs,
        simulator: str = "verilator",
        p_valid: float = 1.0,
        p_ready: float = 1.0,
        seed: int = 1,
        vcd: str | os.PathLike | None = None,
        max_reported: int = MAX_REPORTED,
    ) -> Report:
        """Co-simulate block ``index`` on ``inputs``.

        ``p_valid``/``p_ready``: probability per cycle of presenting a waiting beat / of
        accepting an output (random bubbles and back-pressure, from ``seed``). ``vcd``: a file
        to dump the run's waveforms to; by default ``$CHIPTWIN_RTL_VCD/<block>-<index>-<sim>.vcd``
        when :data:`rtl_ref.sim.VCD_ENV` is set, else none.
        """
        block = self.blocks[index]
        beats = block.beats(inputs)
        t0 = time.perf_counter()
        exp = block.expected(inputs)
        model_s = time.perf_counter() - t0
        vcd_file = Path(vcd) if vcd else sim.vcd_path(f"{block.label()}-{index}-{simulator}")
        b = self.build(simulator, trace=vcd_file is not None)
        names = block.counter_names()
        out = sim.run(b, index, beats, len(exp.d0), len(names), p_valid, p_ready, seed, vcd_file)
        counts = dict(zip(names, out.counters, strict=True))
        n_bad, found = _compare(exp, out, block, inputs, max_reported)
        count_error = "" if len(out.d0) == len(exp.d0) else (
            f"{len(out.d0)} output beats, the model has {len(exp.d0)}")
        return Report(
            label=block.label(), simulator=simulator, n_beats=len(beats),
            n_outputs=len(out.d0), cycles=out.cycles, sim_seconds=out.seconds,
            model_seconds=model_s, n_mismatches=n_bad, mismatches=found,
            overflow_model=exp.overflow, overflow_rtl=block.overflow(counts),
            coverage=coverage(block, inputs, beats, exp), count_error=count_error,
            out_cycles=out.cycle,
        )
