"""Sensitivity studies (kind = "sensitivity"): the one-at-a-time expansion around the scenario's
own values, the ranking and verdict on a case whose answer is known, the tornado and report,
every malformed assumption refused (exit 2, naming the key and the value), resumption and
identical tables for 1 and 2 workers."""

from __future__ import annotations

import json

import pytest

from chiptwin.cli import main, resolve_scenario
from chiptwin.study import load_study, run_study
from chiptwin.study.outputs import write_study_outputs
from chiptwin.study.rows import row_seed
from chiptwin.study.sensitivity import Assumption, analyse, conditions
from chiptwin.study.spec import point_id
from tests.study.conftest import comparable, write_study

#: The suite's small scenario (4 × 6 chip, 14 flows, ≈ 20 ms a run): the least DNA whose power
#: SNR's one-sided 90 % lower bound reaches 3e4. Measured at the reference (qe 0.4, 25 °C): 1.4e4
#: at 0.2 fmol, 8.6e4 at 0.5 fmol; the SNR grows ≈ as the amount squared, ×4–6 a step of this
#: axis. qe 0.1 … 0.9 scales the signal electrons ×0.25 … ×2.25 and moves the SNR ×16 down (2.2e4
#: at 1 fmol) and ×5 up (7.0e4 at 0.2 fmol): the answer moves from 2 to 0.2 fmol, 3 steps. The
#: temperature 15 … 35 °C moves the dark current ×2.7 either way (7 °C per doubling) and the SNR
#: ×1.2 up and ×1.5 down (1.8e4 and 9.7e3 at 0.2, 1.0e5 and 5.9e4 at 0.5 fmol): each side of 3e4
#: by ≥ ×1.7, so the answer stays at 0.5 fmol.
STUDY = """
[study]
name = "sens_small"
kind = "sensitivity"
scenario = "small.toml"
seed = 5
replicates = 3

[[study.axis]]
key = "assay.dna_fmol"
values = [0.1, 0.2, 0.5, 1.0, 2.0]

[[study.metric]]
name = "snr_power"

[study.requirement]
snr_power = ">= 3e4"
confidence = 0.9

[[study.assumption]]
key = "chip.pixel.qe"
range = [0.1, 0.9]
why = "front-side diode at 560 nm, a wide span for the test"

[[study.assumption]]
key = "chip.pixel.temperature_C"
range = [15.0, 35.0]
why = "room temperature ± 10 °C"
"""

#: The same design, 3 amounts × 5 conditions × 2 replicates: 30 rows, for resumption and workers.
CHEAP = STUDY.replace("replicates = 3", "replicates = 2").replace(
    "values = [0.1, 0.2, 0.5, 1.0, 2.0]", "values = [0.2, 0.5, 1.0]")


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """The small sensitivity study run once, its outputs written."""
    folder = tmp_path_factory.mktemp("sens")
    result = run_study(load_study(write_study(folder, STUDY), resolve_scenario), workers=1)
    out = folder / "out"
    out.mkdir()
    write_study_outputs(result, out)
    return result, out


def test_one_at_a_time_conditions_around_the_scenarios_own_values(tmp_path):
    text = STUDY.replace("seed = 5", 'seed = 5\nset = { "chip.pixel.qe" = 0.3 }').replace(
        "range = [0.1, 0.9]", "range = [0.3, 0.9]")
    study = load_study(write_study(tmp_path, text), resolve_scenario)
    # the reference is the scenario's value after `set` (qe 0.3, its low end: not run twice)
    # and the schema's default where the scenario says nothing (25 °C)
    assert [(a.key, a.reference) for a in study.assumptions] == [
        ("chip.pixel.qe", 0.3), ("chip.pixel.temperature_C", 25.0)]
    conds = [{k: p.params[k] for k in ("chip.pixel.qe", "chip.pixel.temperature_C")}
             for p in study.points() if p.params["assay.dna_fmol"] == 0.1]
    assert conds == [{"chip.pixel.qe": 0.3, "chip.pixel.temperature_C": 25.0},
                     {"chip.pixel.qe": 0.9, "chip.pixel.temperature_C": 25.0},
                     {"chip.pixel.qe": 0.3, "chip.pixel.temperature_C": 15.0},
                     {"chip.pixel.qe": 0.3, "chip.pixel.temperature_C": 35.0}]
    points = study.points()
    assert len(points) == 5 * 4 and len({p.id for p in points}) == len(points)
    assert all(p.id == point_id(p.params) for p in points)  # a row's seed: study seed + identity
    assert all(p.cost == (i % 5,) for i, p in enumerate(sorted(
        points, key=lambda p: (p.given, p.cost))))
    a = Assumption("k", 1.0, 3.0, 2.0, "")
    assert conditions((a,)) == [{"k": 2.0}, {"k": 1.0}, {"k": 3.0}]


