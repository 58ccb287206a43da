"""``run_study`` for ``kind = "optimize"``: a multi-objective design search with Optuna.

Why Optuna (the optional extra ``chiptwin[optimize]``): it is a well-kept, widely used library
(Akiba et al., "Optuna: a next-generation hyperparameter optimization framework", KDD 2019)
whose ask/tell interface lets the study's own executors (the process pool or Dask) evaluate a
batch of points in parallel; its RDB storage keeps every trial in SQLite, here in the study's
own ``results.sqlite`` beside the rows, so an interrupted study goes on where it stopped; it
handles constraints natively (a trial's constraint values, feasible when all are ≤ 0); and it
ships NSGA-II (Deb et al. 2002) for several objectives and TPE (Bergstra et al., "Algorithms
for hyper-parameter optimization", NeurIPS 2011) for one, both seeded, so a study is
reproducible.

Order of work: (1) every trial asked for but never told (an interrupted batch) is evaluated
first; (2) batches of ``batch`` points are asked for, each point's ``replicates`` rows run
through the executor (rows already in the store are taken, never recomputed), each point's
metrics estimated with their intervals, the batch told in trial order (so the same seed gives
the same trials however many workers ran them); (3) after each batch the stopping rule is
checked (:func:`chiptwin.study.optimize_front.stalled`); (4) the summary is rebuilt from the
stored trials and rows, so a resumed study reports exactly what an uninterrupted one would.
"""

from __future__ import annotations

import time
import zlib
from collections.abc import Callable
from typing import Any

import numpy as np

from chiptwin.config import ScenarioError
from chiptwin.detection.stats import Estimate, mean_estimate, rate_estimate
from chiptwin.study.execute import WORKER_TIMEOUT_S, batches, make_executor
from chiptwin.study.metrics import CATALOGUE
from chiptwin.study.optimize_front import convergence, minimised, reference_point, stalled
from chiptwin.study.rows import RowTask, chip_seed, row_seed
from chiptwin.study.spec import point_id, point_scenario
from chiptwin.study.store import Store

Progress = Callable[[int, int], None]
EXTRA_HINT = 'needs the optional extra: pip install "chiptwin[optimize]" (Optuna)'


def optuna_module(source: str = "chiptwin"):
    """Optuna, or a refusal (exit code 2) naming the extra to install."""
    try:
        import optuna
    except ImportError:
        raise ScenarioError(source, "study.kind", "optimize", EXTRA_HINT) from None
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    return optuna


def sampler_seed(study_seed: int, trials: int) -> int:
    """The sampler's seed for the batch that starts after ``trials`` trials (32 bits, as the
    NumPy generator Optuna keeps takes): a stream of the study seed per batch, so a study
    resumed at a batch's start asks for exactly the points the uninterrupted one did."""
    ss = np.random.SeedSequence(study_seed, spawn_key=(zlib.crc32(b"optimize.sampler"), trials))
    return int(ss.generate_state(1, np.uint32)[0])


def make_sampler(optuna: Any, opt: Any, seed: int) -> Any:
    """NSGA-II for several objectives (its population the batch), TPE for one; constraints are
    set on each trial (:meth:`optuna.trial.Trial.set_constraint`, Optuna ≥ 5), or read back by a
    ``constraints_func`` on older versions."""
    legacy = None if hasattr(optuna.trial.Trial, "set_constraint") else _stored_constraints
    if len(opt.objectives) > 1:
        return optuna.samplers.NSGAIISampler(population_size=opt.batch, seed=seed,
                                             constraints_func=legacy)
    return optuna.samplers.TPESampler(seed=seed, constant_liar=True, constraints_func=legacy,
                                      multivariate=True, n_startup_trials=startup(opt))


