"""Study files are validated like scenarios: exit 2, one line naming file/key/value/allowed,
nothing written; axes expand as documented."""

from __future__ import annotations

import re

import pytest

from chiptwin.cli import main, resolve_scenario
from chiptwin.study import load_study
from tests.conftest import real_data
from tests.study.conftest import STUDY, write_study

MALFORMED = [
    ("unknown axis key", ('key = "chip.adc.bits"', 'key = "chip.adc.bitz"'), "study.axis[0].key"),
    ("unknown section key", ("seed = 11", "seed = 11\nreplicate = 3"), "study.replicate"),
    ("bad range", ("values = [6, 8, 10]", 'range = [10, 6]\nscale = "int"'),
     "study.axis[0].range"),
    ("log range without n", ("values = [6, 8, 10]", 'range = [1, 10]\nscale = "log"'),
     "study.axis[0].n"),
    ("unknown scale", ("values = [6, 8, 10]", 'range = [6, 10]\nscale = "cubic"'),
     "study.axis[0].scale"),
    ("unknown metric", ('name = "calls_correct"', 'name = "calls_correctly"'),
     "study.metric[0].name"),
    ("requirement on a metric not computed", ('base_error_rate = "<= 0.2"',
                                              'snr_power = ">= 10"'), "study.requirement"),
    ("replicates 0", ("replicates = 3", "replicates = 0"), "study.replicates"),
    ("malformed requirement", ('"<= 0.2"', '"about 0.2"'), "study.requirement.base_error_rate"),
    ("loss without reference", ('reference = { "chip.adc.bits" = 14 }', ""),
     "study.metric"),
    ("inconsistent reference", ('{ "chip.adc.bits" = 14 }', '{ "chip.adc.bits" = 24 }'),
     "study.reference"),
    ("missing scenario", ('scenario = "small.toml"', 'scenario = "nope.toml"'),
     "study.scenario"),
    ("bisect on two budget axes", ("seed = 11", 'seed = 11\nsearch = "bisect"',
                                   "[[study.metric]]", '[[study.axis]]\nkey = '
                                   '"chip.dsp.average_frames"\nvalues = [1, 2]\n\n'
                                   "[[study.metric]]"), "study.search"),
    ("too many rows", ("replicates = 3", "replicates = 10000", "[[study.metric]]",
                       '[[study.axis]]\nkey = "chip.dsp.cms_samples"\nrange = [1, 200]\n'
                       'scale = "int"\n\n[[study.metric]]'), "study.replicates"),
    ("axis on another assay kind's key", ('key = "chip.adc.bits"', 'key = "assay.atp_fmol"'),
     "study.axis[0].key"),
    ("confidence out of range", ("confidence = 0.9", "confidence = 1.5"),
     "study.requirement.confidence"),
]


@pytest.mark.parametrize("what, edit, key", MALFORMED, ids=[m[0] for m in MALFORMED])
def test_malformed_study_exits_2_one_line_nothing_written(tmp_path, capsys, what, edit, key):
    text = STUDY
    for old, new in zip(edit[::2], edit[1::2], strict=True):
        text = text.replace(old, new, 1)
    assert text != STUDY, f"the edit for {what!r} did not apply"
    path = write_study(tmp_path, text)
    out = tmp_path / "out"
    assert main(["study", str(path), "--out", str(out), "--workers", "1", "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert str(path) in err and key in err, err
    assert not out.exists()


def test_typo_in_metric_suggests_the_name(tmp_path):
    path = write_study(tmp_path, STUDY.replace('"calls_correct"', '"calls_corect"', 1))
    with pytest.raises(ValueError, match="did you mean 'calls_correct'"):
        load_study(path, resolve_scenario)


def test_axes_expand_lin_log_int_zip_and_given(tmp_path):
    text = STUDY.replace('values = [6, 8, 10]', 'range = [6, 8]\nscale = "int"') + """
[[study.axis]]
key = "assay.dna_fmol"
range = [0.01, 1.0]
scale = "log"
n = 3
given = true

[[study.axis]]
key = "chip.dsp.clock_hz"
range = [1e6, 3e6]
scale = "lin"
n = 3
zip = true

[[study.axis]]
key = "chip.dsp.cycles_per_sample"
values = [1.0, 2.0, 3.0]
zip = true
"""
    study = load_study(write_study(tmp_path, text), resolve_scenario)
    assert study.axes[0].values == (6, 7, 8)
    assert study.axes[1].values == (0.01, 0.1, 1.0)
    assert study.axes[2].values == (1e6, 2e6, 3e6)
    points = study.points()
    assert len(points) == 3 * 3 * 3  # bits × amount × (clock, cycles zipped)
    zipped = {(p.params["chip.dsp.clock_hz"], p.params["chip.dsp.cycles_per_sample"])
              for p in points}
    assert zipped == {(1e6, 1.0), (2e6, 2.0), (3e6, 3.0)}
    assert {p.given for p in points} == {(0.01,), (0.1,), (1.0,)}
    assert len({p.id for p in points}) == len(points)


def test_every_bundled_study_validates():
    from chiptwin.cli import bundled_studies

    studies = bundled_studies()
    assert set(studies) >= {"adc_bits_pyro", "frame_memory", "lod_pyro", "calibrate_emva_set001"}
    for name, path in studies.items():
        if name.startswith("calibrate_"):  # reads its measured data set: skips without it
            real_data("emva1288", "set001_ccd_12bit_crop128")
        load_study(path, resolve_scenario)


def test_validate_checks_every_point_of_a_study(tmp_path, capsys):
    text = STUDY.replace("values = [6, 8, 10]", "values = [6, 8, 24]")  # 24 bits: too slow
    path = write_study(tmp_path, text)
    assert main(["validate", str(path)]) == 0
    out = capsys.readouterr().out
    assert "3 points × 3 replicates" in out
    assert "1 of 3 points are inconsistent" in out
    assert re.search(r"^ +1 × [\w.]+: ", out, flags=re.M), out
