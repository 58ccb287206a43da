"""The suite's own rule for a missing tool (tests/conftest.py): skip with how to install it on a
developer's machine, fail under ``CI=true`` — CI installs every tool, so a skip there would hide
a test that proves nothing."""

from __future__ import annotations

import pytest

from tests.conftest import require_module


def test_a_missing_tool_fails_under_ci_and_skips_elsewhere(monkeypatch):
    monkeypatch.setenv("CI", "true")
    with pytest.raises(pytest.fail.Exception, match="CI=true and a test cannot run"):
        require_module("chiptwin_no_such_module", "raytrace")
    monkeypatch.setenv("CI", "")
    with pytest.raises(BaseException, match=r"pip install -e '\.\[raytrace\]'") as off_ci:
        require_module("chiptwin_no_such_module", "raytrace")
    assert type(off_ci.value).__name__ == "Skipped"  # pytest's skip outcome, not a failure
    assert require_module("numpy").__name__ == "numpy"
