"""The chip as a discrete-event model: pixel array, ADCs, frame memory, DSP (SimPy); a steady run
also in closed form (:mod:`chiptwin.chip.steady`); its event trace as a waveform
(:mod:`chiptwin.chip.vcd`)."""

from chiptwin.chip.des import ChipRun, Schedule, simulate_chip
from chiptwin.chip.steady import SteadyRun, steady_run
from chiptwin.chip.trace import Recorder
from chiptwin.chip.vcd import write_vcd

__all__ = ["ChipRun", "Recorder", "Schedule", "SteadyRun", "simulate_chip", "steady_run",
           "write_vcd"]
