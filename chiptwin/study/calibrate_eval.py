"""One evaluation of a calibration: a candidate's values → the twin's side of every measured value.

A worker gets an :class:`EvalTask` (picklable: the model of the fit and the candidate's values)
and returns the simulated values with their own standard errors (:func:`run_evaluations`, sent
through the study's executors like a budget study's rows). Every candidate is simulated with
**common random numbers**: the same seeds, derived from the study seed as a budget study's rows
are (:func:`chiptwin.study.rows.row_seed`, the chip's fixed pattern from
:func:`chiptwin.study.rows.chip_seed`, an EMVA replay's stream from
:func:`chiptwin.twin.stages.stage_rng`), so two candidates differ by their values, not by their
draws, and the optimiser sees a deterministic objective.

- **table, x a scenario key**: at each x, ``replicates`` runs; the value is the metric's mean,
  its standard error the runs' spread / √replicates;
- **table, x = time**: the sites' light at each time (the kinetics stage; nothing drawn, its
  standard error 0);
- **EMVA 1288**: the twin read through the data set's protocol
  (:func:`chiptwin.study.calibrate_emva.replay_stats`);
- **IEEE 1241 bench**: the transition noise of the same converters through the bench's DC
  sweep (:func:`chiptwin.study.calibrate_adc.adc_stats`).
"""

from __future__ import annotations

import time
import traceback
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from chiptwin.config import ScenarioError
from chiptwin.study.rows import RowTask, chip_seed, row_seed, run_row
from chiptwin.study.spec import point_id, point_scenario


@dataclass(frozen=True)
class Model:
    """What a worker needs to simulate any candidate of one fit.

    ``base_raw``, ``source``, ``scenario_path``: the study's base scenario (with ``set``), as
    :func:`chiptwin.study.spec.point_scenario` reads them."""

    kind: str  # "table", "series", "emva1288" or "adc1241"
    base_raw: dict[str, Any]
    source: str
    scenario_path: str
    keys: tuple[str, ...]
    seed: int
    fixed_pattern_seed: int
    x_key: str = ""
    x_values: tuple = ()
    metric: str = ""
    replicates: int = 1
    plan: Any = field(default=None, repr=False)
    max_pixels: int | None = None
    compared: Any = field(default=None, repr=False)


@dataclass(frozen=True)
class EvalTask:
    model: Model
    values: tuple


#: Seconds of an EMVA replay per pixel read (one pixel of one image through the chain, the CMS
#: and the pair statistics), for the wall-time estimate: measured 76 ms for set 001's 50 points ×
#: 4 images × 4,096 pixels in one process (2-core machine, 2026-11-29).
REPLAY_S_PER_PIXEL: float = 9.3e-8
#: Seconds of one light curve (the kinetics' rate at the table's times): ≈ 2 ms measured.
SERIES_S: float = 2e-3


def candidate_seconds(study: Any) -> float | None:
    """Estimated seconds of one candidate of an EMVA, ADC-bench or time-series target (None for
    a table of runs: their rows are costed as a budget study's,
    ``chiptwin.config.cost.row_seconds``)."""
    t = study.calibration.target
    if t.kind == "adc1241":
        from chiptwin.study import calibrate_adc

        return calibrate_adc.candidate_seconds(t.plan)
    if t.kind == "emva1288":
        temporal = t.measurement.temporal
        pixels = temporal.n_values if t.max_pixels is None else min(t.max_pixels,
                                                                    temporal.n_values)
        return REPLAY_S_PER_PIXEL * 4 * temporal.t_exp_s.size * pixels
    return SERIES_S if t.series else None


def model_of(study: Any) -> Model:
    """The fit's model from a calibrate :class:`~chiptwin.study.spec.Study`."""
    cal, t = study.calibration, study.calibration.target
    pinned = study.base_raw.get("chip", {}).get("fixed_pattern_seed", -1)
    common = dict(base_raw=study.base_raw, source=study.source,
                  scenario_path=study.scenario_path, keys=cal.keys, seed=study.seed,
                  fixed_pattern_seed=pinned if pinned >= 0 else chip_seed(study.seed))
    if t.kind == "emva1288":
        from chiptwin.study.calibrate_emva import comparison, replay_plan

        return Model("emva1288", **common, plan=replay_plan(t.measurement),
                     max_pixels=t.max_pixels, compared=comparison(t.measurement.temporal))
    if t.kind == "adc1241":
        return Model("adc1241", **common, plan=t.plan)
    if t.series:
        return Model("series", **common, x_values=t.x_values)
    return Model("table", **common, x_key=t.x, x_values=t.x_values, metric=t.y,
                 replicates=cal.replicates)