def test_the_assumption_that_moves_the_answer_ranks_first(finished):
    result, _ = finished
    sens = result.summary["sensitivity"]
    (section,) = sens["results"]
    assert section["reference"]["value"] == 0.5
    qe, temperature = section["ranking"]
    assert qe["key"] == "chip.pixel.qe" and temperature["key"] == "chip.pixel.temperature_C"
    assert (qe["low"]["value"], qe["high"]["value"]) == (2.0, 0.2)
    assert qe["steps"] == 3 and qe["swing"] == pytest.approx(10.0)
    assert temperature["steps"] == 0 and temperature["swing"] == 1.0
    assert section["verdict"].startswith("decided by chip.pixel.qe: 2 at 0.1, 0.2 at 0.9")
    assert sens["verdict"] == section["verdict"] and sens["tolerance_steps"] == 1
    for r in result.table:  # seeded from the study seed and the point's identity
        assert r["seed"] == row_seed(5, point_id(r["params"]), r["replicate"])


def test_tornado_report_and_study_json_are_written(finished):
    result, out = finished
    png = out / "sensitivity.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 5000
    report = (out / "report.md").read_text()
    assert "## Sensitivity" in report and "![Tornado" in report
    row = next(line for line in report.splitlines() if line.startswith("| 1 | `chip.pixel.qe`"))
    assert "0.1 … 0.9 (0.4)" in row and "×10 (3 step(s))" in row and "snr_power" in row
    saved = json.loads((out / "study.json").read_text())
    assert saved["kind"] == "sensitivity" and saved["sensitivity"]["verdict"].startswith(
        "decided by chip.pixel.qe")


def _summary(values, answers, keys=("a", "b")):
    """A finished study's summary with the given answers: ``answers`` maps a condition (the
    assumption moved and its end, or "ref") to the budget value, None for none met."""
    refs = dict.fromkeys(keys, 1.0)
    out = []
    for cond, v in answers.items():
        given = dict(refs) if cond == "ref" else {**refs, cond[0]: cond[1]}
        out.append({"given": given, "point": None if v is None else {"x": v},
                    "bounds": {}})
    return {"axes": [{"key": "x", "values": values, "given": False}], "answer": out,
            "confidence": 0.95}


ASSUMED = (Assumption("a", 0.0, 2.0, 1.0, "why a"), Assumption("b", 0.5, 3.0, 1.0, "why b"))


def test_verdict_integer_axis_robust_only_when_identical():
    same = {"ref": 14, ("a", 0.0): 14, ("a", 2.0): 14, ("b", 0.5): 14, ("b", 3.0): 14}
    robust = analyse(_summary([12, 13, 14, 15, 16], same), ASSUMED)
    assert robust["verdict"].startswith("robust") and robust["tolerance_steps"] == 0
    one_bit = analyse(_summary([12, 13, 14, 15, 16], {**same, ("b", 3.0): 15}), ASSUMED)
    assert one_bit["verdict"].startswith("decided by b: 14 at 0.5, 15 at 3 (swing 1)")
    # an end no budget meets is off-scale: ranked first, its swing unbounded
    off = analyse(_summary([12, 13, 14, 15, 16], {**same, ("a", 2.0): None,
                                                  ("b", 0.5): 12}), ASSUMED)
    top, second = off["results"][0]["ranking"]
    assert top["key"] == "a" and top["off_scale"] and top["swing"] is None
    assert top["high"]["text"] == "none met (> 16)" and second["swing"] == 2
    assert top["swing_text"].startswith("≥ 3")  # 17 bits at least, against 14
    assert off["verdict"].startswith("decided by a: 14 at 0, none met (> 16) at 2")
    # none met in every condition: nothing moves
    nothing = analyse(_summary([12, 13, 14, 15, 16], dict.fromkeys(same, None)), ASSUMED)
    assert nothing["verdict"].startswith("robust") and "none met" in nothing["verdict"]


