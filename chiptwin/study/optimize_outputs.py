"""An optimize study's outputs beside its database: ``results.csv`` (every evaluation),
``pareto.csv`` and ``pareto.json`` (the feasible front, each point's keys, metrics and
intervals), ``front.png``, ``chosen.png``, ``convergence.png``, ``report.md``, ``study.json``.

Written as a budget study's are (:mod:`chiptwin.study.outputs`): each file through a temporary
name and a rename, ``study.json`` (the mark of a finished study) last.
"""

from __future__ import annotations

import csv
import io
import itertools
import json
from pathlib import Path
from typing import Any

import numpy as np

from chiptwin.study.files import write_atomic
from chiptwin.twin.figures import save_figure


def write_optimize_outputs(result: Any, out: Path) -> None:
    """Every output of a finished design search into ``out`` (which holds results.sqlite)."""
    s = result.summary
    write_atomic(out / "results.csv", points_csv(s, s["trials"]))
    write_atomic(out / "pareto.csv", points_csv(s, s["front"]))
    write_atomic(out / "pareto.json", json.dumps(
        {"objectives": s["objectives"], "constraints": s["constraints"],
         "confidence": s["confidence"], "chosen": s["chosen"], "front": s["front"]},
        indent=1) + "\n")
    plots = [front_plot(s, out), chosen_plot(s, out), convergence_plot(s, out)]
    write_atomic(out / "report.md", report_markdown(s, [p for p in plots if p]))
    write_atomic(out / "study.json", json.dumps(s, indent=1, default=str) + "\n")


def _metric_names(s: dict[str, Any]) -> list[str]:
    return list(dict.fromkeys([o["metric"] for o in s["objectives"]]
                              + [c["metric"] for c in s["constraints"]]))


def points_csv(s: dict[str, Any], points: list[dict[str, Any]]) -> str:
    """One line per point: trial, state, feasibility, the keys, each metric with its
    two-sided interval and one-sided bounds."""
    keys = [p["key"] for p in s["parameters"]]
    names = _metric_names(s)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["trial", "point", "state", "feasible", *keys,
                *[f"{m}_{x}" for m in names for x in ("value", "lo", "hi", "lower", "upper")],
                "message"])
    for p in points:
        values = []
        for m in names:
            e = p["metrics"].get(m, {})
            values += [e.get(x, "") for x in ("value", "lo", "hi", "lower", "upper")]
        w.writerow([p["trial"], p["id"], p["state"], p["feasible"],
                    *[p["params"][k] for k in keys], *values, p["message"]])
    return buf.getvalue()


def answer_lines(s: dict[str, Any]) -> list[str]:
    """What the CLI prints: the chosen point, the front's size, what stopped the search."""
    ev, stop = s["evaluations"], s["stop"]
    return [a["statement"] for a in s["answer"]] + [
        f"front: {len(s['front'])} feasible non-dominated point(s) of {ev['feasible']} "
        f"feasible, {ev['done']} evaluations ({ev['distinct_points']} distinct points); "
        f"stopped by {stop['stopped_by']} ({stop['rule']})"]


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _values(points: list[dict], metric: str, what: str = "value") -> np.ndarray:
    return np.array([p["metrics"][metric][what] for p in points], dtype=float)


def _wide(values: np.ndarray) -> bool:
    """Positive values over more than two decades: drawn on a log axis."""
    v = values[np.isfinite(values)]
    return v.size > 1 and v.min() > 0 and v.max() / v.min() > 100