def run_evaluations(tasks: list[EvalTask]) -> list[dict[str, Any]]:
    """The executors' task function: each candidate of ``tasks`` evaluated, in order."""
    return [evaluate(t) for t in tasks]


def evaluate(task: EvalTask) -> dict[str, Any]:
    """One candidate: ``{"values", "status" (ok/invalid/error), "sim", "sim_se", "message",
    "wall_s"}``; an inconsistent scenario is ``invalid``, an exception ``error``."""
    t0 = time.perf_counter()
    m = task.model
    params = dict(zip(m.keys, task.values, strict=True))
    try:
        sim, se = simulate(m, params)
    except ScenarioError as exc:
        return _record(task, "invalid", None, None, str(exc), t0)
    except Exception as exc:  # recorded; the optimiser sees an infinite objective
        where = traceback.extract_tb(exc.__traceback__)[-1]
        message = f"{type(exc).__name__}: {exc} (at {where.filename}:{where.lineno})"
        return _record(task, "error", None, None, message, t0)
    if not (np.all(np.isfinite(sim)) and np.all(np.isfinite(se))):
        return _record(task, "error", None, None, "the simulation gave a value that is not "
                       "finite", t0)
    return _record(task, "ok", sim, se, "", t0)


def simulate(m: Model, params: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """The twin's side of every measured value at ``params`` (the fitted keys' values), with
    its standard errors; a twin-made target is this at known values and another seed."""
    return _SIMULATE[m.kind](m, params)


def _record(task: EvalTask, status: str, sim, se, message: str, t0: float) -> dict[str, Any]:
    return {"values": list(task.values), "status": status,
            "sim": None if sim is None else [float(v) for v in sim],
            "sim_se": None if se is None else [float(v) for v in se],
            "message": message, "wall_s": time.perf_counter() - t0}


def _table(m: Model, params: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """At each x, the metric's mean over ``replicates`` runs and its standard error."""
    values, se = [], []
    for x in m.x_values:
        point = {m.x_key: x}
        pid = point_id(point)
        runs = []
        for r in range(m.replicates):
            seed = row_seed(m.seed, pid, r)
            s = point_scenario(m, {**point, **params}, seed, m.fixed_pattern_seed)
            row = run_row(RowTask(pid, "point", r, seed, point, (m.metric,), s))
            if row["status"] != "ok":
                raise ScenarioError(m.source, f"{m.x_key} = {x}", params, row["message"]) \
                    if row["status"] == "invalid" else RuntimeError(row["message"])
            runs.append(row["metrics"][m.metric])
        a = np.asarray(runs, dtype=float)
        values.append(a.mean())
        se.append(a.std(ddof=1) / np.sqrt(a.size))
    return np.asarray(values), np.asarray(se)


def _series(m: Model, params: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """The sites' emitted light at each time (photons/s, mean over the sites)."""
    from chiptwin.fidelity import resolve
    from chiptwin.twin.stages import light_source

    s = point_scenario(m, params, row_seed(m.seed, point_id({}), 0), m.fixed_pattern_seed)
    s, _ = resolve(s)
    rate = light_source(s).rate(np.asarray(m.x_values, dtype=float)).mean(axis=0)
    return rate, np.zeros_like(rate)


def _emva(m: Model, params: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    from chiptwin.study.calibrate_emva import replay_stats
    from chiptwin.twin.stages import stage_rng

    seed = row_seed(m.seed, point_id({}), 0)
    s = point_scenario(m, params, seed, m.fixed_pattern_seed)
    return replay_stats(s, m.plan, stage_rng(seed, "calibrate.replay"), m.max_pixels, m.compared)


def _adc(m: Model, params: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    from chiptwin.study.calibrate_adc import adc_stats
    from chiptwin.twin.stages import stage_rng

    seed = row_seed(m.seed, point_id({}), 0)
    s = point_scenario(m, params, seed, m.fixed_pattern_seed)
    return adc_stats(s, m.plan, stage_rng(seed, "calibrate.adc1241"))


_SIMULATE = {"table": _table, "series": _series, "emva1288": _emva, "adc1241": _adc}
