"""``run_study``: validate every point, run the rows a search needs, store them, summarise.

Order of work: (1) every point's scenario is validated before the first run (a typo costs a
second; an inconsistent combination becomes an ``invalid`` point, shown in the report); (2) the
reference points run first (their rows define the ideal of ``snr_loss_db``); (3) the grid runs
every point × replicate (with ``stop_early``, in looks of ``batch`` replicates, each point until
it is decided), or the bisection runs points one at a time, adding ``batch`` replicates
until every requirement is decided (or the cap ``replicates`` is reached); (4) rows already in
the store are never recomputed, so the same command resumes an interrupted study.
"""

from __future__ import annotations

import dataclasses
import json
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from chiptwin import __version__
from chiptwin.config import ScenarioError
from chiptwin.config.cost import WORKER_START_S
from chiptwin.detection.stats import (
    INTERIM_ALPHA_SHARE,
    Estimate,
    decide,
    look_levels,
    look_sizes,
    looks_confidence,
    loss_db_interval,
    mean_estimate,
    rate_estimate,
)
from chiptwin.study import search, sensitivity
from chiptwin.study.execute import WORKER_TIMEOUT_S, batches, make_executor, rows_per_task
from chiptwin.study.metrics import CATALOGUE, row_metrics
from chiptwin.study.rows import SCENE_CACHE_SIZE, RowTask, chip_seed, row_seed
from chiptwin.study.spec import Point, Study, load_study, point_scenario
from chiptwin.study.store import Store

Progress = Callable[[int, int], None]
#: Point statuses that end a point's looks (``undecided`` adds a batch; ``measured`` has no
#: requirement to decide).
DECIDED = ("pass", "fail", "invalid")


@dataclass
class StudyResult:
    """A finished study: ``table`` (one dict per run), ``answer`` (one per combination of the
    given axes), ``summary`` (what ``study.json`` holds)."""

    study: Study
    table: list[dict[str, Any]]
    answer: list[dict[str, Any]]
    summary: dict[str, Any] = field(default_factory=dict)


def run_study(study: Study | str | Path, workers: int | None = None,
              scheduler: str | None = None, db: str | Path = ":memory:", fresh: bool = False,
              progress: Progress | None = None,
              announce: Callable[[float, int], None] | None = None, *,
              task_rows: int | None = None, in_flight: int | None = None,
              scheduler_file: str | None = None,
              worker_timeout_s: float = WORKER_TIMEOUT_S) -> StudyResult:
    """Run a study and return its table and answer.

    Parameters
    ----------
    study : a :class:`Study`, a study file, or the name of a bundled study
    workers : processes of the local pool (default: every core; 1 runs in this process)
    scheduler : a Dask scheduler address, or ``"local"`` for a ``distributed.LocalCluster``
    db : the SQLite file rows go to (``":memory:"``: nothing kept); an existing one resumes
    fresh : discard the rows stored in ``db`` first
    progress : ``progress(rows_done, rows_total)`` as rows finish
    announce : ``announce(seconds, rows)`` once before the first row: the estimated wall time
        of the rows not stored yet (:func:`estimate_s`) on this executor's workers
    task_rows : rows per executor task (default: a few seconds of rows,
        :func:`chiptwin.study.execute.rows_per_task`); the table does not depend on it
    in_flight : executor tasks out at once (default: two per worker)
    scheduler_file : a Dask scheduler file (instead of ``scheduler``), as HPC clusters write
    worker_timeout_s : seconds a Dask cluster may take to show its first worker
    """
    t0 = time.perf_counter()
    if not isinstance(study, Study):
        from chiptwin.config.catalog import resolve_scenario, resolve_study

        study = load_study(resolve_study(str(study)), resolve_scenario)
    if study.kind == "calibrate":  # a fit, not a grid of rows (chiptwin.study.calibrate)
        from chiptwin.study.calibrate import run_calibrate

        table, summary = run_calibrate(study, workers, scheduler, db, fresh, progress,
                                       announce, in_flight=in_flight,
                                       scheduler_file=scheduler_file,
                                       worker_timeout_s=worker_timeout_s)
        return StudyResult(study, table, summary["answer"], summary)
    if study.kind == "optimize":  # a design search with Optuna (chiptwin.study.optimize)
        from chiptwin.study.optimize import run_optimize

        table, summary = run_optimize(study, workers, scheduler, db, fresh, progress,
                                      announce, in_flight=in_flight,
                                      scheduler_file=scheduler_file,
                                      worker_timeout_s=worker_timeout_s)
        return StudyResult(study, table, summary["answer"], summary)
    plan = Plan(study)  # validates every point before anything runs
    # a bad scheduler fails before the store
    executor = make_executor(workers, scheduler, in_flight, scheduler_file, worker_timeout_s)
    try:
        store = Store(db, study, fresh=fresh)
        try:
            resumed = len(store.done())
            if announce:
                per_row, rows = estimate_s(plan)
                left = max(rows - resumed, 0)
                start = WORKER_START_S if executor.workers > 1 else 0.0
                announce(start + per_row * left / max(executor.workers, 1), left)
            runner = _Runner(plan, store, executor, progress, task_rows)
            decisions = runner.search()
            table = store.rows()
        finally:
            store.close()
    except BaseException:  # Ctrl-C, SIGTERM, an error: stored rows stay, workers go now
        executor.abort()
        raise
    executor.close()
    summary = summarise(plan, table, decisions)
    summary["runs"].update(resumed=resumed, computed=runner.computed)
    summary.update(wall_time_s=round(time.perf_counter() - t0, 3),
                   executor={"kind": executor.name, "workers": executor.workers})
    return StudyResult(study, table, summary["answer"], summary)


