"""``run_study`` for ``kind = "calibrate"``: evaluate candidates through the executors, fit,
profile, summarise.

Order of work: (1) the scenario's own values are evaluated first (their wall time announces the
rest); (2) differential evolution, a generation at a time through the executor; (3) the polish
from its best member, alternated with the errors' scales until they settle (:func:`settle`);
(4) the Jacobian at the optimum, the profiles; if a profile finds a χ² below the optimum's, the
fit settles again from there and the profiles are redone (at most :data:`RESTARTS` times);
(5) the smoothness check (:func:`~chiptwin.study.calibrate_fit.smoothness`). Every candidate
evaluated is stored (:meth:`~chiptwin.study.store.Store.add_evaluations`, one transaction per
executor task) under the target's hash; the optimiser is deterministic, so the same command
replays it, takes every stored evaluation and simulates only what is missing.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from chiptwin.config import ScenarioError
from chiptwin.study.calibrate_data import Measured, block_scales, residuals
from chiptwin.study.calibrate_eval import EvalTask, model_of, run_evaluations
from chiptwin.study.calibrate_fit import (
    DE_ATOL_CHI2,
    SCALE_ROUNDS,
    FitResult,
    evolve,
    jacobian_at,
    polish,
    smoothness,
)
from chiptwin.study.calibrate_profile import Profiles, profiles
from chiptwin.study.execute import batches
from chiptwin.study.store import candidate_key

Progress = Callable[[int, int], None]
#: Restarts of the polish from a better point a profile found (a key whose effect sets in past
#: a threshold, as a full well below the brightest pixels, has no derivative at the optimum: the
#: polish cannot see the better point, a profile can).
RESTARTS: int = 2


def measured_of(cal: Any) -> Measured:
    """The measured vector of a calibration's target."""
    t = cal.target
    if t.kind == "emva1288":
        from chiptwin.study.calibrate_emva import emva_measured

        return emva_measured(t.measurement)
    if t.kind == "adc1241":
        from chiptwin.study.calibrate_adc import adc_measured

        return adc_measured(t)
    n = t.n_points
    weighted = t.se is not None
    return Measured(np.asarray(t.y_values, float),
                    np.asarray(t.se, float) if weighted else np.ones(n),
                    np.zeros(n, dtype=np.int64), (t.y,), np.zeros(n, dtype=bool),
                    np.asarray(t.x_values, float), f"{t.x} [{t.units[0]}]", weighted)


