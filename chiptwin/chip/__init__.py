"""The chip as a discrete-event model: pixel array, ADCs, frame memory, DSP (SimPy); a steady run
also in closed form (:mod:`chiptwin.chip.steady`)."""

from chiptwin.chip.des import ChipRun, Schedule, simulate_chip
from chiptwin.chip.steady import SteadyRun, steady_run
from chiptwin.chip.trace import Recorder

__all__ = ["ChipRun", "Recorder", "Schedule", "SteadyRun", "simulate_chip", "steady_run"]
