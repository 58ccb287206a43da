"""``[optics.top]`` wired through the twin: the scene's coupling, the raytrace cache, the summary
and the report.

Kinds: unit (the cache key holds the top; the scenario path hands the top to both
levels), regression of the jssc2006_faceplate scene under an open top (summary and report).
"""

from __future__ import annotations

import contextlib
import io
import json

import numpy as np
import pytest

from chiptwin.cli import main
from chiptwin.config import load_scenario
from chiptwin.optics.layers import Layer, Stack
from chiptwin.optics.raytrace import raytrace
from chiptwin.optics.stack_psf import coupling_stack
from chiptwin.optics.top import Top
from chiptwin.twin import stages
from tests.conftest import NO_TOP

#: An open well 50 µm deep, over the scenes' own top (a flow cell's lid in the pyro scenes).
OPEN_50 = [*NO_TOP, 'optics.top.medium="air"', "optics.top.solution_depth_um=50.0"]


def test_raytrace_cache_key_holds_the_top(tmp_path):
    """A matrix traced under one top is not handed out for another (nor for none); the same
    top hits the cache."""
    grid = dict(n_rows=3, n_cols=3, pitch_um=20.0, diode_w_um=15.0, diode_h_um=12.0,
                site_x_um=[30.0], site_y_um=[30.0])
    stack = Stack((Layer("water", 1.33, 4.0),), silicon_n=1.33)

    def trace(top):
        return raytrace(stack, rng=np.random.default_rng(1), n_rays=5_000, cache=tmp_path,
                        top=top, **grid)

    first = [trace(t) for t in (None, Top("air", 5.0), Top("air", 6.0))]
    assert not any(r.cached for r in first)
    again = trace(Top("air", 5.0))
    assert again.cached and np.array_equal(again.counts, first[1].counts)
    assert first[0].escaped_top[0] > 0.45 > 0.25 > first[1].escaped_top[0]


def test_scene_hands_the_top_to_the_psf_level():
    """pyro_1fmol, isotropic, under an open top 50 µm above its sites: the scene's psf coupling
    is :func:`coupling_stack` with that top; the top adds light to every pixel."""
    s = load_scenario("pyro_1fmol", ['optics.emitter="isotropic"', *OPEN_50])
    c = stages.coupling(s)
    no_top = stages.coupling(load_scenario("pyro_1fmol", ['optics.emitter="isotropic"',
                                                          *NO_TOP]))
    grid = stages._grid(s, np.arange(s.chip.rows), np.arange(s.chip.cols),
                        stages.site_pixels(s))
    direct = coupling_stack(**grid, stack=stages.optics_stack(s), emitter="isotropic",
                            site_radius_um=s.sites.footprint_radius_um,
                            top=Top("air", solution_depth_um=50.0))
    assert np.array_equal(c, direct)
    assert np.all(c > no_top)


def test_jssc2006_faceplate_under_an_open_top_reports_it(tmp_path):
    """The reference chip on its faceplate with an open well 50 µm deep: 34.2 % of the light
    returns (0.342329, the Fresnel/TIR integral), the faceplate passes only its Fresnel share
    inside the acceptance cone, which lands on the neighbours (cross-talk from none, below
    −120 dB, to −20.6 dB at the psf level); the summary and the report say so, in lines of at
    most 100 columns."""
    out = tmp_path / "out"
    argv = ["run", "jssc2006_faceplate", "--out", str(out), "--set", "assay.n_flows=8",
            "--set", "run.duration_s=500.0"] + [a for s in OPEN_50 for a in ("--set", s)]
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed), contextlib.redirect_stderr(io.StringIO()):
        assert main(argv) == 0
    top = json.loads((out / "summary.json").read_text())["optics"]["top"]
    assert top["medium"] == "air" and top["solution_n"] == 1.33
    assert top["returned_share"] == pytest.approx(0.342329, abs=1e-6)
    assert top["tir_share"] == pytest.approx(0.32965, abs=1e-5)
    assert top["without"]["crosstalk_db"] is None
    assert top["with"]["crosstalk_db"] == pytest.approx(-20.6, abs=0.1)
    assert 0.0 < top["own_pixel_change_rel"] < 0.01
    report = (out / "report.md").read_text()
    assert "open well, 50 µm of solution under air" in report and "34.2% returns" in report
    lines = printed.getvalue().splitlines()
    assert any("top surface" in line for line in lines)
    assert all(len(line) <= 100 for line in lines if "top" in line), lines
