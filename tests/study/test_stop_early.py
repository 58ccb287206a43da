"""A grid that stops early (``stop_early = true``): the per-look levels keep the study's confidence
over the looks (Monte Carlo on the decision rule itself), and on a real study it stores fewer rows
for the same answer, resumably."""

from __future__ import annotations

import math

import numpy as np
import pytest

from chiptwin.cli import main, resolve_scenario
from chiptwin.detection.stats import (
    decide,
    look_levels,
    look_sizes,
    mean_estimate,
    rate_estimate,
)
from chiptwin.study import load_study, run_study
from tests.study.conftest import STUDY, write_study


def test_the_looks_spend_exactly_the_error_rate():
    for confidence, looks in [(0.95, 9), (0.9, 2), (0.99, 30)]:
        levels = look_levels(confidence, looks)
        assert len(levels) == looks
        assert math.isclose(sum(1 - c for c in levels), 1 - confidence)
        assert levels[-1] == pytest.approx(1 - 0.9 * (1 - confidence))  # the cap keeps 90 %
        assert all(c > levels[-1] for c in levels[:-1])
    assert look_levels(0.95, 1) == (0.95,)  # one look: the one-look grid's level
    assert look_sizes(90, 10) == tuple(range(10, 100, 10))
    assert look_sizes(7, 3) == (3, 6, 7) and look_sizes(3, 10) == (3,)


def sequential(rows: np.ndarray, op: str, threshold: float, batch: int,
               levels: tuple[float, ...], estimate) -> str:
    """The engine's rule for one requirement: at look k the first ``look_sizes[k]`` rows, the
    bound at ``levels[k]``; the first decided look ends it."""
    for n, level in zip(look_sizes(len(rows), batch), levels, strict=True):
        d = decide(estimate(rows[:n], level), op, threshold)
        if d != "undecided":
            return d
    return "undecided"


def wrong_rate(draw, op: str, threshold: float, met: bool, batch: int, levels, estimate,
               studies: int, seed: int) -> float:
    """The share of simulated sequential studies whose decision is wrong: ``fail`` when the true
    value meets the requirement, ``pass`` when it does not."""
    rng = np.random.default_rng(seed)
    wrong = "fail" if met else "pass"
    return sum(sequential(draw(rng), op, threshold, batch, levels, estimate) == wrong
               for _ in range(studies)) / studies


def tolerance(alpha: float, studies: int) -> float:
    """Three binomial standard errors of a rate α estimated from ``studies`` studies."""
    return 3 * math.sqrt(alpha * (1 - alpha) / studies)


@pytest.mark.parametrize("op", ["<=", ">="])
@pytest.mark.parametrize("offset", [0.0, 1.0])
def test_mean_decisions_are_wrong_at_most_one_minus_confidence(op, offset):
    """A metric whose true mean sits at the threshold (met: a wrong decision is a fail) or one
    standard error of the cap's mean (σ/√cap) on the wrong side (not met: a wrong decision is a
    pass): 90 rows in looks of 10 at 95 %, 2,000 simulated studies, normal rows. Taken at 95 %
    at every look instead (no account of the looks), the same studies decide wrongly far more
    often than 5 %: the check can fail."""
    cap, batch, confidence, studies = 90, 10, 0.95, 2000
    sign = 1.0 if op == "<=" else -1.0
    mean = sign * offset / math.sqrt(cap)  # threshold 0, σ = 1
    def draw(rng): return rng.normal(mean, 1.0, cap)
    levels = look_levels(confidence, len(look_sizes(cap, batch)))
    met = offset == 0.0
    wrong = wrong_rate(draw, op, 0.0, met, batch, levels, mean_estimate, studies, seed=1)
    assert wrong <= 1 - confidence + tolerance(1 - confidence, studies)
    if met:
        naive = wrong_rate(draw, op, 0.0, met, batch, (confidence,) * len(levels),
                           mean_estimate, studies, seed=1)
        assert naive > 1 - confidence + tolerance(1 - confidence, studies)


