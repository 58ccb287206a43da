"""What the command line's commands share: the scenario and study paths they accept, the
context of their long work, and how they show a path."""

from __future__ import annotations

import contextlib
import sys
from pathlib import Path

from chiptwin._numba import announce_compiles
from chiptwin.cli.progress import Progress as _Progress
from chiptwin.config import ScenarioError
from chiptwin.config.catalog import (
    bundled_scenarios,
    bundled_studies,
    resolve_scenario,
    resolve_study,
)


def _working(progress: _Progress | None):
    """The context of a command's long work, which reports ``progress``: the first kernel numba
    compiles in it is announced (:func:`chiptwin._numba.announce_compiles`), so a first run's
    pause says what it is. Only around the work: a refused input keeps its one line."""
    return contextlib.nullcontext() if progress is None else announce_compiles(_say_compiling)


def _say_compiling() -> None:
    """On a terminal the progress bar's line is cleared first (it is redrawn)."""
    clear = "\r\033[K" if sys.stderr.isatty() else ""
    print(f"{clear}  compiling numba kernels: their first use on this machine (10–30 s); "
          "cached for later runs", file=sys.stderr, flush=True)


def _scenario_path(name: str, studies_too: bool = False) -> Path:
    """A scenario file as given, or a bundled scenario's; an unknown name is refused with the
    closest bundled names (before the loader's "not a readable file")."""
    path = resolve_scenario(name)
    if not path.exists():
        from chiptwin.cli.text import unknown_name

        known = [*bundled_scenarios(), *(bundled_studies() if studies_too else ())]
        raise _refusal(unknown_name(name, "scenario or study" if studies_too else "scenario",
                                    known))
    return path


def _study_path(name: str) -> Path:
    """A study file as given, or a bundled study's, as :func:`_scenario_path`."""
    path = resolve_study(name)
    if not path.exists():
        from chiptwin.cli.text import unknown_name

        raise _refusal(unknown_name(name, "study", bundled_studies()))
    return path


def _shown(path: Path) -> str:
    """An output folder as the user would type it: relative when it is under this folder."""
    try:
        return str(Path(path).resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path)


def _refusal(message: str) -> ScenarioError:
    """A refusal of the command line itself (no file, no key to name): printed as it is."""
    exc = ScenarioError("chiptwin", "(command line)", None, message)
    exc.args = (message,)
    return exc


def _check_json_path(json_path: str) -> None:
    target = Path(json_path)
    if target.is_dir() or not target.parent.is_dir():
        raise ScenarioError("chiptwin", "--json", json_path,
                            "must be a file path in an existing folder")
