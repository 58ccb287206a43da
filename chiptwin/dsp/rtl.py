"""The ``rtl`` DSP level: the chip's DSP chain simulated from its Verilog RTL.

The RTL, its testbenches and the co-simulation harness are the ``rtl_ref`` package at the root of
the source tree (``rtl_ref/README.md``); this module is the chip model's entry point to it::

    from chiptwin.dsp.pipeline import chain_for
    from chiptwin.dsp.rtl import RtlPipeline

    dsp = RtlPipeline(chain_for(s.chip), report_error=..., keep_codes=...)

:class:`RtlPipeline` has the interface and fields of ``Pipeline("fixed", chain)`` and gives the
same values bit for bit. It needs Verilator (or Icarus Verilog): without it, the constructor
raises :class:`SimulatorMissing` with the command that installs it; :func:`missing` lists the
simulators that are not usable, for a check at validation time.
"""

from __future__ import annotations

import sys
from pathlib import Path

try:
    import rtl_ref  # noqa: F401  (installed, or on the path of a source checkout)
except ModuleNotFoundError:  # an editable install lists only chiptwin's packages
    _root = Path(__file__).resolve().parents[1]
    if not (_root / "rtl_ref" / "__init__.py").is_file():
        raise ModuleNotFoundError(
            "the rtl DSP level needs the rtl_ref package of the chiptwin source tree"
        ) from None
    sys.path.insert(0, str(_root))

from rtl_ref.pipeline import ChainResult, RtlPipeline, run_chain_fixed, run_chain_rtl  # noqa: E402
from rtl_ref.tools import INSTALL_HINT, SimulatorMissing, missing  # noqa: E402

__all__ = [
    "INSTALL_HINT",
    "ChainResult",
    "RtlPipeline",
    "SimulatorMissing",
    "missing",
    "run_chain_fixed",
    "run_chain_rtl",
]
