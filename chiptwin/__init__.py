"""chiptwin — a digital twin of a CMOS bioluminescence detection chip.

The signal travels through these stages, in this order (:data:`STAGES`)::

    kinetics ──► optics ──► pixel ──► adc ──► memory ──► dsp ──► detection ──► report
    photons/s    photons/    e⁻        codes   frames     results  SNR, calls
    per site     pixel

* kinetics: light emitted per assay site (Salama et al. 2004, eqs. 2–19). Unit: photons/s.
* optics: the share of it reaching each pixel's photodiode (NA², PSF coupling). Unit: photons/pixel.
* pixel: photodiode and readout (QE, dark current, shot, kTC, read noise, full well). Unit: e⁻.
* adc: per-pixel ADC. Unit: codes (LSB).
* memory: on-chip frame memory of finite capacity. Unit: frames (bits).
* dsp: background subtraction, correlated multiple sampling, averaging, ... Unit: codes.
* detection: per-site SNR (power ratio, eq. 22, and amplitude ratio), decisions, base calls.

The packages, bottom to top (each imports only from those below it; ``docs/architecture.md``):
foundations (``constants``, ``_numba``, ``_checks``, ``limits``) → ``config`` (scenario, study and
datasheet files; the output folder) → the stages (``kinetics``, ``optics``, ``photons``,
``pixel``, ``chip``, ``dsp``, ``detection``) → ``twin`` (a run) → the tools (``fidelity``,
``report``, ``study``, ``characterize``) → ``cli``.

Start here::

    import chiptwin as ct
    result = ct.run("pyro_1fmol", seed=1)          # a bundled name, or a TOML file
    study = ct.run_study("adc_bits_pyro", workers=2)
    sheet = ct.characterize("pyro_1fmol")          # EMVA 1288 datasheet of the chip
    ds = ct.open_run("out/pyro_1fmol")             # a run's folder as a labelled xarray Dataset
    table = ct.open_study("out/adc_bits_pyro")     # a study's rows over its axes and replicates

or the ``chiptwin`` command. The names below are loaded on first use, so ``import chiptwin``
stays light and the stage packages never import the tools above them.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
import types
import warnings
from importlib.metadata import PackageNotFoundError, version
from typing import Any

STAGES: tuple[str, ...] = (
    "kinetics",
    "optics",
    "pixel",
    "adc",
    "memory",
    "dsp",
    "detection",
    "report",
)
"""The stages in signal order, written once."""

try:
    __version__ = version("chiptwin")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0.0.0+unknown"

#: The public API: name → the module that defines it (loaded on first use).
_API: dict[str, str] = {
    "run": "chiptwin.fidelity.auto",
    "run_study": "chiptwin.study.engine",
    "characterize": "chiptwin.characterize",
    "run_ladder": "chiptwin.fidelity.ladder",
    "load_scenario": "chiptwin.config.load",
    "load_study": "chiptwin.study.spec",
    "Scenario": "chiptwin.config.schema",
    "ScenarioError": "chiptwin.config.fields",
    "Result": "chiptwin.twin.runner",
    "open_run": "chiptwin.report.dataset",
    "open_study": "chiptwin.report.study_dataset",
}


def __getattr__(name: str) -> Any:
    if name in _API:
        return getattr(importlib.import_module(_API[name]), name)
    raise AttributeError(f"module 'chiptwin' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *_API])


#: Modules that moved when the package was layered: the old path still imports, with
#: a DeprecationWarning naming the new one. Nothing in chiptwin imports an old path.
MOVED: dict[str, str] = {
    "chiptwin.run": "chiptwin.twin.runner",
    "chiptwin.scene": "chiptwin.twin.scene",
    "chiptwin.stages": "chiptwin.twin.stages",
    "chiptwin.programs": "chiptwin.twin.programs",
    "chiptwin.shortcuts": "chiptwin.twin.shortcuts",
    "chiptwin.saturation": "chiptwin.twin.saturation",
    "chiptwin.results": "chiptwin.twin.results",
    "chiptwin.dose_response": "chiptwin.twin.dose_response",
    "chiptwin.ladder": "chiptwin.fidelity.ladder",
    "chiptwin.rtl": "chiptwin.twin.rtl",
    "chiptwin.dsp.rtl": "chiptwin.twin.rtl",
    "chiptwin.dsp.scenario_report": "chiptwin.report.dsp_report",
    "chiptwin.characterize.twin": "chiptwin.config.datasheet",
    "chiptwin.study.stats": "chiptwin.detection.stats",
}


class _RunModule(types.ModuleType):
    """The old module ``chiptwin.run``: its names, ``run`` the one that resolves ``auto``, and
    callable, so ``chiptwin.run(...)`` keeps working once the old path was imported."""

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        return self.run(*args, **kwargs)


class _MovedFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds the old paths of :data:`MOVED` and loads them as the new modules."""

    def find_spec(self, name: str, path: Any = None, target: Any = None) -> Any:
        return importlib.util.spec_from_loader(name, self) if name in MOVED else None

    def create_module(self, spec: Any) -> types.ModuleType:
        warnings.warn(f"{spec.name} moved to {MOVED[spec.name]}; import it from there",
                      DeprecationWarning, stacklevel=2)
        new = importlib.import_module(MOVED[spec.name])
        if spec.name != "chiptwin.run":
            return new
        old = _RunModule(spec.name, new.__doc__)
        old.__dict__.update({k: v for k, v in vars(new).items() if not k.startswith("__")})
        old.run = __getattr__("run")
        return old

    def exec_module(self, module: types.ModuleType) -> None:
        """Nothing to run: :meth:`create_module` returned the loaded module."""


if not any(isinstance(f, _MovedFinder) for f in sys.meta_path):
    sys.meta_path.append(_MovedFinder())

__all__ = ["MOVED", "STAGES", "__version__", *_API]
