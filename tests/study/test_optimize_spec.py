"""An optimize study file is read strictly: every bad parameter, objective, constraint or stopping
rule is one ScenarioError naming the file, the key, the value and what is allowed (exit code 2),
before anything runs; and without Optuna the study exits 2 naming the extra to install.

The shared pieces of the optimize tests live here too: :data:`STUDY` (the suite's small pyro
scene, two keys, one objective and one constraint) and :func:`write`.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from chiptwin.cli import main
from chiptwin.config import ScenarioError
from chiptwin.study import load_study
from tests.conftest import SMALL
from tests.study.test_calibrate_spec import TINY

#: The small scene's snr_power over ADC bits and read noise, under an ADC power budget: the
#: comparator-free quantiser is dithered by the read noise, so at 12 bits the SNR peaks inside
#: the read-noise range (≈ 150–300 e⁻), and 13 bits exceed the 5e-8 W budget (1.3e-7 W).
STUDY = """
[study]
name = "opt_small"
kind = "optimize"
scenario = "small.toml"
seed = 5
replicates = 3
evaluations = 16
batch = 4

[[study.parameter]]
key = "chip.adc.bits"
range = [6, 13]
why = "a single-slope converter of 6 to 13 bits (the reference chip has 13)"

[[study.parameter]]
key = "chip.pixel.read_noise_e"
range = [20.0, 2000.0]
why = "a quiet readout (20 e⁻) to a noisy one; past the LSB it dithers the quantiser"

[[study.objective]]
metric = "snr_power"
direction = "maximize"

[[study.constraint]]
metric = "adc_power_w"
op = "<="
bound = 5e-8
judged = "estimate"
"""


def write(folder: Path, text: str = STUDY, scene: str = SMALL) -> Path:
    """The scene (as small.toml) and the study beside it; returns the study's path."""
    (folder / "small.toml").write_text(scene)
    path = folder / "opt.toml"
    path.write_text(text)
    return path


def refused(tmp_path: Path, text: str, scene: str = SMALL) -> ScenarioError:
    with pytest.raises(ScenarioError) as info:
        load_study(write(tmp_path, text, scene))
    assert str(tmp_path / "opt.toml") in str(info.value)  # the file is named
    return info.value


def test_a_valid_study_has_its_parameters_objectives_and_constraints(tmp_path):
    study = load_study(write(tmp_path))
    opt = study.optimization
    assert study.kind == "optimize" and study.search == "optuna"
    bits, noise = opt.parameters
    assert (bits.integer, bits.lo, bits.hi, bits.log) == (True, 6.0, 13.0, False)
    assert (noise.integer, noise.log) == (False, True)  # two decades: searched in log space
    assert opt.sampler == "TPESampler" and opt.metrics == ("snr_power", "adc_power_w")
    assert str(opt.constraints[0]) == "adc_power_w <= 5e-08"


def test_two_objectives_take_nsga2(tmp_path):
    text = STUDY + '\n[[study.objective]]\nmetric = "adc_power_w"\ndirection = "minimize"\n'
    assert load_study(write(tmp_path, text)).optimization.sampler == "NSGAIISampler"


