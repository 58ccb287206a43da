"""The chip's probe: every block reports ``(t_ns, block, event, value)`` to a recorder passed in.

Nothing in the chip model prints; a trace can be saved as arrays or written as a VCD file for a
waveform viewer (GTKWave): one integer signal per ``block.event``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

#: The steps of a frame the chip model records only when the trace asks for them
#: (:attr:`Recorder.frame_steps`): ``(block, event)`` of the reset, the reset conversions, the start
#: of integration and the signal conversions. They change no state (the frame memory, the DSP and
#: every output depend on ``adc.frame_ready`` alone) and their times follow from the schedule:
#: frame ``k``'s reset at ``k·frame_period``, then ``t_reset``, ``M·t_conv``, ``t_int`` apart.
FRAME_STEPS: tuple[tuple[str, str], ...] = (
    ("pixel", "reset"), ("adc", "convert_reset"), ("pixel", "integrate_start"),
    ("adc", "convert_signal"))


@dataclass
class Recorder:
    """Collects chip events in order of simulation time.

    ``frame_steps`` (default True) asks the chip model for every frame's :data:`FRAME_STEPS`.
    False is the shortcut of a trace that does not need them individually (a study's
    replicates, a long run whose trace nobody reads frame by frame): the sensor then waits once
    from one frame's ``adc.frame_ready`` to the next frame's signal conversions instead of once per
    step (2 SimPy events per frame instead of 5), and the trace says so (this flag, kept in
    :meth:`to_arrays` and the VCD header). Everything else is the same: the same events in the same
    order at the same ticks as the full trace without the steps, and the same chip outputs
    (tested on the bundled scenarios, ``tests/test_shortcuts.py``).
    """

    events: list[tuple[int, str, str, float]] = field(default_factory=list)
    frame_steps: bool = True

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
            "trace_frame_steps": np.array(self.frame_steps),
        }

    def write_vcd(self, path: str | Path) -> None:
        """Write the trace as a Value Change Dump: one 32-bit signal per ``block.event``."""
        names = sorted({f"{b}.{e}" for _, b, e, _ in self.events})
        ids = {name: _vcd_id(i) for i, name in enumerate(names)}
        lines = [] if self.frame_steps else [
            "$comment frame steps (reset, conversions, integration start) not recorded $end"]
        lines += ["$timescale 1ns $end", "$scope module chip $end"]
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
