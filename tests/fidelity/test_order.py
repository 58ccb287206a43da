"""``auto`` tries a stage's levels cheapest first by the wall-time estimate, not in the ladder's
fixed order: under luciferase_label's top surface the ``psf`` coupling integrates each part of
the light over the sites' footprints, where ``raytrace`` reads the matrix it traced once, so
``raytrace`` (the reference, exact) is taken although ``psf`` fits the budget too."""

from __future__ import annotations

import re

import pytest

from chiptwin.config import cost, load_scenario
from chiptwin.fidelity import resolve
from chiptwin.fidelity.auto import Calibrations
from chiptwin.fidelity.ladder import reference_levels
from chiptwin.twin.levels import _by_estimated_time
from tests.conftest import SCENARIOS

#: optics left to auto; 10 s of light, not 32, for a quicker calibration of psf
OPTICS_AUTO = ['run.fidelity.optics="auto"', "run.error_budget.snr_rel=0.01", "run.duration_s=30.0"]


@pytest.fixture(autouse=True)
def _own_cache(tmp_path, monkeypatch):
    """Each test calibrates into its own database (and traces into its own raytrace cache)."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))


def _scene(*sets: str):
    return load_scenario(SCENARIOS / "luciferase_label.toml", [*OPTICS_AUTO, *sets])


def _tried(reason: str) -> list[tuple[str, float]]:
    """The levels and seconds of the reason's ``tried by estimated time: a 0.1 s, b 0.2 s``."""
    text = reason.split("tried by estimated time: ")[1]
    return [(m[1], float(m[2])) for m in re.finditer(r"(\w+) ([\d.e+-]+) s", text)]


def test_the_cheaper_level_by_the_estimate_is_taken_where_the_ladder_order_differs():
    s = _scene()
    ref = reference_levels(s)
    assert ref["optics"] == "raytrace"
    # the ladder's order puts psf first, and psf fits this budget: the old order took it
    psf = Calibrations(s, ref, None).estimate("optics", "psf", ref)
    assert psf.errors["snr_rel"] <= 0.01
    _, choice = resolve(s)
    reason = choice.reasons["optics"]
    assert choice.levels["optics"] == "raytrace", reason
    tried = _tried(reason)
    assert [level for level, _ in tried] == ["raytrace", "psf"]  # na2 has no top: not tried
    assert tried[0][1] < tried[1][1]
    assert "not psf" not in reason  # taken before psf was tried


def test_the_estimates_differ_by_the_psf_couplings_footprint_profiles():
    """Air returns one part of the light: psf's coupling makes 2 profiles over the footprint."""
    s = _scene()
    ref = reference_levels(s)
    timed = dict(_by_estimated_time(s, "optics", ref, {}))
    assert set(timed) == {"psf", "raytrace"}
    assert timed["psf"] - timed["raytrace"] == pytest.approx(2 * cost.FOOTPRINT_PROFILE_S)


def test_equal_estimates_keep_the_ladder_order():
    """Point sites: no footprint to integrate over, psf and raytrace are estimated alike, and
    psf (first in LEVELS) is tried first."""
    s = _scene("sites.footprint_radius_um=0")
    timed = _by_estimated_time(s, "optics", reference_levels(s), {})
    assert [level for level, _ in timed] == ["psf", "raytrace"]
    assert timed[0][1] == timed[1][1]
