"""What-ifs: a study re-asked with ``--set``, ``--axis``, ``--given``, ``--replicates`` and
``--quick`` (chiptwin.study.whatif), every value checked against its key's range before anything
runs, the overrides in the study's identity, and the study as run written as a file that runs
as it is (the same identity)."""

from __future__ import annotations

import tomllib

import pytest

from chiptwin.cli import main
from chiptwin.config import ScenarioError
from chiptwin.config.catalog import bundled_studies, resolve_scenario, resolve_study
from chiptwin.study import load_study
from chiptwin.study.whatif import (
    QUICK_AXIS_VALUES,
    QUICK_REPLICATES,
    Overrides,
    render_toml,
    study_toml,
    study_with,
)

ADC = resolve_study("adc_bits_pyro")


def adc(**kw):
    return study_with(ADC, Overrides(**kw), resolve_scenario, "adc_bits_pyro")


def axes(study) -> dict:
    return {a.key: (a.values, a.given, a.zip) for a in study.axes}


def test_no_override_is_the_file_as_it_is():
    assert adc().hash == load_study(ADC, resolve_scenario).hash
    assert adc().name == "adc_bits_pyro" and not adc().quick and not adc().asked


def test_set_goes_into_the_scene_and_pins_the_condition_of_its_key():
    s = adc(set=("chip.adc.comparator_noise_uV=45",))
    assert s.base_raw["chip"]["adc"]["comparator_noise_uV"] == 45.0
    assert "chip.adc.comparator_noise_uV" not in axes(s)  # the condition pinned at 45 µV
    assert "assay.dna_fmol" in axes(s)  # the other condition kept
    assert s.overrides["chip.adc.clock_hz"] == 160e6  # the study's own set kept


def test_axis_replaces_values_by_step_or_list_and_keeps_the_role():
    s = adc(axis=("chip.adc.bits=12:16:2", "assay.dna_fmol=0.5,0.05"))
    a = axes(s)
    assert a["chip.adc.bits"] == ((12, 14, 16), False, False)
    assert a["assay.dna_fmol"] == ((0.5, 0.05), True, False)  # a condition stays one
    assert axes(adc(axis=("chip.adc.clock_hz=0.16e9:0.2e9:0.02e9",)))["chip.adc.clock_hz"] == (
        (1.6e8, 1.8e8, 2e8), False, False)  # a new key: a budget axis, after the others
    assert list(axes(adc(axis=("chip.pixel.qe=0.3",))))[-1] == "chip.pixel.qe"


def test_given_adds_a_condition_and_plus_zips_two_keys():
    a = axes(adc(given=("chip.pixel.qe=0.3,0.6",)))
    assert a["chip.pixel.qe"] == ((0.3, 0.6), True, False)
    s = adc(given=("chip.pixel.diode_w_um+chip.pixel.diode_h_um=50,100",))
    a = axes(s)
    assert a["chip.pixel.diode_w_um"] == a["chip.pixel.diode_h_um"] == ((50.0, 100.0), True, True)
    diodes = {(p.params["chip.pixel.diode_w_um"], p.params["chip.pixel.diode_h_um"])
              for p in s.points()}
    assert diodes == {(50.0, 50.0), (100.0, 100.0)}  # square diodes, not four rectangles


def test_replicates_and_quick_say_what_they_shrank():
    assert adc(replicates=7).replicates == 7
    s = adc(quick=True)
    assert s.replicates == QUICK_REPLICATES
    bits = axes(s)["chip.adc.bits"][0]
    assert len(bits) == QUICK_AXIS_VALUES and (bits[0], bits[-1]) == (10, 16)  # ends kept
    assert bits == (10, 12, 14, 16)
    assert axes(s)["chip.adc.comparator_noise_uV"][0] == (0.0, 30.52, 61.04, 122.07)  # whole
    assert s.quick == "replicates 90 → 10; chip.adc.bits 7 values → 10, 12, 14, 16"
    assert "quick" in s.name
    # with --replicates, quick shrinks the grid only
    assert adc(quick=True, replicates=30).replicates == 30
    lod = study_with(resolve_study("lod_pyro"), Overrides(quick=True), resolve_scenario)
    assert lod.batch <= lod.replicates == QUICK_REPLICATES  # a look's batch shrunk with them


def test_overrides_are_the_identity_and_their_order_is_not():
    plain = adc()
    a = adc(set=("chip.pixel.qe=0.3",), given=("chip.pixel.read_noise_e=50,200",))
    b = study_with(ADC, Overrides(given=("chip.pixel.read_noise_e=50,200",),
                                  set=("chip.pixel.qe=0.3",)), resolve_scenario, "other words")
    assert a.hash != plain.hash and a.name != plain.name
    assert a.hash == b.hash and a.name == b.name  # the same what-if: the same folder, resumed
    assert adc(set=("chip.pixel.qe=0.31",)).hash != adc(set=("chip.pixel.qe=0.3",)).hash


