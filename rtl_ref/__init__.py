"""rtl_ref: the Verilog RTL of chiptwin's DSP datapath and its bit-exact co-simulation harness.

The fixed-point model (:mod:`chiptwin.dsp`) is the specification. ``rtl/`` holds one Verilog
module per DSP block, parameterized by the register formats the model's configs declare;
``tb/`` the two testbenches (Verilator C++, Icarus Verilog); this package generates tops,
builds them, streams vectors made by the model through them and compares bit for bit.

Entry points: :class:`rtl_ref.cosim.Bank` (co-simulation), :mod:`rtl_ref.routines` (drop-in RTL
twins of the model's routines, returning :class:`chiptwin.dsp.FixedResult`),
:mod:`rtl_ref.pipeline` (the chip model's DSP stage through the RTL), ``python -m rtl_ref``
(command line; see ``rtl_ref/README.md``).
"""

from rtl_ref.tools import INSTALL_HINT, SimulatorMissing, missing, require

__all__ = ["INSTALL_HINT", "SimulatorMissing", "missing", "require"]