def front_plot(s: dict[str, Any], folder: Path) -> tuple[str, str] | None:
    """Every pair of objectives: the evaluated points (infeasible crossed), the feasible front
    with its intervals, the chosen point starred. One objective: the objective against the
    evaluation number."""
    plt = _plt()
    objs = [o["metric"] for o in s["objectives"]]
    done = [p for p in s["trials"] if p["state"] == "complete"]
    if not done:
        return None
    pairs = list(itertools.combinations(objs, 2)) or [("evaluation", objs[0])]
    fig, axes = plt.subplots(1, len(pairs), figsize=(5.2 * len(pairs), 4.0), squeeze=False)
    chosen = s["chosen"]["point"]
    for ax, (mx, my) in zip(axes[0], pairs, strict=True):
        def xs(points, what="value", mx=mx):
            return (np.array([p["trial"] for p in points], dtype=float) if mx == "evaluation"
                    else _values(points, mx, what))
        for feas, marker, label in ((True, "o", "feasible"), (False, "x", "infeasible")):
            pts = [p for p in done if p["feasible"] is feas]
            if pts:
                ax.plot(xs(pts), _values(pts, my), marker, color="0.6", ms=4, label=label,
                        ls="none")
        front = sorted(s["front"], key=lambda p: xs([p])[0])
        if front:
            x, y = xs(front), _values(front, my)
            yerr = [y - _values(front, my, "lo"), _values(front, my, "hi") - y]
            xerr = None if mx == "evaluation" else [x - xs(front, "lo"), xs(front, "hi") - x]
            ax.errorbar(x, y, yerr=yerr, xerr=xerr, fmt="o-", color="C0", capsize=2,
                        label="Pareto front (feasible)")
        if chosen:
            ax.plot(xs([chosen]), _values([chosen], my), "*", color="C3", ms=14,
                    label="chosen")
        ax.set_xlabel(mx)
        ax.set_ylabel(my)
        for values, set_scale in ((xs(done), ax.set_xscale), (_values(done, my), ax.set_yscale)):
            if _wide(values):
                set_scale("log")
        ax.legend(fontsize=7)
    return save_figure(fig, folder, "front.png", "The evaluated points and the feasible Pareto "
                       f"front ({s['confidence']:.0%} intervals), each pair of objectives; the "
                       f"chosen point starred ({s['chosen']['rule']}).")


def chosen_plot(s: dict[str, Any], folder: Path) -> tuple[str, str] | None:
    """The chosen point's value of each key, placed within the key's searched range (or
    among its choices)."""
    chosen = s["chosen"]["point"]
    if chosen is None:
        return None
    plt = _plt()
    params = s["parameters"]
    fig, ax = plt.subplots(figsize=(6.5, 0.6 + 0.55 * len(params)))
    for i, p in enumerate(params):
        v = chosen["params"][p["key"]]
        if "values" in p:
            j = p["values"].index(v)
            frac, ends = j / max(len(p["values"]) - 1, 1), (p["values"][0], p["values"][-1])
        else:
            lo, hi = p["range"]
            frac = (np.log(v / lo) / np.log(hi / lo)) if p["scale"] == "log" else \
                (v - lo) / (hi - lo)
            ends = (lo, hi)
        ax.plot([0, 1], [i, i], color="0.8", lw=6, solid_capstyle="butt")
        ax.plot([frac], [i], "o", color="C3")
        ax.annotate(f"{v:.4g}" if isinstance(v, float) else str(v), (frac, i),
                    textcoords="offset points", xytext=(0, 6), ha="center", fontsize=8)
        ax.annotate(f"{ends[0]:g}" if isinstance(ends[0], float) else str(ends[0]), (0, i),
                    textcoords="offset points", xytext=(-4, -3), ha="right", fontsize=7)
        ax.annotate(f"{ends[1]:g}" if isinstance(ends[1], float) else str(ends[1]), (1, i),
                    textcoords="offset points", xytext=(4, -3), ha="left", fontsize=7)
    ax.set_yticks(range(len(params)), [p["key"] for p in params], fontsize=8)
    ax.set_xlim(-0.15, 1.15)
    ax.set_ylim(-0.7, len(params) - 0.3)
    ax.set_xticks([])
    ax.set_title("the chosen point within each key's range", fontsize=9)
    return save_figure(fig, folder, "chosen.png", "The chosen point's keys, each within its "
                       f"searched range (log keys on a log scale); rule: {s['chosen']['rule']}.")


def convergence_plot(s: dict[str, Any], folder: Path) -> tuple[str, str] | None:
    """The feasible front's hypervolume after each evaluation, and where the search stopped."""
    curve = s["hypervolume"]["curve"]
    if not curve:
        return None
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.5, 3.4))
    ax.plot(np.arange(1, len(curve) + 1), curve, "-", color="C0")
    if s["stop"]["gain"]:
        ax.axvline(len(curve), color="C3", ls=":", label=f"stopped ({s['stop']['stopped_by']})")
        ax.legend(fontsize=8)
    ax.set_xlabel("evaluations (a failed or infeasible one adds nothing)")
    ax.set_ylabel("hypervolume of the feasible front")
    ref = ", ".join(f"{k} = {v:.4g}" if v is not None else f"{k} = none"
                    for k, v in s["hypervolume"]["reference_point"].items())
    return save_figure(fig, folder, "convergence.png", "Hypervolume of the feasible Pareto "
                       f"front against evaluations; reference point {ref} "
                       f"({s['hypervolume']['reference_rule']}). Stopping rule: "
                       f"{s['stop']['rule']}.")


