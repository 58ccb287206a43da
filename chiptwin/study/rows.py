"""One row of a study: a point's scenario run with one replicate's seed, reduced to its metrics.

A row depends only on its task (the point's validated scenario and the row's seed), never on
which process runs it or in what order, so serial, pool and Dask executions give the same bits.
Each process keeps the last few prepared scenes (kinetics, optics, the chip's schedule and,
unless chips vary, its fixed pattern): replicates of a point share them and redo only the draws.
"""

from __future__ import annotations

import time
import traceback
import zlib
from collections import OrderedDict
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from chiptwin.config import Scenario, ScenarioError
from chiptwin.study.metrics import measure

#: Prepared scenes a process keeps (points in flight per process are few: rows of one point are
#: sent together, in one task of consecutive rows).
SCENE_CACHE_SIZE = 4
_CHIP_KEY = zlib.crc32(b"chip")


def row_seed(study_seed: int, point_id: str, replicate: int) -> int:
    """``SeedSequence(study_seed, spawn_key=(point_hash, replicate))`` as a scenario seed
    (63 bits): ``chiptwin run … --seed`` with it reproduces the row."""
    ss = np.random.SeedSequence(study_seed, spawn_key=(int(point_id, 16), replicate))
    return int(ss.generate_state(1, np.uint64)[0] >> np.uint64(1))


def chip_seed(study_seed: int) -> int:
    """The one chip of a study without ``vary_chip``: its PRNU/DSNU maps' seed."""
    ss = np.random.SeedSequence(study_seed, spawn_key=(_CHIP_KEY,))
    return int(ss.generate_state(1, np.uint64)[0] >> np.uint64(1))


@dataclass(frozen=True)
class RowTask:
    """Everything a worker needs for one row (picklable)."""

    point: str
    kind: str  # "point" or "reference"
    replicate: int
    seed: int
    params: dict[str, Any]
    metrics: tuple[str, ...]
    scenario: Scenario | None  # None: the point failed validation (``invalid``)
    invalid: str = ""


def row_record(task: RowTask, status: str, metrics: dict | None, message: str,
               wall_s: float) -> dict[str, Any]:
    """A row as the ``runs`` table holds it."""
    return {"point": task.point, "kind": task.kind, "replicate": task.replicate,
            "seed": task.seed, "params": task.params, "metrics": metrics, "status": status,
            "message": message, "wall_s": wall_s}


_SCENES: OrderedDict[str, Any] = OrderedDict()


def _scene(task: RowTask, s: Scenario):
    """The point's scene, its ``auto`` fidelity resolved (once per point) and the choice."""
    from chiptwin.fidelity import resolve
    from chiptwin.twin.runner import chip_sensor, prepare
    from chiptwin.twin.stages import flow_model

    # keyed by the point's whole scenario (its seed aside): a point hash names the axis values
    # only, and two studies run in one process (tests, a notebook) may share one
    key = repr(replace(task.scenario, scenario=replace(task.scenario.scenario, seed=0)))
    cached = _SCENES.get(key)
    if cached is None:
        resolved, choice = resolve(s)
        cached = (prepare(resolved), resolved, choice)
        _SCENES[key] = cached
        while len(_SCENES) > SCENE_CACHE_SIZE:
            _SCENES.popitem(last=False)
    _SCENES.move_to_end(key)
    scene, resolved, choice = cached
    if flow_model(s) is not None:  # every replicate another run: its chemistry's draws (and
        scene = prepare(replace(resolved, scenario=s.scenario))  # the DNA drawn from its seed)
    elif s.chip.fixed_pattern_seed < 0:  # every replicate another chip: redraw PRNU/DSNU
        scene = replace(scene, sensor=chip_sensor(s))
        if s.assay.kind == "pyrosequencing" and s.assay.dna_cv:  # ... and its sites' DNA
            scene = prepare(replace(resolved, scenario=s.scenario))
    return scene, replace(resolved, scenario=s.scenario), choice


def run_rows(tasks: list[RowTask]) -> list[dict[str, Any]]:
    """Run one executor task: a few rows, in order (rows of one point back to back share its
    prepared scene). Each row is :func:`run_row`'s, so batching changes no number."""
    return [run_row(t) for t in tasks]


def run_row(task: RowTask) -> dict[str, Any]:
    """Run one row; an inconsistent point is ``invalid``, an exception ``error`` (with its
    message), neither stops the study."""
    t0 = time.perf_counter()
    if task.scenario is None:
        return row_record(task, "invalid", None, task.invalid, 0.0)
    from chiptwin.twin.runner import run_prepared

    s = replace(task.scenario, scenario=replace(task.scenario.scenario, seed=task.seed))
    try:
        scene, s, choice = _scene(task, s)
        # no metric reads the trace frame by frame: the chip model skips each frame's steps
        result = run_prepared(s, scene, choice=choice, frame_steps=False)
        metrics = measure(result, task.metrics)
    except ScenarioError as exc:
        return row_record(task, "invalid", None, str(exc), time.perf_counter() - t0)
    except Exception as exc:  # recorded, shown in the report; the study goes on
        where = traceback.extract_tb(exc.__traceback__)[-1]
        message = f"{type(exc).__name__}: {exc} (at {where.filename}:{where.lineno})"
        return row_record(task, "error", None, message, time.perf_counter() - t0)
    return row_record(task, "ok", metrics, "", time.perf_counter() - t0)
