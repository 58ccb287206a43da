"""The chip's probe: every block reports ``(t_ns, block, event, value)`` to a recorder passed in.

Nothing in the chip model prints; a trace can be saved as arrays or written as a VCD file for a
waveform viewer (GTKWave): one integer signal per ``block.event``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


@dataclass
class Recorder:
    """Collects chip events in order of simulation time."""

    events: list[tuple[int, str, str, float]] = field(default_factory=list)

    def record(self, t_ns: int, block: str, event: str, value: float = 0.0) -> None:
        """Append one event. ``t_ns`` is the integer nanosecond tick of the chip clock."""
        self.events.append((int(t_ns), block, event, float(value)))

    def __len__(self) -> int:
        return len(self.events)

    def count(self, block: str, event: str) -> int:
        """How many times ``block`` reported ``event``."""
        return sum(1 for _, b, e, _ in self.events if b == block and e == event)

    def times(self, block: str, event: str) -> np.ndarray:
        """The ticks at which ``block`` reported ``event``. Unit: ns."""
        return np.array([t for t, b, e, _ in self.events if b == block and e == event], np.int64)

    def to_arrays(self) -> dict[str, np.ndarray]:
        """Columns for an ``.npz`` file: ``t_ns``, ``block``, ``event``, ``value``."""
        t, b, e, v = zip(*self.events, strict=True) if self.events else ((), (), (), ())
        return {
            "trace_t_ns": np.array(t, np.int64),
            "trace_block": np.array(b, dtype="U16"),
            "trace_event": np.array(e, dtype="U24"),
            "trace_value": np.array(v, np.float64),
        }

    def write_vcd(self, path: str | Path) -> None:
        """Write the trace as a Value Change Dump: one 32-bit signal per ``block.event``."""
        names = sorted({f"{b}.{e}" for _, b, e, _ in self.events})
        ids = {name: _vcd_id(i) for i, name in enumerate(names)}
        lines = ["$timescale 1ns $end", "$scope module chip $end"]
        lines += [f"$var integer 32 {ids[n]} {n.replace('.', '_')} $end" for n in names]
        lines += ["$upscope $end", "$enddefinitions $end"]
        last_t = None
        for t, b, e, v in self.events:
            if t != last_t:
                lines.append(f"#{t}")
                last_t = t
            lines.append(f"b{int(v) & 0xFFFFFFFF:b} {ids[f'{b}.{e}']}")
        Path(path).write_text("\n".join(lines) + "\n")


def _vcd_id(i: int) -> str:
    """Short printable VCD identifiers: !, ", #, ... then two characters."""
    chars = [chr(c) for c in range(33, 127)]
    out = ""
    while True:
        out = chars[i % len(chars)] + out
        i = i // len(chars) - 1
        if i < 0:
            return out
