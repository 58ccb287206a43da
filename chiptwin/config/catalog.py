"""The bundled scenarios and studies, by name: what ``chiptwin list`` shows and what a name on
the command line or in :func:`chiptwin.run` resolves to.

An installed package carries them as ``chiptwin.scenarios`` (``scenarios/`` mapped in
pyproject.toml); a source tree has them in ``scenarios/`` beside the package.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path


def bundled_scenarios() -> dict[str, Path]:
    """The scenarios shipped with the package, by name.

    An installed package carries them as ``chiptwin.scenarios`` (``scenarios/`` mapped in
    pyproject.toml); a source tree has them in ``scenarios/`` beside the package.
    """
    try:  # a namespace package: iterate its entries, str() of the folder is not a path
        files = [Path(str(f)) for f in resources.files("chiptwin.scenarios").iterdir()]
    except ModuleNotFoundError:
        files = list((Path(__file__).resolve().parents[2] / "scenarios").iterdir())
    return {f.stem: f for f in sorted(files) if f.suffix == ".toml"}


def bundled_studies() -> dict[str, Path]:
    """The studies shipped with the package (``scenarios/studies``), by name."""
    folder = bundled_scenarios_folder() / "studies"
    return {f.stem: f for f in sorted(folder.iterdir()) if f.suffix == ".toml"} if \
        folder.is_dir() else {}


def bundled_scenarios_folder() -> Path:
    """The folder of the bundled scenarios (installed, or the source tree's)."""
    try:
        return Path(str(next(iter(resources.files("chiptwin.scenarios").iterdir())))).parent
    except (ModuleNotFoundError, StopIteration):
        return Path(__file__).resolve().parents[2] / "scenarios"


def resolve_study(name: str) -> Path:
    """A path as given, or a bundled study's file (see :func:`resolve_scenario`)."""
    path = Path(name)
    if path.is_file() or path.suffix == ".toml":
        return path
    return bundled_studies().get(name, path)


def resolve_scenario(name: str) -> Path:
    """A path as given, or a bundled scenario's file.

    One rule: a name that is a file (or ends in ``.toml``) is that file; any other name is a
    bundled scenario's. A folder of the same name (``chiptwin run pyro_1fmol --out pyro_1fmol``
    makes one) does not hide the bundled scenario.
    """
    path = Path(name)
    if path.is_file() or path.suffix == ".toml":
        return path
    return bundled_scenarios().get(name, path)


__all__ = ["bundled_scenarios", "bundled_scenarios_folder", "bundled_studies", "resolve_scenario",
           "resolve_study"]
