"""A budget answer is the least value that meets the requirement: an interval between grid points
where the grid does not resolve it, the frame memory a schedule needs where a run confirms it;
and the two statements that once said less than they should (a resumed folder's change, a read
judged on a template its flows cannot reach)."""

from __future__ import annotations

import pytest

from chiptwin.config import ScenarioError
from chiptwin.config.consistency_chip import memory_needed_bits
from chiptwin.config.load import load_scenario
from chiptwin.study.search import least_value
from chiptwin.study.store import IDENTITY_CHANGED, describe_change
from tests.study.conftest import write_study

#: least_value(values, statuses, answer index, floor) → (least, between, resolved)
CASES = [
    # the grid brackets the need: an interval, never the grid point as the need
    (([65536, 262144, 524288], ["invalid", "invalid", "pass"], 2, None),
     (None, [262144, 524288], False)),
    (([0.01, 0.1, 1.0], ["fail", "undecided", "pass"], 2, None), (None, [0.1, 1.0], False)),
    # neighbouring integers: nothing lies between, the answer is the least value
    (([12, 13, 14], ["fail", "fail", "pass"], 2, None), (14, [13, 14], True)),
    # the cheapest value tried passes: at most it, unless it is the least the key allows
    (([4, 8], ["pass", "pass"], 0, None), (None, [None, 4], False)),
    (([1, 4, 16], ["pass", "pass", "pass"], 0, 1), (1, [None, 1], True)),
    # a bisection that never ran the value below: no lower bound is claimed
    (([1, 2, 3, 4], ["not_visited", "not_visited", "fail", "pass"], 3, None),
     (4, [3, 4], True)),
    (([10, 20, 30], ["fail", "not_visited", "pass"], 2, None), (None, [None, 30], False)),
]


@pytest.mark.parametrize(("args", "want"), CASES)
def test_the_least_value_is_an_interval_unless_nothing_lies_between(args, want):
    got = least_value(*args)
    assert (got["least"], got["between"], got["resolved"]) == want
    if not got["resolved"] and got["between"][0] is not None:
        assert "does not resolve it" in got["text"]


def test_no_answer_has_no_least_value():
    assert least_value([1, 2], ["fail", "fail"], None) is None


def _frames_dropped(s) -> int:
    from chiptwin.twin import run

    return run(s).summary["chip"]["overflows"]  # frames lost to a full memory


def test_the_schedules_memory_runs_and_one_frame_less_is_refused(small_toml):
    """At :func:`memory_needed_bits` no frame is dropped; one frame less is refused by
    validation, naming the key and the bits it must reach."""
    s = load_scenario(small_toml)
    need = memory_needed_bits(s)
    assert need == 4 * s.chip.frame_bits + s.chip.memory.word_bits * s.chip.n_pixels
    assert _frames_dropped(load_scenario(small_toml, [f"chip.memory.capacity_bits={need}"])) == 0
    with pytest.raises(ScenarioError, match=f"chip.memory.capacity_bits.*≥ {need}"):
        load_scenario(small_toml, [f"chip.memory.capacity_bits={need - s.chip.frame_bits}"])
    with pytest.raises(ScenarioError, match="chip.memory.capacity_bits"):
        load_scenario(small_toml, [f"chip.memory.capacity_bits={need - 1}"])


def test_pyro_1fmol_needs_264192_bits_not_the_grids_524288():
    """The frame_memory study's answer on pyro_1fmol with 16 dark frames: 16 frames × 16,384
    bits + the 2,048-bit dark reference = 264,192 bits, run without a dropped frame; the grid
    tried 262,144 (refused) and 524,288 (passes)."""
    s = load_scenario("pyro_1fmol", ["chip.dsp.average_frames=1", "chip.dsp.n_dark_frames=16"])
    need = memory_needed_bits(s)
    assert need == 16 * 16_384 + 2_048 == 264_192
    at = load_scenario("pyro_1fmol", ["chip.dsp.average_frames=1", "chip.dsp.n_dark_frames=16",
                                      f"chip.memory.capacity_bits={need}"])
    assert _frames_dropped(at) == 0
    with pytest.raises(ScenarioError, match="264192"):
        load_scenario("pyro_1fmol", ["chip.dsp.n_dark_frames=16",
                                     f"chip.memory.capacity_bits={need - 16_384}"])


MEMORY_STUDY = """
[study]
name = "small_memory"
scenario = "small.toml"
seed = 5
replicates = 2
vary_chip = false

[[study.axis]]
key = "chip.memory.capacity_bits"
values = [{lo}, {hi}]

[[study.metric]]
name = "frames_dropped"

[[study.metric]]
name = "snr_power"

[study.requirement]
frames_dropped = "<= 0"
confidence = 0.9
"""


def test_a_memory_study_states_the_schedules_need_checked_by_a_run(tmp_path):
    """The grid brackets the need (one frame below it is invalid, four frames above passes);
    the study states the need itself, after a run at that size dropped nothing and gave the
    answer's first run's metrics bit for bit."""
    from chiptwin.study.engine import run_study
    from chiptwin.study.outputs import answer_lines, write_study_outputs
    from tests.conftest import SMALL

    (tmp_path / "small.toml").write_text(SMALL)
    s = load_scenario(tmp_path / "small.toml")
    need, frame = memory_needed_bits(s), s.chip.frame_bits
    path = write_study(tmp_path, MEMORY_STUDY.format(lo=need - frame, hi=need + 4 * frame))
    result = run_study(path, workers=1, db=tmp_path / "results.sqlite")
    write_study_outputs(result, tmp_path)
    least = result.summary["answer"][0]["least"]["chip.memory.capacity_bits"]
    assert least["least"] == need and least["resolved"]
    assert least["grid"]["between"] == [need - frame, need + 4 * frame]
    assert least["check"]["frames_dropped"] == 0
    assert any(f"{need:,} bits" in line for line in answer_lines(result.summary))


def test_a_resumed_folder_whose_identity_changed_says_what_the_identity_is():
    """The identity is the parsed [study] table and its overrides: where nothing of them
    differs key by key (a folder made under another identity rule), the refusal says so, not
    "its text (comments or layout)"."""
    text = '[study]\nname = "a"\nscenario = "x.toml"\n'
    moved = text.replace("x.toml", "/elsewhere/x.toml") + "# a comment\n"
    assert describe_change(text, "{}", moved, "{}") == IDENTITY_CHANGED
    assert "parsed [study] table" in IDENTITY_CHANGED and "overrides" in IDENTITY_CHANGED
    assert describe_change(text, "{}", text.replace('"a"', '"b"'), "{}") == "study name: 'a' → 'b'"


def test_a_template_longer_than_its_flows_reach_is_judged_on_the_bases_they_reach(small_toml):
    """A 40-base template in 14 flows: the summary names the template's length, the true
    sequence is the part the flows reach, and the headline says "reads the first N bases (the
    flows reach base N of 40)" beside the sites called right."""
    from chiptwin.report.outputs import headline
    from chiptwin.twin import run

    template = "TCAGGTTCCA" + "ACGTTGCAAC" * 3
    s = load_scenario(small_toml, [f'assay.template="{template}"'])
    summary = run(s).summary
    n = len(summary["true_sequence"])
    assert summary["template_length"] == len(template) == 40 and 0 < n < 40
    rows = dict(headline(summary))
    assert rows["reads"] == f"the first {n} bases (the flows reach base {n} of 40)"
    short = dict(headline({**summary, "template_length": n}))  # a template the flows finish
    assert "reads" not in short

