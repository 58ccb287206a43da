"""Bad input to the long-read keys: exit 2, one line naming the key and what is allowed."""

from __future__ import annotations

from pathlib import Path

import pytest

from chiptwin.cli import main

SCENE = Path("scenarios/pyro_long_read.toml").read_text()
DRAWN = 'template = ""                        # drawn: key + template_length bases'
LENGTH = "template_length = 396                # insert after the key: 400 bases in all"

# (what is wrong, (text, replacement) pairs, the key the message names, a word of what is allowed)
BAD = [
    ("letter outside ACGT", [(DRAWN, 'template = "TCAGGXTC"'), (LENGTH, "")],
     "assay.template", "A, C, G, T"),
    ("empty template", [(LENGTH, "")], "assay.template", "A, C, G, T"),
    ("template and template_length", [(DRAWN, 'template = "TCAGGATC"')], "assay.template",
     "not both"),
    ("homopolymer beyond the caller", [(DRAWN, f'template = "TCAG{"A" * 13}C"'), (LENGTH, "")],
     "assay.template", "resolves up to 12"),
    ("droop out of range", [("droop_per_flow = 0.001", "droop_per_flow = 0.5")],
     "assay.droop_per_flow", "0.02"),
    ("CV out of range", [("dna_cv = 0.2", "dna_cv = 1.5")], "assay.dna_cv", "1"),
    ("carry-forward out of range", [("carry_forward = 0.01", "carry_forward = 0.2")],
     "assay.carry_forward", "0.05"),
    ("drawn homopolymers beyond the caller", [("template_homopolymer_max = 8",
                                               "template_homopolymer_max = 13")],
     "assay.template_homopolymer_max", "12"),
    ("flows beyond the schema", [("n_flows = 400", "n_flows = 20000")], "assay.n_flows",
     "10000"),
    ("flows beyond the time budget", [("[run]\n", "[run]\nmax_wall_s = 5.0\n")],
     "run.max_wall_s", "the run is estimated at"),
    ("droop at the cascade level", [('kinetics = "closed_form"', 'kinetics = "cascade"')],
     "assay.droop_per_flow", "cascade"),
    ("unknown caller", [('caller = "dephase"', 'caller = "viterbi"')], "assay.caller",
     "dephase"),
]


@pytest.mark.parametrize(("what", "edits", "key", "allowed"), BAD, ids=[b[0] for b in BAD])
def test_bad_long_read_input_exits_2_naming_the_key(tmp_path, capsys, what, edits, key,
                                                     allowed):
    text = SCENE
    for old, new in edits:
        assert old in text
        text = text.replace(old, new, 1)
    path = tmp_path / "bad.toml"
    path.write_text(text)
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert key in err and allowed in err and err.count("\n") == 1, err
    assert "Traceback" not in err


def test_the_scene_itself_validates(tmp_path):
    path = tmp_path / "ok.toml"
    path.write_text(SCENE)
    assert main(["validate", str(path)]) == 0