def test_rate_decisions_are_wrong_at_most_one_minus_confidence():
    """A rate at its threshold (base errors ≤ 2 %: met, a wrong decision is a fail): runs of 36
    trials, 60 runs in looks of 10, Korn–Graubard bounds as a study takes them, 600 studies."""
    cap, batch, confidence, studies, p = 60, 10, 0.95, 600, 0.02
    def draw(rng): return np.stack([rng.binomial(36, p, cap), np.full(cap, 36)], axis=1)
    def estimate(rows, level): return rate_estimate(rows[:, 0], rows[:, 1], level)
    levels = look_levels(confidence, len(look_sizes(cap, batch)))
    wrong = wrong_rate(draw, "<=", p, True, batch, levels, estimate, studies, seed=2)
    assert wrong <= 1 - confidence + tolerance(1 - confidence, studies)


# --- a real study ---------------------------------------------------------------------------------

TINY = STUDY.replace("replicates = 3", "replicates = 6\nbatch = 2").replace(
    "values = [6, 8, 10]", "values = [11, 13]").replace(
    'base_error_rate = "<= 0.2"',
    'base_error_rate = "<= 0.2"\nsnr_loss_db = "<= 5"\ncalls_correct = ">= 0.5"')


def test_a_grid_that_stops_early_stores_fewer_rows_for_the_same_answer(tmp_path):
    """11 bits lose ≈ 13 dB against 14 bits, decided against 5 dB at the first look of 2
    replicates (a fail); 13 bits lose ≈ 2.4 dB, but its 2 reads a run all right bound
    calls_correct above 0.5 only from 8 reads at the interim level 1 − 0.1·0.1/2 (0.005^(1/8) =
    0.52): it passes at the second look. 2 + 4 rows instead of 6 + 6 (the reference runs its 6):
    replicate counts differ between points, and the answer is the whole grid's."""
    (tmp_path / "full").mkdir()
    full = run_study(write_study(tmp_path / "full", TINY), workers=1)
    early_path = write_study(tmp_path, TINY.replace("batch = 2", "batch = 2\nstop_early = true"))
    db = tmp_path / "early.sqlite"
    early = run_study(early_path, workers=1, db=db)
    assert early.answer[0]["point"] == full.answer[0]["point"] == {"chip.adc.bits": 13}
    assert [p["status"] for p in early.summary["points"]] == [
        p["status"] for p in full.summary["points"]] == ["fail", "pass"]
    assert early.summary["monotonicity"] == full.summary["monotonicity"]
    assert len(full.table) == 18 and len(early.table) == 6 + 2 + 4
    se = early.summary["stop_early"]
    assert se["runs_saved"] == 6
    assert [k["points_stopped"] for k in se["looks"]] == [1, 1, 0]
    assert [p["replicates"] for p in early.summary["points"]] == [2, 4]
    # every stored row is a row of the whole grid (same seeds, same values)
    whole = {(r["point"], r["replicate"]): r["metrics"] for r in full.table}
    assert all(whole[(r["point"], r["replicate"])] == r["metrics"] for r in early.table)
    again = run_study(early_path, workers=1, db=db)  # resumed: nothing to run, the same answer
    assert again.summary["runs"]["computed"] == 0 and again.answer == early.answer


def test_report_says_what_stopping_early_saved(tmp_path):
    path = write_study(tmp_path, TINY.replace("batch = 2", "batch = 2\nstop_early = true"))
    out = tmp_path / "out"
    assert main(["study", str(path), "--out", str(out), "--workers", "1", "--quiet"]) == 0
    report = (out / "report.md").read_text()
    assert "Stopped early: 12 runs of the whole grid's 18 (6 saved, 33%)" in report
    assert "stop_early: replicates added in looks of `batch`" in report


@pytest.mark.parametrize("edit, message", [
    ("stop_early = 1", "must be true or false"),
    ('stop_early = true\nsearch = "bisect"', 'applies to search = "grid"'),
])
def test_bad_stop_early_is_refused(tmp_path, edit, message):
    path = write_study(tmp_path, TINY.replace("batch = 2", "batch = 2\n" + edit))
    with pytest.raises(Exception, match="study.stop_early") as info:
        load_study(path, resolve_scenario)
    assert message in str(info.value)


def test_stop_early_without_a_requirement_is_refused(tmp_path):
    text = TINY.replace("batch = 2", "batch = 2\nstop_early = true").split(
        "[study.requirement]")[0]
    path = write_study(tmp_path, text)
    with pytest.raises(Exception, match="needs a \\[study.requirement\\]"):
        load_study(path, resolve_scenario)
