"""The ``rtl`` DSP level: the chip's DSP chain simulated from its Verilog RTL.

The RTL, its testbenches and the co-simulation harness are the ``rtl_ref`` package at the root of
the source tree (``rtl_ref/README.md``); this module is the chip model's entry point to it::

    from chiptwin.dsp.pipeline import chain_for
    from chiptwin.twin.rtl import RtlPipeline

    dsp = RtlPipeline(chain_for(s.chip), report_error=..., keep_codes=...)

:class:`RtlPipeline` has the interface and fields of ``Pipeline("fixed", chain)`` and gives the
same values bit for bit. It needs Verilator (or Icarus Verilog): without it, the constructor
raises :class:`SimulatorMissing` with the command that installs it; :func:`missing` lists the
simulators that are not usable, for a check at validation time; :data:`routines` are the RTL
blocks of the program's stages (kinetics, fir8) that :class:`~chiptwin.dsp.program_pipeline.
ProgramPipeline` runs at this level.

It lives in the twin, not in ``chiptwin.dsp``: ``rtl_ref`` imports the DSP it verifies, so the
DSP importing it back was a circle (the layer drawing showed the one arrow up).
"""

from __future__ import annotations

from chiptwin.config.rtl_path import make_importable

make_importable()

from rtl_ref import routines  # noqa: E402
from rtl_ref.pipeline import ChainResult, RtlPipeline, run_chain_fixed, run_chain_rtl  # noqa: E402
from rtl_ref.tools import INSTALL_HINT, SimulatorMissing, missing  # noqa: E402

__all__ = [
    "INSTALL_HINT",
    "ChainResult",
    "RtlPipeline",
    "SimulatorMissing",
    "missing",
    "routines",
    "run_chain_fixed",
    "run_chain_rtl",
]
