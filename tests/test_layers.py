"""The house: every package imports only from the layers below it, with no import
circle, read from the code's own imports (``scripts/layers.py``, the map ``docs/architecture.md``
draws); and the public API works from Python as on the command line."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("layers", ROOT / "scripts" / "layers.py")
layers = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(layers)


def test_no_arrow_runs_up_or_sideways():
    assert layers.violations() == []


def test_no_import_circle():
    assert layers.circles() == []


def test_the_checker_sees_an_arrow_up_and_a_circle():
    g = {"chiptwin.config.load": {"chiptwin.twin.runner"},
         "chiptwin.twin.runner": {"chiptwin.twin.scene"},
         "chiptwin.twin.scene": {"chiptwin.twin.runner"}}
    assert layers.violations(g) == [
        "chiptwin.config.load -> chiptwin.twin.runner: files may not import twin"]
    assert layers.circles(g) == [["chiptwin.twin.runner", "chiptwin.twin.scene"]]


def test_the_dsp_may_not_import_the_rtl_that_verifies_it():
    """rtl_ref imports chiptwin.dsp, so it is a room above the stage kernels: the DSP importing
    it back (chiptwin/dsp/rtl.py did, before it moved to chiptwin.twin.rtl) is an arrow up."""
    g = layers.graph()
    assert "chiptwin.dsp.fixed" in g["rtl_ref.block"]
    assert "rtl_ref.pipeline" in g["chiptwin.twin.rtl"]
    bad = {"chiptwin.dsp.program_pipeline": {"rtl_ref.routines"}}
    assert layers.violations(bad) == ["chiptwin.dsp.program_pipeline -> rtl_ref.routines: "
                                      "stage kernels may not import stages over stages"]


def test_every_room_is_on_a_layer_and_few_modules_sit_flat():
    rooms = {layers.room_of(m) for m in layers.modules()} - {None}
    for room in rooms:
        layers.layer_of(room)  # raises for a room on no layer
    flat = sorted(p.name for p in (ROOT / "chiptwin").glob("*.py") if p.name != "__init__.py")
    assert len(flat) <= 6, flat


def test_stage_packages_import_nothing_of_the_files_or_above():
    """Importing a stage package loads neither ``config`` nor the twin (run in a fresh process:
    this one has imported everything)."""
    code = ("import sys, chiptwin.kinetics, chiptwin.optics, chiptwin.pixel, chiptwin.dsp, "
            "chiptwin.photons, chiptwin.chip, chiptwin.detection\n"
            "print(sorted(m for m in sys.modules if m.startswith(('chiptwin.config', "
            "'chiptwin.twin', 'chiptwin.fidelity', 'chiptwin.study'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=ROOT)
    assert out.stdout.strip() == "[]"


def test_public_api_takes_bundled_names():
    import chiptwin as ct

    r = ct.run("pyro_1fmol", overrides=["assay.n_flows=8", "run.duration_s=500.0"], seed=1)
    assert r.summary["seed"] == 1 and r.summary["sites"]
    assert ct.load_scenario("pyro_1fmol").scenario.name == "pyro_1fmol"
    assert callable(ct.run_study) and callable(ct.characterize)


@pytest.mark.parametrize(("old", "new", "name"), [
    ("chiptwin.stages", "chiptwin.twin.stages", "coupling"),
    ("chiptwin.ladder", "chiptwin.fidelity.ladder", "run_ladder"),
    ("chiptwin.study.stats", "chiptwin.detection.stats", "mean_estimate"),
    ("chiptwin.dsp.rtl", "chiptwin.twin.rtl", "RtlPipeline"),
])
def test_moved_modules_still_import_with_a_warning(old, new, name):
    sys.modules.pop(old, None)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        mod = importlib.import_module(old)
    assert getattr(mod, name) is getattr(importlib.import_module(new), name)
    assert any(new in str(w.message) for w in caught)


def test_old_run_module_path_and_the_public_run_coexist():
    import chiptwin as ct

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        from chiptwin.run import run
    from chiptwin.fidelity import run as public_run

    assert run is public_run
    assert callable(ct.run)  # the old module, once imported, is callable as the function
