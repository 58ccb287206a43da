"""The chip as a discrete-event model: pixel array, ADCs, frame memory, DSP (SimPy)."""

from chiptwin.chip.des import ChipRun, Schedule, simulate_chip
from chiptwin.chip.trace import Recorder

__all__ = ["ChipRun", "Recorder", "Schedule", "simulate_chip"]
