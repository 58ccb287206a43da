"""The chip's probe: every block reports ``(t_ns, block, event, value)`` to a recorder passed in.

Nothing in the chip model prints; a trace can be saved as arrays or written as a VCD file for a
waveform viewer (GTKWave, Surfer): each block's states as signals (:mod:`chiptwin.chip.vcd`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from chiptwin.chip.vcd import write_vcd

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
        """The trace as columns ``trace_t_ns``, ``trace_block``, ``trace_event``, ``trace_value``
        (and ``trace_frame_steps``), as the run's dataset holds them (``run.nc``)."""
        t, b, e, v = zip(*self.events, strict=True) if self.events else ((), (), (), ())
        return {
            "trace_t_ns": np.array(t, np.int64),
            "trace_block": np.array(b, dtype="U16"),
            "trace_event": np.array(e, dtype="U24"),
            "trace_value": np.array(v, np.float64),
            "trace_frame_steps": np.array(self.frame_steps),
        }

    def write_vcd(self, path: str | Path, end_ns: int | None = None, comment: str = "") -> None:
        """Write the trace as an IEEE 1364 value change dump (:mod:`chiptwin.chip.vcd`): per
        block its states, the frame memory's occupancy, the DSP's busy signal, frame numbers."""
        write_vcd(self.events, path, frame_steps=self.frame_steps, end_ns=end_ns,
                  comment=comment)
