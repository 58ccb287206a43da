"""``chiptwin characterize``: the reference chip's datasheet, its outputs, and the CLI's contract
(exit codes, one-line errors, outputs whole or not at all, seeded)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from chiptwin.characterize import characterize
from chiptwin.characterize.datasheet import PARAMETERS
from chiptwin.cli import main
from tests.characterize.conftest import chip_scenario

PLOTS = ("photon_transfer.png", "snr.png", "linearity.png", "dark_signal.png", "histograms.png",
         "dark_current_temperature.png")


def test_reference_chip_datasheet_says_quantisation_regime(tmp_path, capsys):
    """``chiptwin characterize pyro_1fmol`` writes emva1288.json (every parameter with its unit
    and the scenario's value where one exists), datasheet.md and the standard's plots, and says
    that the 13-bit ADC is in the quantisation regime."""
    out = tmp_path / "ds"
    assert main(["characterize", "pyro_1fmol", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "QUANTISATION REGIME" in printed and "σ_y.dark" in printed
    doc = json.loads((out / "emva1288.json").read_text())
    assert doc["standard"] == "EMVA 1288 Release 4.0 Linear" and doc["flags"]["quantisation_regime"]
    assert set(doc["parameters"]) == set(PARAMETERS)
    for key, p in doc["parameters"].items():
        assert p["unit"] and "value" in p and "scenario_value" in p, key
    assert doc["parameters"]["quantum_efficiency"]["scenario_value"] == pytest.approx(25.6)
    assert doc["parameters"]["temporal_dark_noise"]["upper_limit"]
    assert doc["camera"]["adc_bits"] == 13 and doc["camera"]["cms_samples"] == 4
    md = (out / "datasheet.md").read_text()
    assert "| System gain | K |" in md and "QUANTISATION REGIME" in md
    for name in PLOTS:
        assert (out / name).stat().st_size > 1000 and f"]({name})" in md


def test_out_folder_of_someone_else_is_refused_before_measuring(tmp_path, capsys):
    """A folder holding other files is never replaced: exit 2, one line, nothing changed."""
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("keep")
    assert main(["characterize", "pyro_1fmol", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--out" in err[0]
    assert [p.name for p in out.iterdir()] == ["notes.txt"]


@pytest.mark.parametrize("argv, key", [
    (["characterize"], "characterize"),
    (["characterize", "pyro_1fmol", "--set", "chip.adc.bits=99"], "chip.adc.bits"),
    (["characterize", "no_such_scenario"], "no_such_scenario"),
])
def test_bad_input_exit_2_one_line_nothing_written(argv, key, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and key in err[0]
    assert list(tmp_path.iterdir()) == []


def test_seeded_and_rewritable(characterized, tmp_path):
    """The same scenario and seed give the same datasheet; the output folder of a previous
    characterisation is replaced whole."""
    first = characterized("ccd")
    again = characterize(chip_scenario("ccd"))
    a, b = first.to_json()["parameters"], again.to_json()["parameters"]
    assert {k: v["value"] for k, v in a.items()} == {k: v["value"] for k, v in b.items()}
    out = tmp_path / "o"
    first.write(out)
    (out / "emva1288.json").write_text("{}")
    again.write(out)
    assert json.loads((out / "emva1288.json").read_text())["parameters"] == b


def test_progress_counts_every_image():
    """``progress(done, total)`` reaches total = 4·points + 2L + 2·exposures·temperatures."""
    calls = []
    characterize(chip_scenario("ccd"), progress=lambda done, total: calls.append((done, total)))
    total = 4 * 60 + 2 * 16 + 2 * 6 * 6
    assert calls[-1] == (total, total) and len(calls) == total


def test_fixed_point_cms_with_m_a_power_of_two_is_the_float_datasheet(characterized):
    """At ``chip.dsp.mode = fixed`` the bench reads the bit-accurate CMS register; with M = 4 its
    division is exact (two fractional bits), so the datasheet is the float one, figure for figure
    (same seed, same draws)."""
    import dataclasses

    s = chip_scenario("reference")
    fixed = dataclasses.replace(s, chip=dataclasses.replace(
        s.chip, dsp=dataclasses.replace(s.chip.dsp, mode="fixed")))
    a = characterized("reference").to_json()["parameters"]
    b = characterize(fixed).to_json()["parameters"]
    assert {k: v["value"] for k, v in a.items()} == {k: v["value"] for k, v in b.items()}


def test_bundled_datasheet_is_current(characterized, tmp_path):
    """Regression: ``scenarios/datasheets/pyro_1fmol_chip.json`` is the reference chip's
    datasheet (its converters as built) as chiptwin measures it now, every figure within 5
    combined standard errors (exact where it has none). Regenerate it with ``chiptwin
    characterize pyro_1fmol --out OUT`` and copy ``OUT/emva1288.json`` there. It also
    configures a twin by name (``--from pyro_1fmol_chip``)."""
    from tests.conftest import SCENARIOS

    stored = json.loads((SCENARIOS / "datasheets" / "pyro_1fmol_chip.json").read_text())
    now = characterized("as_built").to_json()
    for key, p in now["parameters"].items():
        old = stored["parameters"][key]
        if p["value"] is None or old["value"] is None:
            assert p["value"] is None and old["value"] is None, key
            continue
        se = np.hypot(p["std_error"] or 0.0, old["std_error"] or 0.0)
        assert abs(p["value"] - old["value"]) <= max(5 * se, 1e-9 * abs(old["value"])), key
    assert stored["flags"] == now["flags"] and stored["camera"] == now["camera"]
    assert main(["characterize", "--from", "pyro_1fmol_chip", "--out", str(tmp_path / "o"),
                 "--quiet"]) == 0
