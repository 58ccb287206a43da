"""The stream protocol and the harness around it: back-pressure changes the cycles, never the
values; a design that stops producing is reported, not waited for; VCDs on request."""

from __future__ import annotations

import numpy as np
import pytest

from chiptwin.dsp.frame_ops import BackgroundConfig
from rtl_ref import sim, vectors
from rtl_ref.cosim import Bank
from rtl_ref.frame_blocks import BackgroundBlock

pytestmark = pytest.mark.rtl


@pytest.mark.parametrize("kind", ["average", "fir", "kinetics"])
def test_heavy_back_pressure_moves_cycles_not_values(kind: str, banks) -> None:
    bank = banks[kind]
    inputs = vectors.for_block(bank.blocks[0], 20_000, np.random.default_rng(3))
    free = bank.run(0, inputs, "verilator")
    jammed = bank.run(0, inputs, "verilator", p_valid=0.3, p_ready=0.15, seed=99)
    assert free.ok and jammed.ok, free.text() + jammed.text()
    assert jammed.cycles > 3 * free.cycles
    assert np.all(np.diff(jammed.out_cycles) > 0)


def test_a_stalled_design_is_reported(banks) -> None:
    """Asking for more outputs than the design makes: the testbench gives up after
    ``max_idle`` cycles without a handshake, and the harness raises."""
    bank = banks["average"]
    blk = bank.blocks[0]
    inputs = vectors.for_block(blk, 512, np.random.default_rng(0))
    beats = blk.beats(inputs)
    n_out = len(blk.expected(inputs).d0)
    for simulator in ("verilator", "icarus"):
        with pytest.raises(sim.SimulationError, match="stalled"):
            sim.run(bank.build(simulator), 0, beats, n_out + 1, 4, max_idle=50)


def test_vcd_on_request(banks, tmp_path, monkeypatch) -> None:
    """``CHIPTWIN_RTL_VCD=dir`` makes every run write ``dir/<block>-<index>-<sim>.vcd``;
    Verilator then uses a ``--trace`` build."""
    monkeypatch.setenv(sim.VCD_ENV, str(tmp_path))
    bank = Bank([BackgroundBlock(BackgroundConfig())])
    inputs = vectors.for_block(bank.blocks[0], 300, np.random.default_rng(1))
    for simulator in ("icarus", "verilator"):
        report = bank.run(0, inputs, simulator, p_valid=0.8, p_ready=0.8)
        assert report.ok, report.text()
        text = (tmp_path / f"background-0-{simulator}.vcd").read_text()
        assert "$enddefinitions" in text and "in_valid" in text and "out_ready" in text
