"""Bisection on synthetic monotone axes: it finds the threshold, costs fewer points than the grid,
and reports a planted non-monotone point."""

from __future__ import annotations

import pytest

from chiptwin.study.search import bisect, cheapest, violations


@pytest.mark.parametrize("threshold", [0, 1, 5, 8, 15])
def test_bisect_finds_a_known_threshold_in_log2_steps(threshold):
    calls = []

    def decide(i):
        calls.append(i)
        return "pass" if i >= threshold else "fail"

    found = bisect(16, decide, verify=0)
    assert found["answer"] == threshold
    assert found["violations"] == []
    assert len(calls) == len(set(calls)) <= 2 + 4  # both ends, then log2(16) halvings


def test_no_passing_point_gives_no_answer():
    assert bisect(10, lambda i: "fail")["answer"] is None


def test_undecided_counts_as_not_meeting():
    found = bisect(8, lambda i: "pass" if i >= 6 else ("undecided" if i >= 3 else "fail"))
    assert found["answer"] == 6


def test_planted_non_monotone_point_is_reported_and_skipped():
    """True threshold 4, but point 9 fails: the verification probe between the answer and the
    costliest pass lands on it; the violation is reported and the answer moves above it."""
    def decide(i):
        return "fail" if i == 9 else ("pass" if i >= 4 else "fail")

    found = bisect(16, decide, verify=1)
    assert {"pass_at": 4, "fail_at": 9} in found["violations"]
    assert found["answer"] == 10
    assert found["visited"][9] == "fail"


def test_an_undecided_probe_above_the_answer_is_no_violation():
    """Threshold 4; the verification probe lands on 9, undecided at the cap: its interval
    allows a pass, so the answer stays 4, as the study's answer rule (engine._answer: only a
    decided failure above a pass disqualifies it) reports it. The search once moved to 10 and
    the summary said 4."""
    def decide(i):
        return "undecided" if i == 9 else ("pass" if i >= 4 else "fail")

    found = bisect(16, decide, verify=1)
    assert found["visited"][9] == "undecided"
    assert found["answer"] == 4 and found["violations"] == []


def test_violations_and_cheapest_on_a_grid():
    assert violations({0: "fail", 1: "pass", 2: "fail", 3: "pass"}) == [
        {"pass_at": 1, "fail_at": 2}]
    costs = [(0, 1), (0, 0), (1, 0)]
    assert cheapest(costs, ["pass", "pass", "pass"]) == 1
    assert cheapest(costs, ["fail", "undecided", "pass"]) == 2
    assert cheapest(costs, ["fail", "fail", "fail"]) is None