def test_verdict_names_ties_and_non_monotone_answers():
    answers = {"ref": 14, ("a", 0.0): 15, ("a", 2.0): 13, ("b", 0.5): 14, ("b", 3.0): 16}
    summary = _summary([12, 13, 14, 15, 16], answers)
    # condition b = 3 passed at 14, failed at 15: its answer 16 stands above the failure
    summary["monotonicity"] = {"violations": [{"kind": "decision", "axis": "x",
                                               "passes": {"x": 14, "a": 1.0, "b": 3.0},
                                               "fails": {"x": 15, "a": 1.0, "b": 3.0}}]}
    sens = analyse(summary, ASSUMED)
    assert sens["verdict"].startswith("decided by a: 15 at 0, 13 at 2 (swing 2); tied with b")
    b = sens["results"][0]["ranking"][1]
    assert not b["high"]["monotone"] and "non-monotone" in b["high"]["text"]
    assert b["low"]["monotone"] and b["low"]["text"] == "14"


def test_verdict_continuous_axis_tolerates_one_step():
    values = [0.01, 0.02, 0.05, 0.1, 0.2]
    one_step = {"ref": 0.05, ("a", 0.0): 0.1, ("a", 2.0): 0.05, ("b", 0.5): 0.05,
                ("b", 3.0): 0.05}
    assert analyse(_summary(values, one_step), ASSUMED)["verdict"].startswith("robust")
    two = analyse(_summary(values, {**one_step, ("b", 3.0): 0.01}), ASSUMED)
    b = two["results"][0]["ranking"][0]
    assert b["key"] == "b" and b["swing"] == pytest.approx(5.0) and b["steps"] == 2
    assert two["verdict"].startswith("decided by b") and "×5" in two["verdict"]


MALFORMED = [
    ("outside the schema's range", ("range = [0.1, 0.9]", "range = [0.1, 1.5]"),
     "study.assumption[0].range", "chip.pixel.qe = 1.5"),
    ("no such key", ('key = "chip.pixel.qe"', 'key = "chip.pixel.qee"'),
     "study.assumption[0].key", "'chip.pixel.qee'"),
    ("not a number", ('key = "chip.pixel.qe"', 'key = "chip.pixel.true_cds"'),
     "study.assumption[0].key", "is not a number"),
    ("already on an axis", ('key = "chip.pixel.qe"', 'key = "assay.dna_fmol"'),
     "study.assumption[0].key", "'assay.dna_fmol'"),
    ("another assay kind's key", ('key = "chip.pixel.qe"', 'key = "assay.atp_fmol"'),
     "study.assumption[0].key", "'assay.atp_fmol'"),
    ("lo not below hi", ("range = [0.1, 0.9]", "range = [0.9, 0.1]"),
     "study.assumption[0].range", "[0.9, 0.1]"),
    ("reference outside", ("range = [0.1, 0.9]", "range = [0.5, 0.9]"),
     "study.assumption[0].range", "the tornado needs the reference inside"),
    ("missing why", ('why = "room temperature ± 10 °C"', ""),
     "study.assumption[1].why", "chip.pixel.temperature_C"),
    ("listed twice", ('key = "chip.pixel.temperature_C"', 'key = "chip.pixel.qe"'),
     "study.assumption[1].key", "listed twice"),
    ("assumptions in a budget study", ('kind = "sensitivity"', ""), "study.assumption",
     "kind"),
    ("two budget axes", ("[[study.metric]]", '[[study.axis]]\nkey = "chip.adc.bits"\n'
                         "values = [10, 12]\n\n[[study.metric]]"), "study.kind",
     "'sensitivity'"),
    ("too many rows", ("values = [0.1, 0.2, 0.5, 1.0, 2.0]",
                       'range = [0.01, 1.0]\nscale = "log"\nn = 1000', "replicates = 3",
                       "replicates = 300"), "study.replicates", "5000 points × 300"),
    ("an end the scenario cannot take", ('key = "chip.pixel.temperature_C"',
                                         'key = "chip.pixel.capacitance_fF"',
                                         "range = [15.0, 35.0]", "range = [100.0, 3000.0]"),
     "study.assumption[1].range", "capacitance_fF = 100.0 gives an inconsistent scenario"),
]