@pytest.mark.parametrize(("old", "new", "key", "says"), [
    # an objective the scene cannot give: a pyro-only metric on a flux scene is in its own test
    ('metric = "snr_power"', 'metric = "snr_powr"', "study.objective[0].metric",
     "must be a metric of the catalogue"),
    ('metric = "snr_power"', 'metric = "snr_loss_db"', "study.objective[0].metric",
     "reference point"),
    # a constraint on a metric that does not exist
    ('metric = "adc_power_w"', 'metric = "chip_area"', "study.constraint[0].metric",
     "must be a metric of the catalogue"),
    # a key that cannot vary: not in the schema, not numeric
    ('key = "chip.adc.bits"', 'key = "chip.adc.bitz"', "study.parameter[0].key",
     "is not a key of chip.adc"),
    ('key = "chip.adc.bits"\nrange = [6, 13]', 'key = "run.fidelity.photons"\nrange = [1, 2]',
     "study.parameter[0].key", "is not a number"),
    # a range outside the key's own (bits: 1 … 24), an integer key's fractional end
    ("range = [6, 13]", "range = [6, 40]", "study.parameter[0].range",
     "outside the key's own range"),
    ("range = [6, 13]", "range = [6.5, 13]", "study.parameter[0].range", "is an integer"),
    ("range = [20.0, 2000.0]", "range = [2000.0, 20.0]", "study.parameter[1].range",
     "lo must be below hi"),
    # a wrong direction, a wrong operator, a bound that is not a number
    ('direction = "maximize"', 'direction = "up"', "study.objective[0].direction",
     '"maximize" or "minimize"'),
    ('op = "<="', 'op = "<"', "study.constraint[0].op", '"<=" or ">="'),
    ("bound = 5e-8", 'bound = "small"', "study.constraint[0].bound", "finite number"),
    ('why = "a quiet', 'whyy = "a quiet', "study.parameter[1].whyy", "unknown key"),
    ("evaluations = 16", "evaluations = 1", "study.evaluations", "[2, 10000]"),
    ("batch = 4", "batch = 4\nstop = { gain = 0.01, last = 2 }", "study.stop.last",
     "[batch = 4, evaluations = 16)"),
    ("batch = 4", "batch = 4\nstop = { gain = 2.0, last = 8 }", "study.stop.gain", "(0, 1)"),
    ("batch = 4", "batch = 4\naxis = []", "study.axis", 'not a key of a study of kind'),
])
def test_bad_input_names_the_key_the_value_and_what_is_allowed(tmp_path, old, new, key, says):
    assert old in STUDY
    exc = refused(tmp_path, STUDY.replace(old, new, 1))
    assert exc.key == key, exc
    assert says in str(exc), exc


def test_a_means_bound_needs_two_replicates(tmp_path):
    text = STUDY.replace("replicates = 3", "replicates = 1").replace('judged = "estimate"',
                                                                    'judged = "bound"')
    exc = refused(tmp_path, text)
    assert exc.key == "study.constraint[0].judged" and "replicates ≥ 2" in str(exc)
    load_study(write(tmp_path, STUDY.replace("replicates = 3", "replicates = 1")))  # estimate


def test_a_pyro_only_objective_on_a_flux_scene_is_refused(tmp_path):
    text = (STUDY.replace('metric = "snr_power"', 'metric = "base_error_rate"')
            .replace('direction = "maximize"', 'direction = "minimize"')
            .replace("[6, 13]", "[8, 16]").replace("[20.0, 2000.0]", "[20.0, 200.0]"))
    exc = refused(tmp_path, text, TINY)
    assert exc.key == "study.objective[0].metric"
    assert "needs base calls; the scenario's assay kind is 'flux'" in str(exc)


def test_a_named_choice_takes_any_key_its_rule_allows(tmp_path):
    text = STUDY.replace('key = "chip.adc.bits"\nrange = [6, 13]',
                         'key = "run.fidelity.photons"\nvalues = ["binned", "events"]')
    opt = load_study(write(tmp_path, text)).optimization
    assert opt.parameters[0].choices == ("binned", "events")
    bad = STUDY.replace('key = "chip.adc.bits"\nrange = [6, 13]',
                        'key = "run.fidelity.photons"\nvalues = ["binned", "photons"]')
    exc = refused(tmp_path, bad)
    assert exc.key == "study.parameter[0].values" and "'photons'" in str(exc)


def test_the_command_line_exits_2_naming_the_file(tmp_path, capsys):
    path = write(tmp_path, STUDY.replace('direction = "maximize"', 'direction = "max"'))
    assert main(["study", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert str(path) in err and "study.objective[0].direction" in err and "'max'" in err
    assert not (tmp_path / "out").exists()  # refused before anything was written


def test_without_optuna_the_study_exits_2_naming_the_extra(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "optuna", None)  # `import optuna` raises ImportError
    path = write(tmp_path)
    assert main(["study", str(path), "--out", str(tmp_path / "out"), "--workers", "1"]) == 2
    err = capsys.readouterr().err
    assert 'pip install "chiptwin[optimize]"' in err and "study.kind" in err