def estimate_s(plan: Plan) -> tuple[float, int]:
    """The mean estimated seconds of one row and the rows the study may run (a bisect's cap),
    from each valid point's :func:`chiptwin.config.cost.row_seconds`: the scene's preparation
    shared by the point's replicates (each a scene of its own where chips vary and the sites'
    DNA with them)."""
    from chiptwin.config.cost import row_seconds

    study = plan.study
    if study.calibration is not None:  # a calibration: one candidate's seconds, the most
        from chiptwin.study.calibrate_eval import candidate_seconds

        per = candidate_seconds(study)
        if per is not None:
            return per, study.calibration.max_evaluations
    seconds = [row_seconds(sc, 1 if _scene_per_row(sc) else study.replicates)
               for sc in plan.scenarios.values()]
    per_row = sum(seconds) / len(seconds) if seconds else 0.0
    rows = (len(plan.points) + len(plan.references)) * study.replicates
    if study.calibration is not None:  # the runs of one candidate, times the most candidates
        rows *= study.calibration.max_evaluations
    return per_row, rows


def _scene_per_row(s) -> bool:
    """Every replicate prepares its scene again: another chip and, with it, the sites' DNA, or
    another run of a flow-value model's chemistry (as ``chiptwin.study.rows`` does)."""
    from chiptwin.twin.stages import flow_model

    return (s.chip.fixed_pattern_seed < 0 and s.assay.kind == "pyrosequencing"
            and bool(s.assay.dna_cv)) or flow_model(s) is not None


class Plan:
    """The study's points, their validated scenarios (an inconsistent point is kept as invalid
    with its message), and their reference points."""

    def __init__(self, study: Study) -> None:
        self.study = study
        self.metrics = row_metrics(study.metrics)
        self.points = study.points()
        refs = {p.id: study.reference_point(p) for p in self.points}
        own = {p.id for p in self.points}
        self.reference_of = {pid: (r.id if r else None) for pid, r in refs.items()}
        self.references = {r.id: r for r in refs.values() if r and r.id not in own}
        fps = None
        if not study.vary_chip:
            pinned = study.base_raw.get("chip", {}).get("fixed_pattern_seed", -1)
            fps = pinned if pinned >= 0 else chip_seed(study.seed)
        self.scenarios: dict[str, Any] = {}
        self.invalid: dict[str, str] = {}
        for p in [*self.points, *self.references.values()]:
            try:
                self.scenarios[p.id] = point_scenario(study, p.params, study.seed, fps)
            except ScenarioError as exc:
                self.invalid[p.id] = str(exc)
        self.by_id = {p.id: p for p in [*self.points, *self.references.values()]}

    def tasks(self, point_id: str, replicates: range) -> list[RowTask]:
        p = self.by_id[point_id]
        return [RowTask(p.id, "reference" if p.reference else "point", r,
                        row_seed(self.study.seed, p.id, r), p.params, self.metrics,
                        self.scenarios.get(p.id), self.invalid.get(p.id, ""))
                for r in replicates]


class _Runner:
    """Runs missing rows through the executor into the store; keeps the rows in memory."""

    def __init__(self, plan: Plan, store: Store, executor, progress: Progress | None,
                 task_rows: int | None = None) -> None:
        self.plan, self.store, self.executor, self.progress = plan, store, executor, progress
        self.task_rows = task_rows
        self.rows: dict[tuple[str, int], dict] = {}
        self._ok_s, self._ok_n = 0.0, 0  # the wall time of the rows that ran, and how many
        for row in store.rows():
            self._keep(row)
        self.computed = 0
        self.total = 0

    def _keep(self, row: dict) -> None:
        self.rows[(row["point"], row["replicate"])] = row
        if row["status"] == "ok":
            self._ok_s += row["wall_s"]
            self._ok_n += 1

    def ensure(self, wanted: list[tuple[str, int]]) -> None:
        """Run every ``(point, replicates)`` row not stored yet, in tasks of consecutive rows
        (a point's replicates together); each finished task's rows stored in one transaction."""
        tasks = list({(t.point, t.replicate): t for pid, n in wanted
                      for t in self.plan.tasks(pid, range(n))
                      if (t.point, t.replicate) not in self.rows}.values())
        self.total = max(self.total, len(self.rows) + len(tasks))
        if not tasks:
            return
        size = self.task_rows or rows_per_task(self.row_s(), len(tasks), self.executor.workers)
        for rows in self.executor.run(batches(tasks, size)):
            self.store.add(rows)
            for row in rows:
                self._keep(row)
            self.computed += len(rows)
            if self.progress:
                self.progress(len(self.rows), self.total)

    def row_s(self) -> float:
        """A row's seconds: the mean measured over the rows run so far, else the estimate."""
        return self._ok_s / self._ok_n if self._ok_n else estimate_s(self.plan)[0]

    def point_rows(self, pid: str, n: int) -> list[dict]:
        return [self.rows[(pid, r)] for r in range(n) if (pid, r) in self.rows]

    def search(self) -> dict[str, dict[str, Any]]:
        """Run what the search needs; returns, per point id, its replicates and confidence."""
        study, plan = self.plan.study, self.plan
        cap = study.replicates
        refs = sorted({r for r in plan.reference_of.values() if r})
        if study.search == "grid" and not study.stop_early:
            self.total = (len(plan.points) + len(plan.references)) * cap
            self.ensure([(pid, cap) for pid in refs] + [(p.id, cap) for p in plan.points])
            return {p.id: {"n": cap, "confidence": study.confidence} for p in plan.points}
        self.total = (len(plan.points) + len(plan.references)) * cap  # at most: it stops early
        self.ensure([(pid, cap) for pid in refs])
        if study.search == "grid":
            return self.stop_early()
        looks = -(-cap // study.batch)
        conf = looks_confidence(study.confidence, looks)
        out: dict[str, dict[str, Any]] = {}
        for group in _given_groups(plan.points):
            def decide_index(i: int, group=group) -> str:
                p = group[i]
                for n in look_sizes(cap, study.batch):
                    self.ensure([(p.id, n)])
                    status = point_status(plan, p, self.point_rows(p.id, n),
                                          self._ref_rows(p.id), conf)["status"]
                    if status in DECIDED:
                        break
                out[p.id] = {"n": n, "confidence": conf, "looks": looks}
                return status
            search.bisect(len(group), decide_index, study.verify)
        return out

    def stop_early(self) -> dict[str, dict[str, Any]]:
        """A grid in looks (:func:`~chiptwin.detection.stats.look_sizes`): each look runs the
        next ``batch`` replicates of every point of a group not decided yet, in one round
        through the executor; a point whose status is decided at the look's level
        (:func:`~chiptwin.detection.stats.look_levels`) stops there. The references ran whole
        before (every loss interval of a look uses all of its reference's rows).

        The groups (:meth:`look_group_size` points) go one after another: a process keeps a few
        prepared scenes (:data:`~chiptwin.study.rows.SCENE_CACHE_SIZE`), and a look over every
        point of a large grid would prepare each point again at each look in each process
        (≈ 11 s a point of ``adc_bits_pyro``, against 0.14 s a row)."""
        plan, study = self.plan, self.plan.study
        sizes = look_sizes(study.replicates, study.batch)
        levels = look_levels(study.confidence, len(sizes))
        self.total = (len(plan.points) + len(plan.references)) * study.replicates  # at most
        out: dict[str, dict[str, Any]] = {}
        size = self.look_group_size()
        for first in range(0, len(plan.points), size):
            undecided = plan.points[first:first + size]
            for look, (n, level) in enumerate(zip(sizes, levels, strict=True), 1):
                self.ensure([(p.id, n) for p in undecided])
                for p in undecided:
                    out[p.id] = {"n": n, "confidence": level, "look": look, "looks": len(sizes)}
                undecided = [p for p in undecided if point_status(
                    plan, p, self.point_rows(p.id, n), self._ref_rows(p.id), level)["status"]
                    not in DECIDED]
        return out

    def look_group_size(self) -> int:
        """Points whose looks run together: as many as a process keeps prepared, so each is
        prepared once per process as in a whole grid; more on many workers, so a look still
        gives every worker four rows or more (there a point's rows spread over processes that
        prepare it anyway)."""
        workers = max(self.executor.workers, 1)
        return max(SCENE_CACHE_SIZE, -(-4 * workers // self.plan.study.batch))

    def _ref_rows(self, pid: str) -> list[dict]:
        ref = self.plan.reference_of.get(pid)
        return self.point_rows(ref, self.plan.study.replicates) if ref else []


def _given_groups(points: list[Point]) -> list[list[Point]]:
    """Points grouped by the given axes' values, each group in cost order."""
    groups: dict[tuple, list[Point]] = {}
    for p in points:
        groups.setdefault(tuple(json.dumps(g) for g in p.given), []).append(p)
    return [sorted(g, key=lambda p: p.cost) for g in groups.values()]


def point_estimates(plan: Plan, rows: list[dict], ref_rows: list[dict], confidence: float
                    ) -> dict[str, Estimate]:
    """Every metric of a point from its ``ok`` rows."""
    ok = [r["metrics"] for r in rows if r["status"] == "ok"]
    out: dict[str, Estimate] = {}
    if not ok:
        return out
    for name in (*plan.study.metrics, *[m for m in plan.metrics if m not in plan.study.metrics]):
        kind = CATALOGUE[name].kind
        if kind == "rate":
            k, n = np.array([m[name] for m in ok]).T
            out[name] = rate_estimate(k, n, confidence)
        elif kind == "mean":
            out[name] = mean_estimate(np.array([m[name] for m in ok]), confidence)
        else:
            ref = [r["metrics"]["snr_power"] for r in ref_rows if r["status"] == "ok"]
            if ref:
                out[name] = loss_db_interval(np.array([m["snr_power"] for m in ok]),
                                             np.array(ref), confidence)
    return out


def point_status(plan: Plan, p: Point, rows: list[dict], ref_rows: list[dict],
                 confidence: float) -> dict[str, Any]:
    """Estimates, one decision per requirement, and the point's status."""
    est = point_estimates(plan, rows, ref_rows, confidence)
    if rows and all(r["status"] == "invalid" for r in rows):
        return {"status": "invalid", "estimates": est, "decisions": {}}
    decisions = {str(q): decide(est[q.metric], q.op, q.threshold) if q.metric in est
                 else "undecided" for q in plan.study.requirements}
    if not plan.study.requirements:
        status = "measured"
    elif "fail" in decisions.values():
        status = "fail"
    elif all(d == "pass" for d in decisions.values()):
        status = "pass"
    else:
        status = "undecided"
    return {"status": status, "estimates": est, "decisions": decisions}


def summarise(plan: Plan, table: list[dict], searched: dict[str, dict]) -> dict[str, Any]:
    """``study.json``: every point's estimates, the answer per given combination, the
    monotonicity check, run counts."""
    study = plan.study
    by_point: dict[str, list[dict]] = {}
    for row in table:
        by_point.setdefault(row["point"], []).append(row)
    points, status_of = [], {}
    for p in plan.points:
        info = searched.get(p.id)
        n = info["n"] if info else 0
        rows = [r for r in by_point.get(p.id, []) if r["replicate"] < n]
        ref = plan.reference_of.get(p.id)
        ref_rows = by_point.get(ref, []) if ref else []
        st = point_status(plan, p, rows, ref_rows, info["confidence"] if info else
                          study.confidence) if info else {"status": "not_visited",
                                                            "estimates": {}, "decisions": {}}
        status_of[p.id] = {**st, "confidence": info["confidence"] if info else None}
        points.append({
            "id": p.id, "params": p.params, "given": list(p.given), "cost": list(p.cost),
            "reference": ref, "status": st["status"], "replicates": len(rows),
            "rows": {s: sum(r["status"] == s for r in rows) for s in ("ok", "invalid", "error")},
            "confidence": info["confidence"] if info else None,
            "metrics": {k: e.as_dict() for k, e in st["estimates"].items()},
            "decisions": st["decisions"],
            "message": next((r["message"] for r in rows if r["message"]),
                            plan.invalid.get(p.id, "")),
        })
    answers, violations = [], []
    for group in _given_groups(plan.points):
        violations += _monotonicity(study, group, status_of)
        answers.append(_answer(study, group, status_of))
    counts = {s: sum(r["status"] == s for r in table) for s in ("ok", "invalid", "error")}
    summary = {
        "study": study.name, "description": study.description, "source": study.source,
        "quick": study.quick, "asked": study.asked,
        "scenario": study.scenario_path, "seed": study.seed, "search": study.search,
        "replicates": study.replicates, "vary_chip": study.vary_chip,
        "reference": study.reference, "confidence": study.confidence,
        "axes": [dataclasses.asdict(a) for a in study.axes],
        "requirement": [str(q) for q in study.requirements],
        "answer": answers, "points": points,
        "monotonicity": {"assumption": "along each budget axis, cheapest first, a point that "
                         "meets the requirement is followed by no point that fails it (an "
                         "undecided one, whose interval allows a pass, breaks nothing)",
                         "violations": violations},
        "statistics": {"rates": "Clopper-Pearson at Korn-Graubard's effective n: trials pooled "
                                 "over replicates, the replicates as clusters",
                       "design_effect": _design_effects(points),
                       "means": "Student t over replicates",
                       "snr_loss_db": "delta method on ln of mean power SNR, t quantile",
                       "requirement": "met when the one-sided bound at `confidence` is on the "
                                      "allowed side; " + search.UNDECIDED_IS_FAIL,
                       "bisect": "per-look confidence 1-(1-c)/looks (Bonferroni over the "
                                 "sequential looks)" if study.search == "bisect" else None,
                       "stop_early": STOP_EARLY_RULE if study.stop_early else None},
        "runs": {"total": len(table), **counts},
        "chiptwin_version": __version__,
    }
    if study.stop_early:
        summary["stop_early"] = _stop_early_summary(plan, table, searched)
    if study.kind == "sensitivity":  # a budget study's study.json stays as it was
        summary["kind"] = study.kind
        summary["sensitivity"] = sensitivity.analyse(summary, study.assumptions)
    return summary


STOP_EARLY_RULE = (
    "replicates added in looks of `batch` to every point not yet decided; a point stops at the "
    "first look that decides it (pass, fail or invalid), at most `replicates`; look k of K at "
    "one-sided level 1 - s(1-c)/(K-1) before the last and 1 - (1-s)(1-c) at the last, "
    f"s = {INTERIM_ALPHA_SHARE:g} (Haybittle-Peto's shape; the spends add to 1-c, so Bonferroni "
    "keeps the confidence over the looks); references run every replicate")


def _stop_early_summary(plan: Plan, table: list[dict], searched: dict[str, dict]
                        ) -> dict[str, Any]:
    """``study.json``'s ``stop_early``: the looks, where the points stopped, the runs saved
    against the whole grid (every point and reference at ``replicates``)."""
    study = plan.study
    sizes = look_sizes(study.replicates, study.batch)
    levels = look_levels(study.confidence, len(sizes))
    stopped = [sum(info.get("look") == k for info in searched.values())
               for k in range(1, len(sizes) + 1)]
    whole = (len(plan.points) + len(plan.references)) * study.replicates
    return {"rule": STOP_EARLY_RULE, "batch": study.batch,
            "looks": [{"replicates": n, "confidence": c, "points_stopped": k}
                      for n, c, k in zip(sizes, levels, stopped, strict=True)],
            "runs_whole_grid": whole, "runs": len(table), "runs_saved": whole - len(table)}


def _design_effects(points: list[dict]) -> str | None:
    """Per rate metric, the design effects measured where they could be (0 < k < n, at least
    ``MIN_CLUSTER_RUNS`` runs): what a point with k = 0 or k = n, whose bound assumes 1, can be
    judged by."""
    found: dict[str, list[float]] = {}
    for p in points:
        for name, e in p["metrics"].items():
            if e.get("method", "").startswith("Korn-Graubard") and 0 < e["k"] < e["trials"]:
                found.setdefault(name, []).append(e["design_effect"])
    if not found:
        return None
    def span(d: list[float]) -> str:
        lo, hi = f"{min(d):.3g}", f"{max(d):.3g}"
        return lo if lo == hi else f"{lo}–{hi}"

    return "; ".join(f"{name} {span(d)} at the {len(d)} point(s) with 0 < k < n"
                     for name, d in found.items()) + \
        " (a point with k = 0 or k = n takes 1: nothing to measure it from)"


def _answer(study: Study, group: list[Point], status_of: dict) -> dict[str, Any]:
    """The answer of one condition (a combination of the given axes' values), labelled with it:
    ``given`` (key: value) and ``condition`` (``key = value, …``, "" without given axes)."""
    given = {a.key: v for a, v in zip(study.given_axes, group[0].given, strict=False)}
    return {"given": given, "condition": ", ".join(f"{k} = {v}" for k, v in given.items()),
            **_answer_of(study, group, status_of)}


def _answer_of(study: Study, group: list[Point], status_of: dict) -> dict[str, Any]:
    if not study.requirements:
        return {"point": None, "statement": "no requirement: nothing to answer"}
    decisions = [status_of[p.id]["status"] for p in group]
    # a point counts only if nothing costlier along its line fails (monotone from it on)
    bad = {v["pass_at"] for v in _line_violations(study, group, status_of)}
    usable = [d if i not in bad else "fail" for i, d in enumerate(decisions)]
    i = search.cheapest([p.cost for p in group], usable)
    if i is None:
        return {"point": None, "statement": "no point meets " + " and ".join(
            map(str, study.requirements)) + f" at {study.confidence:.0%} confidence"}
    p, est = group[i], status_of[group[i].id]["estimates"]
    bounds = {}
    for q in study.requirements:
        e = est[q.metric]
        bound = e.upper if q.op == "<=" else e.lower
        bounds[str(q)] = {"estimate": e.value, "bound": bound, "n": e.n, "method": e.method,
                          **({"k": e.k, "trials": e.trials} if e.k is not None else {})}
    return {"point": p.params, "id": p.id, "bounds": bounds,
            "statement": statement(study, p, est, status_of[p.id]["confidence"])}


def statement(study: Study, p: Point, est: dict[str, Estimate], level: float | None = None
              ) -> str:
    """The answer in one sentence, with every bound, its level and its n (a point decided at a
    sequential look: the look's level, the study's confidence holding over the looks)."""
    at = f"{study.confidence:.0%}" if level in (None, study.confidence) else \
        f"{100 * level:.4g}% (its look's level; {study.confidence:.0%} over the looks)"
    budget = ", ".join(f"{k} = {v}" for k, v in p.params.items()
                       if k in {a.key for a in study.budget_axes})
    parts = []
    for q in study.requirements:
        e = est[q.metric]
        bound = e.upper if q.op == "<=" else e.lower
        side = "upper" if q.op == "<=" else "lower"
        seen = f"{e.k}/{e.trials} {CATALOGUE[q.metric].unit}" if e.k is not None else \
            f"{e.value:.4g}"
        parts.append(f"{q} ({seen}; one-sided {at} {side} bound "
                     f"{bound:.3g}, {e.method}, n = {e.n} runs)")
    return f"cheapest: {budget}: " + "; ".join(parts)


def _line_violations(study: Study, group: list[Point], status_of: dict) -> list[dict]:
    """Decision violations along each budget axis, as indices into ``group``."""
    out = []
    for ax in range(len(study.budget_axes)):
        lines: dict[tuple, dict[int, int]] = {}
        for i, p in enumerate(group):
            rest = p.cost[:ax] + p.cost[ax + 1:]
            lines.setdefault(rest, {})[p.cost[ax]] = i
        for line in lines.values():
            dec = {c: status_of[group[i].id]["status"] for c, i in line.items()}
            for v in search.violations(dec):
                out.append({"axis": study.budget_axes[ax].key, "pass_at": line[v["pass_at"]],
                            "fail_at": line[v["fail_at"]]})
    return out


def _monotonicity(study: Study, group: list[Point], status_of: dict) -> list[dict]:
    """Violations for the report: decision pairs, and metrics significantly worse (disjoint
    intervals) at a costlier point along a budget axis."""
    out = [{"kind": "decision", "axis": v["axis"], "passes": group[v["pass_at"]].params,
            "fails": group[v["fail_at"]].params}
           for v in _line_violations(study, group, status_of)]
    if len(study.budget_axes) != 1:
        return out
    seen = [p for p in group if status_of[p.id]["estimates"]]
    for q in study.requirements:
        for a, b in zip(seen, seen[1:], strict=False):
            ea, eb = status_of[a.id]["estimates"].get(q.metric), status_of[b.id][
                "estimates"].get(q.metric)
            if ea is None or eb is None:
                continue
            worse = eb.lo > ea.hi if q.op == "<=" else eb.hi < ea.lo
            if worse:
                out.append({"kind": "metric", "metric": q.metric, "cheaper": a.params,
                            "costlier": b.params, "cheaper_interval": [ea.lo, ea.hi],
                            "costlier_interval": [eb.lo, eb.hi]})
    return out
