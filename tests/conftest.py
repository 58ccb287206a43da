"""Shared fixtures: the repository's scenario folder and a small, fast scenario; the one rule for
a test whose tool is missing (skip off CI with how to install it, fail under CI=true)."""

from __future__ import annotations

import importlib
import os
from pathlib import Path
from types import ModuleType
from typing import NoReturn

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ROOT / "scenarios"

SMALL = """
[scenario]
name = "small"
seed = 7

[assay]
kind = "pyrosequencing"
template = "TCAGGTTCCA"
n_flows = 14
flow_period_s = 20.0
start_s = 4.0
k_a_per_s = 0.25
photons_per_incorporation = 0.01

[sites]
at_pixels = [[1, 1], [2, 4]]

[chip]
rows = 4
cols = 6

[chip.dsp]
n_dark_frames = 4
cms_samples = 2
average_frames = 4

[run]
duration_s = 284.0
"""


@pytest.fixture
def small_toml(tmp_path: Path) -> Path:
    """A 4 × 6 chip sequencing a 10-base template in 14 short flows: runs in well under a second."""
    path = tmp_path / "small.toml"
    path.write_text(SMALL)
    return path


#: ``--set`` keys that make a bundled scenario small: the same physics, fewer frames (and
#: pixels), so a test can run every bundled scenario in seconds.
REDUCED = {
    "pyro_1fmol": ["assay.n_flows=8", "run.duration_s=500.0"],
    "ccd_100fmol": ["assay.n_flows=8", "run.duration_s=496.0"],
    "pyro_array_256": ["assay.n_flows=8", "run.duration_s=500.0", "chip.rows=8", "chip.cols=8",
                       "sites.at_pixels=[[2, 2], [2, 6], [6, 2], [6, 6]]"],
    "pyro_paper_yield": ["assay.n_flows=8", "run.duration_s=500.0"],
    "pyro_paper_yield_fast": ["assay.n_flows=8", "assay.flow_period_s=4.0",
                              "run.duration_s=34.0"],
}


def in_ci() -> bool:
    """``CI=true`` (GitHub Actions, GitLab, most CI services set it)."""
    return os.environ.get("CI", "").strip().lower() in ("true", "1", "yes")


def unavailable(what: str) -> NoReturn:
    """A test's tool is missing (``what`` says which and how to install it): skip on a
    developer's machine, fail under ``CI=true``, where scripts/test.sh installs every tool — the
    suite's only skips besides test_kill's ``/proc`` (README, "Quick start")."""
    if not in_ci():
        pytest.skip(what)
    pytest.fail(f"CI=true and a test cannot run: {what}", pytrace=False)


def require_module(name: str, extra: str = "test") -> ModuleType:
    """``import name``, or :func:`unavailable` naming the extra that installs it."""
    try:
        return importlib.import_module(name)
    except ImportError:
        unavailable(f"{name} is not installed (pip install -e '.[{extra}]')")


#: Modules whose costly module- or session-scoped fixtures serve several tests: under
#: ``pytest -n auto --dist loadgroup`` (scripts/test.sh) each group runs on one worker, so each
#: fixture is computed once instead of once per worker that gets one of its tests. The same
#: holds for numba's compilation on a fresh checkout (no cache yet): two workers that meet one
#: kernel at once both compile it.
XDIST_GROUPS = {
    "tests/validation/test_paper_yield.py": "paper_yield",  # two whole runs (7 s and 2 s)
    "tests/validation/test_noise_monte_carlo.py": "noise_monte_carlo",  # 1.5 s of seeds
    # the session's `characterized` chips (tests/characterize/conftest.py)
    "tests/characterize/test_cli.py": "characterized",
    "tests/characterize/test_emva1288.py": "characterized",
    "tests/characterize/test_roundtrip.py": "characterized",
    "tests/characterize/test_twin.py": "characterized",
    # the session's `frame_memory_result` study (tests/study/conftest.py)
    "tests/study/test_bundled.py": "frame_memory_study",
    "tests/study/test_outputs.py": "frame_memory_study",
    # _random.fill on three sources (PCG64, SFC64, a Generator): 17-27 s of compilation cold,
    # the PCG64 version compiled by both workers when the module was split (0.7 s of tests warm)
    "tests/pixel/test_random.py": "random_fill",
}


@pytest.hookimpl(tryfirst=True)  # before xdist's own hook, which reads the marks into node ids
def pytest_collection_modifyitems(config, items) -> None:
    for item in items:
        group = XDIST_GROUPS.get(item.path.relative_to(ROOT).as_posix())
        if group:
            item.add_marker(pytest.mark.xdist_group(group))


@pytest.hookimpl(optionalhook=True)  # pytest-xdist's hook, on the controller
def pytest_xdist_node_collection_finished(node, ids) -> None:
    """Under ``--dist loadgroup`` xdist sends each group to one worker by the ``@group`` suffix
    its workers put on the node ids; with pytest 9.2 and pytest-xdist 3.8 the suffix is silently
    lost and every test goes anywhere (pytest-dev/pytest-xdist#1386). Stop rather than compute
    the groups' shared fixtures, and compile their kernels, on every worker unnoticed."""
    if node.config.getoption("dist", default="no") != "loadgroup":
        return
    lost = [i for i in ids if i.split("::")[0] in XDIST_GROUPS and "@" not in i]
    if lost:
        pytest.exit(f"--dist loadgroup groups nothing: {lost[0]} lost its group (pytest "
                    f"{pytest.__version__}, pytest-dev/pytest-xdist#1386): install the test "
                    "extra's pytest (<9.2) or run without --dist loadgroup",
                    returncode=pytest.ExitCode.USAGE_ERROR)