class Evaluator:
    """The calibration as the fit sees it: u → residuals, every candidate evaluated once.

    Candidates are keyed by the fitted keys' exact values (:func:`candidate_key`); those stored
    for this target are taken from the store, the rest sent through the executor in tasks of
    a few, each task's evaluations stored in one transaction as it returns."""

    def __init__(self, study: Any, store: Any, executor: Any,
                 progress: Progress | None = None) -> None:
        cal = study.calibration
        self.params = cal.parameters
        self.k = len(self.params)
        self.integer = np.array([p.integer for p in self.params])
        self.model = model_of(study)
        self.measured = measured_of(cal)
        self.n = self.measured.n
        self.target = cal.target.hash
        self.source = study.source
        self.store, self.executor, self.progress = store, executor, progress
        self.total = cal.max_evaluations
        self.cache = store.evaluations(self.target)
        self.resumed = 0
        self.computed = 0
        self.scales: NDArray[np.float64] | None = None
        self.log: list[dict[str, Any]] = []  # each candidate as first asked for in this run
        self._seen: set[str] = set()

    def values(self, u: NDArray[np.float64]) -> tuple:
        return tuple(p.value(x) for p, x in zip(self.params, u, strict=True))

    def residuals(self, us: list[NDArray[np.float64]], stage: str
                  ) -> list[NDArray[np.float64] | None]:
        values = [self.values(u) for u in us]
        keys = [candidate_key(v) for v in values]
        missing = list({k: v for k, v in zip(keys, values, strict=True)
                        if k not in self.cache}.items())
        if missing:
            self._run(missing)
        for key in keys:
            if key not in self._seen:
                self._seen.add(key)
                rec = self.cache[key]
                self.resumed += rec.get("_resumed", True)
                self.log.append({"stage": stage, "values": rec["values"],
                                 "objective": rec["objective"], "status": rec["status"],
                                 "wall_s": rec["wall_s"]})
        if self.progress:  # past the estimate, the total grows ahead of what is done
            self.total = max(self.total, len(self._seen) + len(self._seen) // 10 + 1)
            self.progress(len(self._seen), self.total)
        return [self.scaled(self.cache[k]) for k in keys]

    def scaled(self, rec: dict[str, Any]) -> NDArray[np.float64] | None:
        if rec["status"] != "ok":
            return None
        r, _ = residuals(self.measured, np.asarray(rec["sim"]), np.asarray(rec["sim_se"]),
                         self.scales)
        return r

    def _run(self, missing: list[tuple[str, tuple]]) -> None:
        tasks = [EvalTask(self.model, v) for _, v in missing]
        size = max(1, len(tasks) // (4 * max(self.executor.workers, 1)))
        for records in self.executor.run(batches(tasks, size), fn=run_evaluations):
            for rec in records:
                if rec["status"] == "ok":
                    r, _ = residuals(self.measured, np.asarray(rec["sim"]),
                                     np.asarray(rec["sim_se"]))
                    rec["residuals"], rec["objective"] = r.tolist(), float(r @ r)
                else:
                    rec["residuals"], rec["objective"] = None, None
            self.store.add_evaluations(self.target, records)
            for rec in records:
                self.cache[candidate_key(rec["values"])] = {**rec, "_resumed": False}
            self.computed += len(records)

    def neighbour(self, j: int, u_j: float, d: int) -> float | None:
        """u of the next integer of integer key j in direction d, None past its range."""
        p = self.params[j]
        x = p.value(u_j) + d
        return None if not p.lo <= x <= p.hi else float(np.clip(p.unit(x), 0.0, 1.0))

    def offset(self, u: NDArray[np.float64]) -> float:
        """The profiled nuisance offset at ``u`` (0 without one)."""
        rec = self.cache[candidate_key(self.values(u))]
        return residuals(self.measured, np.asarray(rec["sim"]), np.asarray(rec["sim_se"]),
                         self.scales)[1]

    def record(self, u: NDArray[np.float64]) -> dict[str, Any]:
        return self.cache[candidate_key(self.values(u))]


def settle(ev: Evaluator, u: NDArray[np.float64]) -> tuple[NDArray[np.float64], int]:
    """Polish from u, then alternate the errors' scales (each block's Birge ratio at the
    optimum, :func:`~chiptwin.study.calibrate_data.block_scales`) and the polish until the
    scales move by less than 1 % (at most :data:`SCALE_ROUNDS` rounds); returns u and the
    candidates asked for."""
    p = ev.k + ev.measured.nuisance
    u, _, asked = polish(ev, u, ~ev.integer, "polish")
    for _ in range(SCALE_ROUNDS):
        raw = np.asarray(ev.record(u)["residuals"])
        scales = block_scales(ev.measured, raw, p)
        if ev.scales is not None and np.allclose(scales, ev.scales, rtol=0.01):
            break
        ev.scales = scales
        u, _, more = polish(ev, u, ~ev.integer, "polish")
        asked += more
    return u, asked


def threshold(measured: Measured, confidence: float, dof: int) -> float:
    """The profile's rise: the χ²₁ quantile (measured errors), or F(1, dof) (the errors' scale
    estimated from the residuals: least squares)."""
    from scipy import stats

    if measured.weighted:
        return float(stats.chi2.ppf(confidence, 1))
    return float(stats.f.ppf(confidence, 1, max(dof, 1)))


def fit(ev: Evaluator, cal: Any, rng: np.random.Generator, x0: NDArray[np.float64]
        ) -> tuple[FitResult, Profiles]:
    """Evolution, polish and scales settled together (:func:`settle`), the Jacobian at the
    optimum, profiles (and one restart from a better point a profile found)."""
    atol = DE_ATOL_CHI2 if ev.measured.weighted else 0.0
    u, f_de, evolution = evolve(ev, rng, cal.popsize, cal.generations, cal.tol, x0, atol)
    evolution["chi2"] = f_de
    if not np.isfinite(f_de):  # every candidate inconsistent or failed: nothing to fit
        first = next((e for e in ev.cache.values() if e["status"] != "ok"), {"message": ""})
        raise ScenarioError(ev.source, "study.parameter", list(cal.keys),
                            "no candidate in the ranges gave a scenario that runs; the first "
                            f"refusal: {first['message']}")
    u, asked = settle(ev, u)
    p = ev.k + ev.measured.nuisance
    T = threshold(ev.measured, cal.confidence, ev.n - p)
    notes: list[str] = []
    for attempt in range(RESTARTS + 1):
        jac, more = jacobian_at(ev, u, "polish")
        r = ev.scaled(ev.record(u))
        result = FitResult(u, float(r @ r), r, jac, T, evolution=evolution,
                           polish={"evaluations": asked + more}, notes=notes)
        prof = profiles(ev, u, result.chi2, T, result.covariance(), jac, ev.neighbour)
        result.intervals = prof.intervals
        if prof.better is None or attempt == RESTARTS:
            result.smoothness = smoothness(ev, u, result.chi2, T)
            if prof.better is not None:
                notes.append(f"a profile found χ² {prof.better[0]:.6g} below the optimum's "
                             f"{result.chi2:.6g} after {RESTARTS} restart(s): the intervals are "
                             "relative to a local optimum")
            return result, prof
        notes.append(f"a profile found χ² {prof.better[0]:.6g}, below the optimum's "
                     f"{result.chi2:.6g}: the fit restarted there (polish and scales settled "
                     "again, profiles redone)")
        u, more = settle(ev, prof.better[1])
        asked += more
    raise AssertionError("unreachable")


def run_calibrate(study: Any, workers: int | None = None, scheduler: str | None = None,
                  db: Any = ":memory:", fresh: bool = False, progress: Progress | None = None,
                  announce: Callable[[float, int], None] | None = None, *,
                  in_flight: int | None = None, scheduler_file: str | None = None,
                  worker_timeout_s: float | None = None
                  ) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """Run a calibrate study (:func:`chiptwin.study.engine.run_study`'s arguments); returns
    the evaluations in the order the fit asked for them and the summary (``study.json``)."""
    from chiptwin.study.calibrate_summary import summarise
    from chiptwin.study.execute import WORKER_TIMEOUT_S, make_executor
    from chiptwin.study.store import Store
    from chiptwin.twin.stages import stage_rng

    t0 = time.perf_counter()
    cal = study.calibration
    executor = make_executor(workers, scheduler, in_flight, scheduler_file,
                             worker_timeout_s or WORKER_TIMEOUT_S)
    try:
        store = Store(db, study, fresh=fresh)
        try:
            ev = Evaluator(study, store, executor, progress)
            x0 = np.clip([p.unit(p.reference) for p in cal.parameters], 0.0, 1.0)
            t1 = time.perf_counter()
            ev.residuals([x0], "reference")  # the scenario's own values
            if announce:
                per = time.perf_counter() - t1 if ev.computed else _mean_wall(ev)
                announce(per * cal.max_evaluations / max(executor.workers, 1),
                         cal.max_evaluations)
            result, prof = fit(ev, cal, stage_rng(study.seed, "calibrate.evolution"), x0)
        finally:
            store.close()
    except BaseException:  # Ctrl-C, SIGTERM, an error: stored evaluations stay, workers go now
        executor.abort()
        raise
    executor.close()
    summary = summarise(study, ev, result, prof)
    summary.update(wall_time_s=round(time.perf_counter() - t0, 3),
                   executor={"kind": executor.name, "workers": executor.workers})
    return ev.log, summary


def _mean_wall(ev: Evaluator) -> float:
    walls = [r["wall_s"] for r in ev.cache.values()]
    return float(np.mean(walls)) if walls else 0.0


def table_rows(log: list[dict[str, Any]], keys: tuple[str, ...]) -> list[list[Any]]:
    """The evaluations as ``results.csv`` rows: n, stage, status, objective, wall, values."""
    return [[i, e["stage"], e["status"], "" if e["objective"] is None else e["objective"],
             f"{e['wall_s']:.4f}", *e["values"]] for i, e in enumerate(log, 1)]


__all__ = ["Evaluator", "fit", "run_calibrate", "table_rows"]
