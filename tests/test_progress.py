"""The progress line says what it knows: an upper-bound total (a study that stops early, a
bisection) is never shown as 100 % before the work ends, and the work's end says it stopped
early. Clock patched: no timing in the assertions."""

from __future__ import annotations

import re

from chiptwin.cli.progress import Progress


class _Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def _lines(capsys) -> list[str]:
    return [line.strip() for line in capsys.readouterr().err.splitlines()]


def test_a_search_whose_total_grows_never_says_100_percent_after_it_grew(monkeypatch, capsys):
    """A search that asks for rows look by look (a calibration past its estimate): after each
    look done equals the total asked so far. Shown as a fraction that read "100 %" at every
    look; once the total has moved, the count of rows so far and the bound."""
    clock = _Clock()
    monkeypatch.setattr("chiptwin.cli.progress.time.perf_counter", clock)
    p = Progress("rows", after_s=0.0)
    done = 0
    for _look in range(6):  # each look: 10 rows asked, then run
        for _ in range(10):
            clock.t += 1.0
            done += 1
            p(done, done + (10 - done % 10) % 10)  # the total known when the look started
    p.finish()
    lines = _lines(capsys)
    after = lines[lines.index("rows 10/10 (100 %) in 9.0 s") + 1:]  # before it grew: a whole
    assert after and not any("100 %" in line for line in after), lines
    assert any(re.fullmatch(r"rows \d+ of at most \d+, [\d.]+ rows/s", line) for line in after)
    assert re.fullmatch(r"rows 60 in [\d.]+ s", lines[-1]), lines[-1]


def test_a_bisection_never_says_100_percent(monkeypatch, capsys):
    """``chiptwin study`` on a bisection: the bound from the start (``at_most``), every look's
    end a count, the close a count with the time."""
    clock = _Clock()
    monkeypatch.setattr("chiptwin.cli.progress.time.perf_counter", clock)
    p = Progress("rows", after_s=0.0, at_most=True)
    for k in range(1, 31):
        clock.t += 1.0
        p(k, 30 if k <= 30 else k)  # the last look ends on the bound itself
    p.finish()
    lines = _lines(capsys)
    assert not any("%" in line for line in lines), lines
    assert lines[-1] == "rows 30 in 29.0 s", lines[-1]


def test_a_study_that_stops_early_says_so(monkeypatch, capsys):
    clock = _Clock()
    monkeypatch.setattr("chiptwin.cli.progress.time.perf_counter", clock)
    p = Progress("rows", after_s=0.0, at_most=True)
    for k in range(1, 41):
        clock.t += 0.5
        p(k, 120)
    p.finish()
    lines = _lines(capsys)
    assert all("%" not in line for line in lines), lines
    assert lines[0].startswith("rows ") and "of at most 120" in lines[0]
    assert lines[-1] == "rows 40 in 19.5 s (stopped early: 40 of at most 120)"


def test_a_whole_total_closes_once(monkeypatch, capsys):
    """A grid run to its total closes with 100 % once; finish() adds nothing after it."""
    clock = _Clock()
    monkeypatch.setattr("chiptwin.cli.progress.time.perf_counter", clock)
    p = Progress("rows", after_s=0.0)
    for k in range(1, 11):
        clock.t += 1.0
        p(k, 10)
    p.finish()
    lines = _lines(capsys)
    assert lines[-1] == "rows 10/10 (100 %) in 9.0 s"
    assert sum("100 %" in line for line in lines) == 1