def report_markdown(s: dict[str, Any], plots: list[tuple[str, str]]) -> str:
    """report.md: the search, the chosen point, the front, the stopping rule, the plots."""
    ev, hv = s["evaluations"], s["hypervolume"]
    lines = [f"# {s['study']}: design search", "", s["description"], "",
             f"Scenario `{s['scenario']}`, seed {s['seed']}, {s['replicates']} replicates per "
             f"point, {s['confidence']:.0%} intervals; sampler Optuna "
             f"{s['sampler']['optuna_version']} {s['sampler']['name']} in batches of "
             f"{s['sampler']['batch']}.", "", "## Answer", "",
             *[f"- {a['statement']}" for a in s["answer"]], "",
             f"Chosen by: {s['chosen']['rule']}.", "", "## Search", "",
             "| key | searched | why |", "| --- | --- | --- |"]
    for p in s["parameters"]:
        where = (", ".join(map(str, p["values"])) if "values" in p else
                 f"[{p['range'][0]:g}, {p['range'][1]:g}] {p['scale']}"
                 + (" (integer)" if p["integer"] else ""))
        lines.append(f"| `{p['key']}` | {where} | {p['why']} |")
    lines += ["", "Objectives: " + "; ".join(f"{o['direction']} `{o['metric']}` [{o['unit']}]"
                                            for o in s["objectives"]) + ".",
              "Constraints: " + ("; ".join(c["rule"] for c in s["constraints"]) or "none") + ".",
              "", f"Evaluations: {ev['done']} of a budget of {ev['budget']} ({ev['complete']} "
              f"complete, {ev['failed']} failed, {ev['feasible']} feasible, "
              f"{ev['distinct_points']} distinct points).", "",
              f"**Stopping rule**: {s['stop']['rule']}; stopped by {s['stop']['stopped_by']} "
              f"after {s['stop']['at_evaluation']} evaluations.", "",
              f"Hypervolume of the feasible front: {hv['final']:.6g}; reference point "
              + ", ".join(f"{k} = {_g(v, '.4g')}" for k, v in hv["reference_point"].items())
              + f" ({hv['reference_rule']}).", "", "## Pareto front (feasible)", ""]
    lines += _front_table(s)
    for name, caption in plots:
        lines += ["", f"![{name}]({name})", "", caption]
    lines += ["", f"Runs: {s['runs']['total']} ({s['runs']['computed']} computed now, "
              f"{s['runs']['resumed']} resumed) in {s.get('wall_time_s', 0):.1f} s on "
              f"{s.get('executor', {}).get('kind', '?')} × "
              f"{s.get('executor', {}).get('workers', '?')}; chiptwin "
              f"{s['chiptwin_version']}.", ""]
    return "\n".join(lines)


def _front_table(s: dict[str, Any]) -> list[str]:
    if not s["front"]:
        return ["No feasible point."]
    keys = [p["key"] for p in s["parameters"]]
    names = _metric_names(s)
    out = ["| trial | " + " | ".join(f"`{k}`" for k in keys) + " | "
           + " | ".join(f"{m} [interval]" for m in names) + " |",
           "|" + " --- |" * (1 + len(keys) + len(names))]
    for p in s["front"]:
        cells = [f"{p['params'][k]:.4g}" if isinstance(p["params"][k], float)
                 else str(p["params"][k]) for k in keys]
        cells += [f"{_g(e['value'], '.4g')} [{_g(e['lo'])}, {_g(e['hi'])}]"
                  for e in (p["metrics"][m] for m in names)]
        mark = " ★" if s["chosen"]["point"] and p["id"] == s["chosen"]["point"]["id"] else ""
        out.append(f"| {p['trial']}{mark} | " + " | ".join(cells) + " |")
    return out


def _g(v: Any, spec: str = ".3g") -> str:
    """A number as text (``"inf"``, as study.json stores an infinite bound, kept)."""
    return format(v, spec) if isinstance(v, int | float) else str(v)