def startup(opt: Any) -> int:
    """TPE's random points before it models: a batch, at least 4 and at most Optuna's default
    10, and no more than a quarter of the budget (a small budget is spent mostly modelling)."""
    return max(4, min(10, opt.batch, opt.evaluations // 4))


def _stored_constraints(trial: Any) -> list[float]:
    return trial.user_attrs["constraints"]


def estimates(rows: list[dict], names: tuple[str, ...], confidence: float
              ) -> dict[str, Estimate]:
    """Every metric of a point from its ``ok`` rows (rates pooled with Korn–Graubard's
    Clopper–Pearson, means with Student t: :mod:`chiptwin.detection.stats`)."""
    ok = [r["metrics"] for r in rows if r["status"] == "ok"]
    if not ok:
        return {}
    out = {}
    for name in names:
        if CATALOGUE[name].kind == "rate":
            k, n = np.array([m[name] for m in ok]).T
            out[name] = rate_estimate(k, n, confidence)
        else:
            out[name] = mean_estimate(np.array([m[name] for m in ok], dtype=float), confidence)
    return out


def judged(c: Any, e: Estimate) -> float:
    """The constraint's value for Optuna: ≤ 0 when met, by the one-sided bound at the study's
    confidence (``judged = "bound"``) or the estimate."""
    if c.judged == "estimate":
        x = e.value
    else:
        x = e.upper if c.op == "<=" else e.lower
    v = x - c.bound if c.op == "<=" else c.bound - x
    return float(v) if np.isfinite(v) else float(np.inf)


def unusable(est: dict[str, Estimate], objectives: tuple) -> str:
    """Why a point's objectives cannot be told to Optuna ("" when they can): no run gave
    them, or an estimate is not finite (``energy_per_base_nj`` of a run that reads no base)."""
    for o in objectives:
        if o.metric not in est:
            return f"{o.metric}: no run of the point finished (see its rows' messages)"
        if not np.isfinite(est[o.metric].value):
            return f"{o.metric} = {est[o.metric].value}: not a finite objective"
    return ""


def fixed_pattern_seed(study: Any) -> int | None:
    """The one chip of a study without ``vary_chip`` (as a budget study's: the scenario's
    pinned seed, else one from the study seed); None when every replicate is another chip."""
    if study.vary_chip:
        return None
    pinned = study.base_raw.get("chip", {}).get("fixed_pattern_seed", -1)
    return pinned if pinned >= 0 else chip_seed(study.seed)


def point_tasks(study: Any, params: dict[str, Any], fps: int | None,
                stored: dict | set = frozenset()) -> list[RowTask]:
    """A point's rows not in ``stored`` (keys ``(point, replicate)``), each seeded as a budget
    study's row (:func:`~chiptwin.study.rows.row_seed`); an inconsistent point's rows are
    ``invalid`` with the refusal."""
    pid = point_id(params)
    wanted = [r for r in range(study.replicates) if (pid, r) not in stored]
    if not wanted:
        return []
    try:
        scenario, invalid = point_scenario(study, params, study.seed, fps), ""
    except ScenarioError as exc:
        scenario, invalid = None, str(exc)
    return [RowTask(pid, "point", r, row_seed(study.seed, pid, r), params,
                    study.optimization.metrics, scenario, invalid) for r in wanted]


class Search:
    """The design search: Optuna asks, the executor evaluates, the store keeps the rows."""

    def __init__(self, study: Any, store: Store, executor: Any, optuna: Any, storage: Any,
                 progress: Progress | None = None) -> None:
        self.study, self.opt = study, study.optimization
        self.store, self.executor, self.progress = store, executor, progress
        self.optuna = optuna
        self.rows = {(r["point"], r["replicate"]): r for r in store.rows()}
        self.resumed = len(self.rows)
        self.computed = 0
        self.fps = fixed_pattern_seed(study)
        self.ostudy = optuna.create_study(
            storage=storage, study_name=f"{study.name}-{study.hash}", load_if_exists=True,
            directions=[o.direction for o in self.opt.objectives],
            sampler=make_sampler(optuna, self.opt, sampler_seed(study.seed, 0)))
        self.stopped_by = "budget"

    def run(self) -> None:
        states = self.optuna.trial.TrialState
        pending = [self.optuna.trial.Trial(self.ostudy, t._trial_id)
                   for t in self.ostudy.get_trials(deepcopy=False, states=(states.RUNNING,))]
        if pending:  # asked for before an interruption: evaluated now, in trial order
            self._evaluate(pending)
        while True:
            done = len(self.ostudy.get_trials(deepcopy=False,
                                              states=(states.COMPLETE, states.FAIL)))
            if self.progress:
                r = self.study.replicates  # in rows, as the announcement counts
                self.progress(done * r, self.opt.evaluations * r)
            if done >= self.opt.evaluations:
                return
            if self.opt.stop.gain and stalled(self.curve(), self.opt.stop.gain,
                                              self.opt.stop.last):
                self.stopped_by = "hypervolume"
                return
            k = min(self.opt.batch, self.opt.evaluations - done)
            self.ostudy.sampler = make_sampler(self.optuna, self.opt,
                                               sampler_seed(self.study.seed, done))
            self._evaluate([self.ostudy.ask() for _ in range(k)])

    def suggest(self, trial: Any) -> dict[str, Any]:
        """The trial's values of the varied keys (each asked for of the trial, so Optuna records
        its distribution)."""
        out = {}
        for p in self.opt.parameters:
            if p.choices:
                out[p.key] = trial.suggest_categorical(p.key, list(p.choices))
            elif p.integer:
                out[p.key] = trial.suggest_int(p.key, int(p.lo), int(p.hi), log=p.log)
            else:
                out[p.key] = trial.suggest_float(p.key, p.lo, p.hi, log=p.log)
        return out

    def _evaluate(self, trials: list[Any]) -> None:
        params = [self.suggest(t) for t in trials]
        self.ensure(params)
        for trial, ps in zip(trials, params, strict=True):  # told in trial order: reproducible
            self._tell(trial, ps)

    def tasks(self, params: dict[str, Any]) -> list[RowTask]:
        return point_tasks(self.study, params, self.fps, self.rows)

    def ensure(self, params: list[dict[str, Any]]) -> None:
        """Run every row of these points not stored yet, each task's rows stored at once.

        A task is one point's rows, so one process prepares a point's scene (the 128-site
        chip's optics take seconds): benchmarks/bench_optimize.py measured the search at 1.60×
        the same rows run alone with tasks cut by row count (a point's replicates split over
        both processes, each preparing it), 1.16× with a point per task (20 evaluations of
        optimize_assay_size, 2 workers, 2026-11-29). With fewer points than workers a point's
        rows are split so that every worker has some."""
        points = {}
        for p in params:
            points.setdefault(point_id(p), self.tasks(p))
        work = [t for t in points.values() if t]
        if not work:
            return
        pieces = -(-self.executor.workers // len(work))  # ceil: tasks per point
        tasks = [chunk for t in work for chunk in batches(t, -(-len(t) // pieces))]
        for rows in self.executor.run(iter(tasks)):
            self.store.add(rows)
            for row in rows:
                self.rows[(row["point"], row["replicate"])] = row
            self.computed += len(rows)

    def point_rows(self, pid: str) -> list[dict]:
        return [self.rows[(pid, r)] for r in range(self.study.replicates)
                if (pid, r) in self.rows]

    def _tell(self, trial: Any, params: dict[str, Any]) -> None:
        pid = point_id(params)
        trial.set_user_attr("point", pid)
        est = estimates(self.point_rows(pid), self.opt.metrics, self.study.confidence)
        states = self.optuna.trial.TrialState
        problem = unusable(est, self.opt.objectives)
        if problem:  # an inconsistent scene, every run failed, or an infinite objective
            trial.set_user_attr("failed", problem)
            self.ostudy.tell(trial, state=states.FAIL)
            return
        cons = [judged(c, est[c.metric]) for c in self.opt.constraints]
        if hasattr(trial, "set_constraint"):
            for c, v in zip(self.opt.constraints, cons, strict=True):
                trial.set_constraint(str(c), v)
        else:
            trial.set_user_attr("constraints", cons)
        self.ostudy.tell(trial, [est[o.metric].value for o in self.opt.objectives])

    def records(self) -> list[dict[str, Any]]:
        """Every finished trial in order: its keys, state, point, metrics and feasibility."""
        states = self.optuna.trial.TrialState
        out = []
        for t in self.ostudy.get_trials(states=(states.COMPLETE, states.FAIL)):
            pid = point_id(t.params)
            rows = self.point_rows(pid)
            est = estimates(rows, self.opt.metrics, self.study.confidence)
            ok = t.state == states.COMPLETE
            cons = [judged(c, est[c.metric]) for c in self.opt.constraints] if ok else []
            out.append({"trial": t.number, "id": pid,
                        "params": {p.key: t.params[p.key] for p in self.opt.parameters},
                        "state": "complete" if ok else "failed",
                        "feasible": ok and all(v <= 0 for v in cons),
                        "constraints": dict(zip(map(str, self.opt.constraints), cons,
                                                strict=False)),
                        "metrics": est, "message": next((r["message"] for r in rows
                                                         if r["message"]),
                                                        t.user_attrs.get("failed", ""))})
        return out

    def curve(self, ref: np.ndarray | None = None) -> list[float]:
        """The feasible front's hypervolume after each finished trial (a failed or infeasible
        one adds nothing)."""
        recs = self.records()
        F = minimised(recs, self.opt.objectives)
        feasible = np.array([r["feasible"] for r in recs], dtype=bool)
        if ref is None:
            ref = reference_point(F[feasible], [_ref(o) for o in self.opt.objectives])
        return convergence(F, feasible, ref)


def _ref(o: Any) -> float | None:
    return None if o.reference is None else o.sign * o.reference


def run_optimize(study: Any, workers: int | None = None, scheduler: str | None = None,
                 db: Any = ":memory:", fresh: bool = False, progress: Progress | None = None,
                 announce: Callable[[float, int], None] | None = None, *,
                 in_flight: int | None = None, scheduler_file: str | None = None,
                 worker_timeout_s: float | None = None
                 ) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """Run an optimize study (:func:`chiptwin.study.engine.run_study`'s arguments); returns
    the evaluations in trial order and the summary (``study.json``)."""
    from chiptwin.study.optimize_summary import summarise

    optuna = optuna_module(study.source)
    t0 = time.perf_counter()
    executor = make_executor(workers, scheduler, in_flight, scheduler_file,
                             worker_timeout_s or WORKER_TIMEOUT_S)
    try:
        store = Store(db, study, fresh=fresh)
        try:
            storage = (optuna.storages.InMemoryStorage() if str(db) == ":memory:" else
                       optuna.storages.RDBStorage(f"sqlite:///{db}"))
            search = Search(study, store, executor, optuna, storage, progress)
            if announce:
                announce(*_estimate(study, executor.workers, len(search.rows)))
            search.run()
            records = search.records()
        finally:
            store.close()
    except BaseException:  # Ctrl-C, SIGTERM, an error: stored rows and trials stay
        executor.abort()
        raise
    executor.close()
    summary = summarise(study, search, records)
    summary.update(wall_time_s=round(time.perf_counter() - t0, 3),
                   executor={"kind": executor.name, "workers": executor.workers})
    return records, summary


def describe(study: Any, workers: int) -> str:
    """What ``chiptwin validate`` says of an optimize study: its space, budget and the
    estimated wall time at most."""
    from chiptwin.config.cost import format_seconds

    opt = study.optimization
    seconds, rows = _estimate(study, workers, 0)
    return (f"{study.name}: ok ({len(opt.parameters)} keys, {len(opt.objectives)} "
            f"objective(s), {len(opt.constraints)} constraint(s); {opt.sampler}, at most "
            f"{opt.evaluations} evaluations × {study.replicates} replicates = {rows} rows, "
            f"≈ {format_seconds(seconds)} on {workers} process(es); stops at {opt.stop})")


def _estimate(study: Any, workers: int, stored: int) -> tuple[float, int]:
    """Seconds and rows left at most: the budget's rows at the base scenario's row cost."""
    import json

    from chiptwin.config.cost import row_seconds
    from chiptwin.config.load import scenario_from_dict

    base = scenario_from_dict(json.loads(json.dumps(study.base_raw)), study.scenario_path)
    rows = max(study.optimization.evaluations * study.replicates - stored, 0)
    return row_seconds(base, study.replicates) * rows / max(workers, 1), rows


__all__ = ["Search", "describe", "estimates", "point_tasks", "run_optimize"]
