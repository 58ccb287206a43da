"""The numbers README.md and the docs quote are the runs' own: every marked quote
(``**text**<!-- answer: KEY -->``) equals its entry in ``docs/answers.json``, every entry is quoted
somewhere and every marker names an entry (``scripts/answers.py`` writes both), and a scene
rerun at its documented seed gives the entries it made, bit for bit."""

from __future__ import annotations

import importlib.util
import json
import math
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _script():
    spec = importlib.util.spec_from_file_location("answers_script", ROOT / "scripts" / "answers.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclass looks its module up
    spec.loader.exec_module(module)
    return module


answers = _script()


def _recorded() -> dict:
    return json.loads(answers.ANSWERS.read_text())


def test_every_marked_quote_is_its_entry_and_every_entry_is_quoted():
    assert answers.problems(_recorded()) == []


def test_every_recorded_entry_is_registered_with_its_source_and_machine():
    registered = {e.key: e for e in answers.ENTRIES}
    for key, record in _recorded()["entries"].items():
        e = registered[key]  # a value no entry makes would be a number typed in by hand
        assert record["source"] == f"chiptwin {e.kind} {e.source}"
        assert record["path"] == list(e.path) and record["text"] == e.text(record["value"], record)
        assert record["machine"]["cores"] >= 1 and record["run_s"] > 0 and record["date"]


def test_a_stale_quote_a_stray_marker_and_an_unquoted_entry_are_each_found(tmp_path):
    """The check on a copy: a quote edited by hand, a marker of no entry, an entry no page
    quotes."""
    (tmp_path / "docs").mkdir()
    (tmp_path / "README.md").write_text("memory **524,288 bits**<!-- answer: m.bits --> and "
                                        "**3**<!-- answer: nowhere -->\n")
    (tmp_path / "docs" / "page.md").write_text("again **264,192 bits**<!-- answer: m.bits -->\n")
    record = {"entries": {"m.bits": {"text": "264,192 bits"}, "unquoted": {"text": "1"}}}
    found = answers.problems(record, tmp_path)
    assert len(found) == 3
    assert "README.md: m.bits quotes '524,288 bits'" in found[0]
    assert "'nowhere' has no entry" in found[1] and "'unquoted' is quoted nowhere" in found[2]
    assert answers.rewrite(record, tmp_path) == ["README.md"]
    assert "**264,192 bits**<!-- answer: m.bits -->" in (tmp_path / "README.md").read_text()
    assert len(answers.problems(record, tmp_path)) == 2  # the marker and the entry remain


def test_a_run_time_quote_names_the_machine_and_the_date():
    e = next(e for e in answers.ENTRIES if e.key == "pyro_1fmol.wall_time")
    record = {"machine": {"cores": 2}, "date": "2026-11-29"}
    assert e.text(0.934, record) == "0.93 s on a 2-core machine, 2026-11-29"


#: Scenes rerun by the slow test: minutes at most on 2 cores.
RERUN = ("pyro_1fmol", "pyro_long_read")


def test_the_cheap_entries_rerun_to_the_same_numbers(tmp_path):
    """Each scene of :data:`RERUN`, run again at the seed its file states, gives every recorded
    figure exactly (run times aside: they are the machine's, not the model's)."""
    recorded = _recorded()["entries"]
    for name in RERUN:
        entries = [e for e in answers.ENTRIES if e.source == name and e.key in recorded
                   and e.fmt is not answers.wall]
        summary, _ = answers.run_source("run", name, tmp_path)
        for e in entries:
            got, want = answers.dig(summary, e.path), recorded[e.key]["value"]
            assert got == want or (isinstance(got, float) and math.isnan(got)
                                   and math.isnan(want)), e.key
            assert summary["seed"] == recorded[e.key]["seed"]


@pytest.mark.parametrize("page", ["README.md", "docs/index.md", "docs/getting-started.md",
                                  "docs/tutorials/pyro_1fmol.md"])
def test_the_headline_scenes_run_time_is_one_generated_figure(page):
    """README, the landing page, getting started and the tutorial once said "about a second",
    "a few seconds" and "≈ 0.07 s": each now quotes the one measured figure."""
    text = (ROOT / page).read_text(encoding="utf-8")
    assert "<!-- answer: pyro_1fmol.wall_time -->" in text
