"""The gallery has an entry for every bundled scenario and study: a scene or study added without
one leaves the page stale (it lacked pyro_long_read and three studies). Reads files only."""

from __future__ import annotations

import re
from pathlib import Path

from chiptwin.config.catalog import bundled_scenarios, bundled_studies

GALLERY = Path(__file__).resolve().parents[2] / "docs" / "gallery.md"


def entries(text: str) -> set[str]:
    """Names with a gallery heading: ``### `name`...`` (two names may share one heading)."""
    return {name for heading in re.findall(r"^### (.+)$", text, flags=re.M)
            for name in re.findall(r"`(\w+)`", heading)}


def test_entries_parser():
    assert entries("### `a`: x\n### `b` and `c`: y\ntext `d`\n") == {"a", "b", "c"}


def test_every_bundled_scenario_and_study_has_an_entry():
    names = set(bundled_scenarios()) | set(bundled_studies())
    assert {"pyro_1fmol", "read_length_pyro"} <= names
    missing = sorted(names - entries(GALLERY.read_text(encoding="utf-8")))
    assert not missing, f"docs/gallery.md has no entry for {missing}"