@pytest.mark.parametrize("name", sorted(bundled_studies()))
def test_every_bundled_study_written_as_a_file_is_the_same_study(name, tmp_path):
    raw = tomllib.loads(bundled_studies()[name].read_text())
    assert tomllib.loads(render_toml(raw)) == raw
    if raw["study"].get("kind") not in (None, "budget", "sensitivity"):
        return  # a calibration's measured data may be absent here
    study = load_study(bundled_studies()[name], resolve_scenario)
    (tmp_path / "study.toml").write_text(study_toml(study))
    again = load_study(tmp_path / "study.toml", resolve_scenario)
    assert again.hash == study.hash and again.points() == study.points()


def test_a_what_if_written_as_a_file_is_the_same_study(tmp_path):
    s = adc(set=("chip.adc.comparator_noise_uV=45",), given=(
        "chip.pixel.diode_w_um+chip.pixel.diode_h_um=50,100",), quick=True)
    path = tmp_path / "study.toml"
    path.write_text(s.text)  # the text is the file: what the CLI writes
    again = load_study(path, resolve_scenario)
    assert (again.hash, again.name, again.quick, again.asked) == (s.hash, s.name, s.quick,
                                                                  s.asked)
    assert s.asked == ("chiptwin study adc_bits_pyro --set chip.adc.comparator_noise_uV=45 "
                       "--given chip.pixel.diode_w_um+chip.pixel.diode_h_um=50,100 --quick")


#: Bad overrides, and what the refusal must say besides naming the override.
BAD = [
    (["--set", "chip.adc.bits=40"], "must be an integer in [1, 24]"),
    (["--set", "chip.adc.bitz=4"], "did you mean 'bits'"),
    (["--set", "chip.adc.bits=12"], "budget axis; --axis chip.adc.bits=12"),
    (["--set", "assay.atp_fmol=1"], "not used by the scenario's assay kind"),
    (["--set", "chip.pixel.diode_w_um=200"], "chip.pitch_um"),  # in range, inconsistent scene
    (["--axis", "chip.adc.bits=12:30:2"], "chip.adc.bits = 26"),
    (["--axis", "chip.adc.bits=16:12:1"], "lo ≤ hi, step > 0"),
    (["--axis", "chip.adc.bits=12,12"], "must not repeat a value"),
    (["--axis", "chip.adc.bits"], "must look like KEY=v1,v2"),
    (["--given", "chip.pixel.qe=0.5,1.5"], "in (0, 1]"),
    (["--given", "chip.pixel.qe=0.5,"], "none empty"),
    (["--replicates", "0"], "[1, 10000]"),
]


@pytest.mark.parametrize(("argv", "says"), BAD, ids=[" ".join(a) for a, _ in BAD])
def test_a_bad_override_exits_2_naming_it_before_anything_runs(argv, says, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["study", "adc_bits_pyro", "--out", str(out), *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"chiptwin: error: {' '.join(argv)}"), err  # the override first
    assert says in err, err
    assert not out.exists()  # nothing run, nothing written


def test_overrides_of_a_calibration_are_refused_naming_the_overrides():
    path = bundled_studies()["calibrate_emva_set001"]
    with pytest.raises(ScenarioError, match=r"^--quick: study.kind = 'calibrate'"):
        study_with(path, Overrides(quick=True), resolve_scenario)


def test_a_condition_zipped_with_a_budget_axis_is_refused(tmp_path):
    """Zipped axes form one group, a budget or a condition: a mix was read as whichever came
    first."""
    from tests.study.conftest import STUDY, write_study

    text = STUDY.replace("values = [6, 8, 10]", "values = [6, 8, 10]\nzip = true") + (
        '\n[[study.axis]]\nkey = "chip.pixel.qe"\nvalues = [0.3, 0.4, 0.5]\ngiven = true\n'
        "zip = true\n")
    with pytest.raises(ScenarioError, match="all conditions .* or all budget axes"):
        load_study(write_study(tmp_path, text))
    path = write_study(tmp_path, text.replace("given = true\n", ""))
    assert len(load_study(path).points()) == 3  # both budget: zipped, three points
    with pytest.raises(ScenarioError, match=r"^--given chip.pixel.diode_w_um\+"):
        study_with(path, Overrides(given=("chip.pixel.diode_w_um+chip.pixel.diode_h_um=50,90",)))
