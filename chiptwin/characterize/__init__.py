"""EMVA 1288 characterisation: the chip's datasheet from the twin, and a twin from a datasheet.

The chip on a camera test bench, as the standard (EMVA 1288 Release 4.0 Linear)
measures a sensor::

    protocol ──► bench ──────────────► series ─────────► evaluation ──► datasheet ──► outputs
    (exposures)  uniform light at the   photon transfer,   the standard's   figures ± σ,   JSON, md,
                 sensor plane → e⁻ →    spatial stacks,    formulas and     scenario        plots
                 ADC codes → CMS (DN)   dark vs T          fit ranges       values

* :mod:`~chiptwin.characterize.protocol`: what is measured (≥ 50 points, L ≥ 16, temperatures).
* :mod:`~chiptwin.characterize.bench`: the scenario's chip as configured (pixel, per-pixel ADC,
  CMS at the DSP's level), read under uniform light.
* :mod:`~chiptwin.characterize.measure`: the three series, each from its own random stream.
* :mod:`~chiptwin.characterize.estimators`: pair and stack statistics with standard errors.
* :mod:`~chiptwin.characterize.evaluate`: the standard's formulas.
* :mod:`~chiptwin.characterize.datasheet`: the figures, with the scenario's own values beside.
* :mod:`~chiptwin.characterize.outputs`, :mod:`~chiptwin.characterize.plots`: ``emva1288.json``,
  ``datasheet.md``, the standard's plots.
* :mod:`~chiptwin.config.datasheet`: a datasheet (the same JSON layout) → ``[chip.pixel]`` and
  ``[chip.adc]`` values (``from_datasheet = "FILE.json"``).

Measured data in (a real camera's EMVA 1288 data set, ``chiptwin characterize --measured DIR``)::

    descriptor ──► measured ─────────► evaluation ──► datasheet
    (the format)   pair/stack stats     (the same)     (the same)
                                                            │
    overlay ◄───────── replay ◄──────────── camera_twin ◄───┘
    measured vs twin   the twin through     scenario TOML,
    in σ               the set's protocol   values ± their errors

* :mod:`~chiptwin.characterize.descriptor`, :mod:`~chiptwin.characterize.descriptor_write`: the
  EMVA 1288 descriptor data set (``EMVA1288_Data.txt`` and PNG/TIFF images), read and written.
* :mod:`~chiptwin.characterize.measured`: a data set as a ``Measurement`` and its datasheet.
* :mod:`~chiptwin.characterize.camera_twin`: the camera's twin as a scenario, each value with
  its standard error; :mod:`~chiptwin.characterize.replay`: a scenario read through a data set's
  protocol; :mod:`~chiptwin.characterize.overlay`: the two laid over each other.
* :mod:`~chiptwin.characterize.export`: the twin's own protocol written as a data set.
"""

from __future__ import annotations

import json
import sys
import time
import types
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from chiptwin.characterize.bench import Progress
    from chiptwin.characterize.datasheet import Datasheet
    from chiptwin.characterize.protocol import Protocol
    from chiptwin.config import Scenario

__all__ = ["Characterization", "characterize"]


@dataclass
class Characterization:
    """A finished characterisation: the datasheet and the run's facts (``meta``)."""

    datasheet: Datasheet
    meta: dict[str, Any]

    def write(self, out_dir: str | Path) -> Path:
        """Write ``emva1288.json``, ``datasheet.md`` and the plots (atomically)."""
        from chiptwin.characterize.outputs import write_outputs

        return write_outputs(self.datasheet, self.meta, out_dir)

    def to_json(self) -> dict[str, Any]:
        """The ``emva1288.json`` document."""
        from chiptwin.characterize.outputs import to_json

        return to_json(self.datasheet, self.meta)


def characterize(s: Scenario | str | Path, protocol: Protocol | None = None,
                 progress: Progress | None = None, datasheet_in: str | Path | None = None,
                 keep_images: bool = False) -> Characterization:
    """Measure the scenario's chip with the EMVA 1288 protocol and evaluate its datasheet.

    Parameters
    ----------
    s : Scenario, a TOML file, or the name of a bundled scenario
        Its ``[chip]`` is measured; its seed seeds the bench's streams.
    protocol : Protocol, optional
        Default :class:`~chiptwin.characterize.protocol.Protocol()`.
    progress : callable, optional
        ``progress(images_done, images_total)``.
    datasheet_in : path, optional
        A datasheet the chip was configured from: its values are shown beside the measured ones.
    keep_images : bool
        Keep the images in ``datasheet.measurement.images`` (for cross-checks).
    """
    from chiptwin import __version__
    from chiptwin.characterize.datasheet import build_datasheet
    from chiptwin.characterize.measure import measure
    from chiptwin.characterize.protocol import Protocol
    from chiptwin.config import Scenario, load_scenario

    if not isinstance(s, Scenario):
        s = load_scenario(s)
    t0 = time.perf_counter()
    m = measure(s, protocol or Protocol(), progress, keep_images)
    d = build_datasheet(m, s)
    if datasheet_in is not None:
        params = json.loads(Path(datasheet_in).read_text(encoding="utf-8"))["parameters"]
        d.input_values = {k: v.get("value") for k, v in params.items() if isinstance(v, dict)}
    # the file's name, not its path: a datasheet travels, the folder it was made in does not
    meta = {"scenario": s.scenario.name, "source": Path(s.source).name, "seed": s.scenario.seed,
            "chiptwin_version": __version__,
            "wall_time_s": round(time.perf_counter() - t0, 6)}
    if datasheet_in is not None:
        meta["datasheet_in"] = Path(datasheet_in).name
    return Characterization(d, meta)


class _CallableModule(types.ModuleType):
    """``chiptwin.characterize`` is this package and, called, :func:`characterize` (the public
    ``chiptwin.characterize(...)``, whichever of the two the name holds when it is used)."""

    def __call__(self, *args: Any, **kwargs: Any) -> Characterization:
        return characterize(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule
