"""An optimize study's ``study.json``: the feasible Pareto front with intervals, the chosen point
and the rule choosing it, the hypervolume's convergence with its reference point, the stopping
rule and what stopped the search."""

from __future__ import annotations

from typing import Any

import numpy as np

from chiptwin import __version__
from chiptwin.study.metrics import CATALOGUE
from chiptwin.study.optimize_front import (
    CHOSEN_RULE,
    CHOSEN_RULE_ONE,
    REFERENCE_MARGIN,
    chosen_index,
    convergence,
    minimised,
    pareto_mask,
    reference_point,
)


def summarise(study: Any, search: Any, records: list[dict[str, Any]]) -> dict[str, Any]:
    """Everything the report, the plots and the CLI read, from the finished trials."""
    opt = study.optimization
    done = [r for r in records if r["state"] == "complete"]
    F = minimised(records, opt.objectives)  # a failed trial: NaN, never feasible
    feasible = np.array([r["feasible"] for r in records], dtype=bool)
    given = [None if o.reference is None else o.sign * o.reference for o in opt.objectives]
    ref = reference_point(F[feasible], given)
    curve = convergence(F, feasible, ref) if feasible.any() else [0.0] * len(records)
    idx = np.flatnonzero(feasible)
    front_idx = idx[pareto_mask(F[idx])] if len(idx) else idx
    front_idx = np.array([i for n, i in enumerate(front_idx)  # a point asked for twice: once
                          if records[i]["id"] not in {records[j]["id"]
                                                      for j in front_idx[:n]}], int)
    front = [records[i] for i in front_idx]
    chosen = front[chosen_index(F[front_idx])] if front else None
    single = len(opt.objectives) == 1
    if single and front:  # one objective: the front is its best point(s)
        front = [chosen]
    rows = search.rows.values()
    counts = {s: sum(r["status"] == s for r in rows) for s in ("ok", "invalid", "error")}
    return {
        "study": study.name, "kind": "optimize", "description": study.description,
        "source": study.source, "scenario": study.scenario_path, "seed": study.seed,
        "replicates": study.replicates, "vary_chip": study.vary_chip,
        "confidence": study.confidence,
        "sampler": {"name": opt.sampler, "batch": opt.batch, "library": "optuna",
                    "optuna_version": search.optuna.__version__},
        "parameters": [_parameter(p) for p in opt.parameters],
        "objectives": [{"metric": o.metric, "direction": o.direction,
                        "unit": CATALOGUE[o.metric].unit} for o in opt.objectives],
        "constraints": [{"metric": c.metric, "op": c.op, "bound": c.bound, "judged": c.judged,
                         "rule": _constraint_rule(c, study.confidence)}
                        for c in opt.constraints],
        "evaluations": {"budget": opt.evaluations, "done": len(records),
                        "complete": len(done), "failed": len(records) - len(done),
                        "feasible": int(feasible.sum()),
                        "distinct_points": len({r["id"] for r in records})},
        "stop": {"rule": str(opt.stop), "gain": opt.stop.gain, "last": opt.stop.last,
                 "stopped_by": search.stopped_by, "at_evaluation": len(records)},
        "hypervolume": {
            "reference_point": {o.metric: (float(o.sign * r) if np.isfinite(r) else None)
                                for o, r in zip(opt.objectives, ref, strict=True)},
            "reference_rule": "each objective's given reference, else the worst feasible "
                              f"value pushed out by {REFERENCE_MARGIN:g} of the feasible "
                              "span (Ishibuchi et al. 2018)",
            "final": curve[-1] if curve else 0.0, "curve": curve,
            "units": "product of the objectives' units, each turned to minimisation"},
        "front": [_point(r, study) for r in front],
        "chosen": {"rule": CHOSEN_RULE_ONE if single else CHOSEN_RULE,
                   "point": _point(chosen, study) if chosen else None},
        "answer": [{"statement": statement(study, chosen)}],
        "trials": [_point(r, study) for r in records],
        "runs": {"total": len(search.rows), **counts, "computed": search.computed,
                 "resumed": search.resumed},
        "chiptwin_version": __version__,
    }


def _parameter(p: Any) -> dict[str, Any]:
    if p.choices:
        return {"key": p.key, "values": list(p.choices), "why": p.why}
    return {"key": p.key, "range": [p.lo, p.hi], "scale": "log" if p.log else "lin",
            "integer": p.integer, "why": p.why}


def _constraint_rule(c: Any, confidence: float) -> str:
    if c.judged == "estimate":
        return f"{c}: the point estimate"
    side = "upper" if c.op == "<=" else "lower"
    return f"{c}: the one-sided {confidence:.0%} {side} bound"


def _point(r: dict[str, Any], study: Any) -> dict[str, Any]:
    return {"trial": r["trial"], "id": r["id"], "params": r["params"], "state": r["state"],
            "feasible": r["feasible"],
            "constraints": {k: v if np.isfinite(v) else "inf" for k, v in r["constraints"].items()},
            "metrics": {k: e.as_dict() for k, e in r["metrics"].items()},
            "message": r["message"]}


def statement(study: Any, r: dict[str, Any] | None) -> str:
    """The chosen point in one sentence, every objective and constraint with its interval."""
    opt = study.optimization
    if r is None:
        return ("no evaluated point meets " + " and ".join(map(str, opt.constraints))
                + f" at {study.confidence:.0%}" if opt.constraints else
                "no evaluated point gave the objectives")
    keys = ", ".join(f"{k} = {_fmt(v)}" for k, v in r["params"].items())
    parts = []
    for o in opt.objectives:
        e = r["metrics"][o.metric]
        parts.append(f"{o.metric} {e.value:.4g} [{e.lo:.4g}, {e.hi:.4g}] ({o.direction})")
    for c in opt.constraints:
        e = r["metrics"][c.metric]
        bound = e.upper if c.op == "<=" else e.lower
        parts.append(f"{c} (estimate {e.value:.3g}, one-sided bound {bound:.3g})")
    return (f"chosen: {keys}: " + "; ".join(parts)
            + f" ({study.confidence:.0%} intervals, n = {study.replicates} runs)")


def _fmt(v: Any) -> str:
    return f"{v:.4g}" if isinstance(v, float) else str(v)
