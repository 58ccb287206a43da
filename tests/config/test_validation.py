"""Malformed scenarios are refused with exit code 2, one line naming the key, nothing written."""

from __future__ import annotations

from pathlib import Path

import pytest

from chiptwin.cli import main
from chiptwin.config import ScenarioError, load_scenario
from tests.conftest import SMALL

# (what is wrong, how to break the small scenario, the key the message must name)
MALFORMED = [
    ("typo'd key", ("[chip.dsp]", "[chip.adc]\nbitz = 12\n[chip.dsp]"), "chip.adc.bitz"),
    ("wrong type", ('seed = 7', 'seed = "seven"'), "scenario.seed"),
    ("negative time", ("duration_s = 284.0", "duration_s = -5.0"), "run.duration_s"),
    ("zero pixels", ("rows = 4", "rows = 0"), "chip.rows"),
    ("impossible memory", ("[chip.dsp]", "[chip.memory]\ncapacity_bits = 100\n[chip.dsp]"),
     "chip.memory.capacity_bits"),
    ("missing section", ("[assay]", "[assayy]"), "[assay]"),
    ("unknown level", ("[run]", "[run.fidelity]\nkinetics = 'magic'\n[run]"),
     "run.fidelity.kinetics"),
    ("bad base", ('template = "TCAGGTTCCA"', 'template = "TCAGXTT"'), "assay.template"),
    ("key not a prefix", ('template = "TCAGGTTCCA"', 'template = "GGTTCCA"'), "assay.key"),
    ("ADC bits out of range", ("[chip.dsp]", "[chip.adc]\nbits = 40\n[chip.dsp]"), "chip.adc.bits"),
    ("frame too short", ("[run]", "[chip.timing]\nt_int_s = 2.0\n[run]"),
     "chip.timing.frame_period_s"),
    ("site off the array", ("at_pixels = [[1, 1], [2, 4]]", "at_pixels = [[1, 1], [9, 4]]"),
     "sites.at_pixels"),
    ("other assay's key", ("[sites]", "atp_fmol = 1.0\n[sites]"), "assay.atp_fmol"),
    ("ADC range below full well", ("[chip.dsp]", "[chip.adc]\nv_max_V = 0.5\n[chip.dsp]"),
     "chip.adc.v_max_V"),
    ("word narrower than ADC", ("[chip.dsp]", "[chip.memory]\nword_bits = 8\n[chip.dsp]"),
     "chip.memory.word_bits"),
    ("run too short for the flows", ("duration_s = 284.0", "duration_s = 100.0"),
     "run.duration_s"),
    ("dark frames after light", ("start_s = 4.0", "start_s = 1.0"), "assay.start_s"),
    ("NaN", ("[chip.dsp]", "[chip.pixel]\nqe = nan\n[chip.dsp]"), "chip.pixel.qe"),
    ("section is a value", ("[sites]", "optics = 3\n[sites]"), "optics"),
    ("bool for number", ("seed = 7", "seed = true"), "scenario.seed"),
]


@pytest.mark.parametrize(("what", "edit", "key"), MALFORMED, ids=[m[0] for m in MALFORMED])
def test_malformed_scenario_exits_2_naming_the_key(tmp_path, capsys, what, edit, key):
    path = tmp_path / "bad.toml"
    assert edit[0] in SMALL
    path.write_text(SMALL.replace(*edit, 1))
    out = tmp_path / "out"
    assert main(["run", str(path), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert key in err and str(path) in err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["bad.toml"]


def test_non_toml_file_is_refused(tmp_path, capsys):
    path = tmp_path / "notes.toml"
    path.write_text("this is [not toml\n")
    assert main(["validate", str(path)]) == 2
    assert "valid TOML" in capsys.readouterr().err


def test_missing_file_is_refused(tmp_path, capsys):
    assert main(["validate", str(tmp_path / "nowhere.toml")]) == 2
    assert "nowhere.toml" in capsys.readouterr().err


def test_typo_suggests_the_key(small_toml):
    with pytest.raises(ScenarioError, match="did you mean 'bits'"):
        load_scenario(small_toml, ["chip.adc.bitz=12"])


def test_set_overrides_meet_the_same_checks(small_toml):
    assert load_scenario(small_toml, ["chip.adc.bits=12"]).chip.adc.bits == 12
    with pytest.raises(ScenarioError, match=r"chip\.adc\.bits = 40: is above the largest "
                       r"allowed, 24; must be an integer in \["):
        load_scenario(small_toml, ["chip.adc.bits=40"])
    with pytest.raises(ScenarioError, match="section.key=value"):
        load_scenario(small_toml, ["chip.adc.bits"])


def test_dsp_levels_must_agree(small_toml):
    with pytest.raises(ScenarioError, match="run.fidelity"):
        load_scenario(small_toml, ["run.fidelity.dsp=float", "chip.dsp.mode=fixed"])


def test_every_bundled_scenario_validates():
    for path in sorted(Path(__file__).resolve().parents[2].joinpath("scenarios").glob("*.toml")):
        assert main(["validate", str(path)]) == 0, path
