"""The report's line on the paper's convention: the physical law's ratios, and a site the
convention leaves without signal (a 1-electron well, found by the scenario mutation test: the
report crashed formatting the undefined ratio)."""

from __future__ import annotations

from chiptwin.report.outputs import _physical_law_rows


def test_ratios_are_stated_and_an_undefined_one_says_why():
    p = {"emitter": "isotropic", "computed": True, "level": "expected",
         "signal_ratio": 0.4789, "snr_power_ratio": None}
    (label, text), = _physical_law_rows(p)
    assert label == "paper convention (NA²)"
    assert "signal × 0.479" in text
    assert "power SNR × undefined (no signal under the convention)" in text
    assert _physical_law_rows(None) == []
    off = {"emitter": "isotropic", "computed": False, "why_not": "run.beside_physical_law = false"}
    assert "not computed: run.beside_physical_law = false" in _physical_law_rows(off)[0][1]