@pytest.mark.parametrize("what, edit, key, said", MALFORMED, ids=[m[0] for m in MALFORMED])
def test_malformed_assumption_exits_2_naming_key_and_value(tmp_path, capsys, what, edit, key,
                                                           said):
    text = STUDY
    for old, new in zip(edit[::2], edit[1::2], strict=True):
        assert old in text, f"the edit for {what!r} does not apply"
        text = text.replace(old, new, 1)
    path = write_study(tmp_path, text)
    out = tmp_path / "out"
    assert main(["study", str(path), "--out", str(out), "--workers", "1", "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert str(path) in err and key in err and said in err, err
    assert not out.exists()


class _Stop(Exception):
    pass


def test_an_interrupted_sensitivity_study_resumes_to_the_same_table(tmp_path):
    path = write_study(tmp_path, CHEAP)
    whole = run_study(path, workers=1)
    db = tmp_path / "results.sqlite"

    stored = []

    def stop_at_12(done: int, total: int) -> None:  # rows are stored a whole task at a time
        if done >= 12:
            stored.append(done)
            raise _Stop

    with pytest.raises(_Stop):
        run_study(path, workers=1, db=db, progress=stop_at_12)
    again = run_study(path, workers=1, db=db)
    assert 12 <= stored[0] < len(whole.table)
    assert again.summary["runs"]["resumed"] == stored[0]
    assert again.summary["runs"]["computed"] == len(whole.table) - stored[0]
    assert comparable(again.table) == comparable(whole.table)
    assert again.summary["sensitivity"] == whole.summary["sensitivity"]


def test_one_and_two_workers_give_identical_tables(tmp_path):
    path = write_study(tmp_path, CHEAP)
    serial, pool = run_study(path, workers=1), run_study(path, workers=2)
    assert comparable(serial.table) == comparable(pool.table)
    assert serial.summary["sensitivity"] == pool.summary["sensitivity"]


def test_bundled_sensitivity_ranges_are_the_reference_chips():
    """The bundled sensitivity studies move each unpublished chip parameter across the plausible
    range the reference chip as built states for it (chiptwin.config.reference_chip), and the
    scene they study states the set's values: one source for both."""
    from chiptwin.config import load_scenario, reference_chip
    from chiptwin.config.load import read_toml
    from tests.conftest import SCENARIOS

    ranges = reference_chip.by_key()
    for name in ("sensitivity_bits", "sensitivity_lod"):
        doc = read_toml(SCENARIOS / "studies" / f"{name}.toml")["study"]
        chip = [a for a in doc["assumption"] if a["key"] in ranges]
        assert len(chip) >= 6, name
        for a in chip:
            ref = ranges[a["key"]]
            assert list(a["range"]) == [ref.lo, ref.hi], (name, a["key"])
        s = load_scenario(SCENARIOS / "studies" / doc["scenario"]) if doc["scenario"].endswith(
            ".toml") else load_scenario(doc["scenario"])
        assert reference_chip.stated(s)["as_reference"], name
