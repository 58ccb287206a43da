"""A study's outputs beside its database: ``results.csv``, ``study.json``, ``report.md``, plots.

The folder keeps ``results.sqlite`` (the resumable store), so it is not replaced whole like a
run's; each file is written to a temporary name and renamed into place, and ``study.json`` (the
mark of a finished study) is removed when a study starts and written last.
"""

from __future__ import annotations

import csv
import io
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from chiptwin.study.engine import StudyResult
from chiptwin.study.files import write_atomic
from chiptwin.study.least import least_values
from chiptwin.study.metrics import CATALOGUE
from chiptwin.study.tornado import sensitivity_markdown, tornado_plot
from chiptwin.twin.figures import save_figure as _save


def write_study_outputs(result: StudyResult, out: Path) -> None:
    """Every output of a finished study into ``out`` (which holds its results.sqlite)."""
    if result.summary.get("kind") == "calibrate":
        from chiptwin.study.calibrate_outputs import write_calibrate_outputs

        return write_calibrate_outputs(result, out)
    if result.summary.get("kind") == "optimize":
        from chiptwin.study.optimize_outputs import write_optimize_outputs

        return write_optimize_outputs(result, out)
    least_values(result.study, result.summary, result.table)
    write_atomic(out / "results.csv", results_csv(result))
    plots = make_plots(result.summary, out)
    if "sensitivity" in result.summary:
        plots.insert(0, tornado_plot(result.summary, out))
    write_atomic(out / "report.md", report_markdown(result.summary, plots))
    write_atomic(out / "study.json", json.dumps(result.summary, indent=1, default=str) + "\n")


def results_csv(result: StudyResult) -> str:
    """One line per run: identity, parameters, each metric (rates as ``_k`` and ``_n``)."""
    params = list(dict.fromkeys(k for r in result.table for k in r["params"]))
    metrics = list(dict.fromkeys(k for r in result.table for k in (r["metrics"] or {})))
    cols = ["point", "kind", "replicate", "seed", "status", "wall_s", *params]
    for m in metrics:
        cols += [f"{m}_k", f"{m}_n"] if CATALOGUE[m].kind == "rate" else [m]
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow([*cols, "message"])
    for r in result.table:
        values = [r["point"], r["kind"], r["replicate"], r["seed"], r["status"],
                  f"{r['wall_s']:.4f}", *[r["params"].get(k, "") for k in params]]
        for m in metrics:
            v = (r["metrics"] or {}).get(m, "")
            values += list(v) if isinstance(v, list) else ["" if v == "" else repr(v)]
            if isinstance(v, str) and CATALOGUE[m].kind == "rate":
                values.append("")
        w.writerow([*values, r["message"]])
    return buf.getvalue()


def answer_lines(summary: dict[str, Any]) -> list[str]:
    """The answer, one line per combination of the given axes (what the CLI prints)."""
    if summary.get("kind") == "calibrate":
        from chiptwin.study.calibrate_outputs import answer_lines as calibrate_lines

        return calibrate_lines(summary)
    if summary.get("kind") == "optimize":
        from chiptwin.study.optimize_outputs import answer_lines as optimize_lines

        return optimize_lines(summary)
    lines = [quick_line(summary)] if summary.get("quick") else []
    at_reference = _reference_values(summary)
    for a in summary["answer"]:
        given = condition_label(a["given"], at_reference)
        lines.append((f"[{given}] " if given else "") + a["statement"])
        lines += [f"  least {key}: {least['text']}" for key, least in a.get("least", {}).items()
                  if least]
    if "sensitivity" in summary:
        lines.append("SENSITIVITY: " + summary["sensitivity"]["verdict"])
    v = summary["monotonicity"]["violations"]
    decisions = [x for x in v if x["kind"] == "decision"]
    if decisions:
        lines.append(f"MONOTONICITY VIOLATED: {len(decisions)} passing point(s) followed by a "
                     "failing one along a budget axis; the answer skips passing points below a "
                     "failure (study.json monotonicity.violations)")
    if len(v) > len(decisions):
        lines.append(f"monotonicity: {len(v) - len(decisions)} metric(s) significantly worse at "
                     "a costlier point (disjoint intervals; study.json monotonicity.violations)")
    return lines


def quick_line(summary: dict[str, Any]) -> str:
    """What a ``--quick`` study shrank, said before its answers."""
    return (f"QUICK LOOK ({summary['quick']}): a first look, not the study's answer; run it "
            "without --quick for that")


def condition_label(given: dict[str, Any], at_reference: dict[str, Any] | None = None) -> str:
    """A condition as ``key = value, …`` (every given axis); a sensitivity study's assumptions
    are named only where moved from their reference value ("reference" where none is)."""
    ref = at_reference or {}
    own = [f"{k} = {v}" for k, v in given.items() if k not in ref]
    moved = [f"{k} = {v}" for k, v in given.items() if k in ref and ref[k] != v]
    return ", ".join(own + (moved or (["reference"] if ref else [])))


def _reference_values(summary: dict[str, Any]) -> dict[str, Any]:
    """A sensitivity study's assumptions at their reference values (labels name only the
    assumption moved from it); ``{}`` for a budget study."""
    return {a["key"]: a["reference"] for a in summary.get("sensitivity", {}).get(
        "assumptions", [])}


@dataclass(frozen=True)
class Line:
    """One line of a metric-against-axis plot: one condition (the given axes' values, and the
    other budget axes' where there are several), its points, and where its answer is."""

    label: str
    x: np.ndarray
    value: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    star: int | None  # the index of the condition's answer on this line, or None


def plot_lines(summary: dict[str, Any], axis: str, name: str) -> list[Line]:
    """The lines of ``name`` against the budget axis ``axis``: one per condition, each with the
    points that have the metric, cheapest first, and its answer's star."""
    at_reference = _reference_values(summary)
    given_keys = [a["key"] for a in summary["axes"] if a["given"]]
    others = [a["key"] for a in summary["axes"] if not a["given"] and a["key"] != axis]
    groups: dict[str, list[dict]] = {}
    for p in summary["points"]:
        if p["metrics"].get(name) is not None:
            label = ", ".join(filter(None, [
                condition_label({k: p["params"][k] for k in given_keys}, at_reference),
                *(f"{k} = {p['params'][k]}" for k in others)]))
            groups.setdefault(label, []).append(p)
    answers = [a["point"] for a in summary["answer"] if a.get("point")]
    lines = []
    for label, group in groups.items():
        group.sort(key=lambda p: p["params"][axis])
        est = [p["metrics"][name] for p in group]
        star = next((i for i, p in enumerate(group) if p["params"] in answers), None)
        lines.append(Line(label, np.array([p["params"][axis] for p in group], dtype=float),
                          np.array([_num(e["value"]) for e in est]),
                          np.array([_num(e["lo"]) for e in est]),
                          np.array([_num(e["hi"]) for e in est]), star))
    return lines


def make_plots(summary: dict[str, Any], folder: Path) -> list[tuple[str, str]]:
    """Each metric against each budget axis with its interval band, one line and one star (its
    answer) per condition, named in the legend; the requirement line; a map of the status over
    two budget axes (one facet per value of a third); memory occupancy against capacity."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    points = [p for p in summary["points"] if p["metrics"]]
    budget = [a["key"] for a in summary["axes"] if not a["given"]]
    names = list(dict.fromkeys(m for p in points for m in p["metrics"]))
    requirement = {r.split()[0]: (r.split()[1], float(r.split()[2]))
                   for r in summary["requirement"]}
    # the band is each point's interval at the level it was decided at: the study's for a grid,
    # the per-look level for a bisection (Bonferroni over its looks)
    levels = ({p["confidence"] for p in points if p.get("confidence") is not None}
              or {summary["confidence"]})
    band = f"{levels.pop():.4g}" if len(levels) == 1 else "per-point"
    quick = "QUICK LOOK: " if summary.get("quick") else ""
    plots = []
    for axis in budget:
        for name in names:
            fig, ax = plt.subplots(figsize=(6.5, 3.4))
            lines = plot_lines(summary, axis, name)
            for ln in lines:
                drawn = ax.plot(ln.x, ln.value, "o-", ms=3, label=ln.label or None)[0]
                ax.fill_between(ln.x, ln.lo, ln.hi, alpha=0.2, color=drawn.get_color())
                if ln.star is not None:
                    ax.plot(ln.x[ln.star], ln.value[ln.star], "*", ms=14, zorder=5,
                            color=drawn.get_color())
            if any(ln.star is not None for ln in lines):
                ax.plot([], [], "*", ms=10, color="grey", label="the answer (cheapest passing)")
            if name in requirement:
                ax.axhline(requirement[name][1], color="red", ls="--", lw=1,
                           label=f"requirement {requirement[name][0]} {requirement[name][1]:g}")
            if name == "memory_peak_frames":
                cap = [(p["params"][axis], p["metrics"]["memory_capacity_frames"]["value"])
                       for p in points if "memory_capacity_frames" in p["metrics"]]
                if cap:
                    c = np.array(sorted(cap), dtype=float)
                    ax.step(c[:, 0], c[:, 1], "k:", where="mid", label="capacity")
            _log_if_wide(ax, axis, points, name)
            _integer_ticks(ax, axis, points)
            ax.set(xlabel=axis, ylabel=f"{name} ({CATALOGUE[name].unit})")
            ax.set_title(f"{quick}{name} vs {axis} (band: {band} confidence interval)",
                         fontsize=9)
            if ax.get_legend_handles_labels()[0]:
                ax.legend(fontsize=7)
            fname = f"{name}_vs_{axis.replace('.', '_')}.png"
            plots.append(_save(fig, folder, fname, f"{quick}{name} against {axis}, one line "
                               f"per condition; band: two-sided interval at {band} confidence "
                               "(for a bisection its per-look level); star: the condition's "
                               "answer"))
    if len(budget) >= 2:
        plots.append(_heat_map(summary, budget, folder))
    return plots


def _integer_ticks(ax, axis: str, points: list[dict]) -> None:
    """An axis of whole numbers (bits, frames) gets whole-number ticks, never 12.5 bits."""
    from matplotlib.ticker import MaxNLocator

    xs = [p["params"][axis] for p in points]
    if xs and all(type(x) is int for x in xs) and ax.get_xscale() == "linear":
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))


def _log_if_wide(ax, axis: str, points: list[dict], name: str) -> None:
    xs = [p["params"][axis] for p in points if isinstance(p["params"][axis], int | float)]
    if xs and min(xs) > 0 and max(xs) / min(xs) >= 100:
        ax.set_xscale("log")
    ys = [_num(p["metrics"][name]["value"]) for p in points if name in p["metrics"]]
    ys = [y for y in ys if np.isfinite(y)]
    if ys and min(ys) > 0 and max(ys) / min(ys) >= 1000:
        ax.set_yscale("log")


#: The status of a point as a number on the status map (``measured``: no requirement to decide).
STATUS_CODE = {"invalid": -1, "fail": 0, "undecided": 1, "measured": 1, "pass": 2}
#: Facets of the status map per row.
FACETS_PER_ROW = 4


def _heat_map(summary: dict, budget: list[str], folder: Path):
    """The status map (:func:`status_figure`), saved."""
    fig = status_figure(summary, budget)
    facets = f", one panel per {budget[2]}" if len(budget) > 2 else ""
    rest = " (best over the axes beyond the third)" if len(summary["axes"]) > 3 else ""
    return _save(fig, folder, "status_map.png",
                 f"Status over {budget[0]} and {budget[1]}{facets}{rest}; blank: no point "
                 "run there", tight=False)


def status_figure(summary: dict, budget: list[str]):
    """Status over the first two budget axes, one facet per value of the third; with more axes
    (or given ones), the best status over them: green where some setting of them meets the
    requirement."""
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap

    facet = budget[2] if len(budget) > 2 else None
    values = sorted({p["params"][facet] for p in summary["points"]}) if facet else [None]
    xs = sorted({p["params"][budget[0]] for p in summary["points"]})
    ys = sorted({p["params"][budget[1]] for p in summary["points"]})
    cols = min(len(values), FACETS_PER_ROW)
    rows = -(-len(values) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(1.6 + 2.9 * cols, 0.8 + 3.0 * rows),
                             squeeze=False, sharex=True, sharey=True, layout="constrained")
    cmap = ListedColormap(["lightgrey", "tab:red", "gold", "tab:green"])
    rotate = max(len(str(x)) for x in xs) * len(xs) > 24
    for ax, value in zip(axes.flat, values, strict=False):
        grid = _status_grid(summary["points"], budget, xs, ys, facet, value)
        im = ax.imshow(grid, origin="lower", cmap=cmap, vmin=-1.5, vmax=2.5, aspect="auto")
        ax.set_xticks(range(len(xs)), [str(x) for x in xs], fontsize=7,
                      rotation=45 if rotate else 0, ha="right" if rotate else "center")
        ax.set_yticks(range(len(ys)), [str(y) for y in ys], fontsize=7)
        if facet:
            ax.set_title(f"{facet} = {value}", fontsize=8)
    for i, ax in enumerate(axes.flat):
        if i >= len(values):
            fig.delaxes(ax)
        elif i + cols >= len(values):  # no facet below it: its own x labels
            ax.xaxis.set_tick_params(labelbottom=True)
    fig.supxlabel(budget[0], fontsize=9)
    fig.supylabel(budget[1], fontsize=9)
    fig.suptitle(("QUICK LOOK: " if summary.get("quick") else "") + "Status of each point"
                 + (" (best over the other axes)" if len(summary["axes"]) > len(budget[:3])
                    else ""), fontsize=10)
    bar = fig.colorbar(im, ax=axes.flat[:len(values)], ticks=[-1, 0, 1, 2], shrink=0.9)
    middle = "undecided" if summary["requirement"] else "measured"
    bar.ax.set_yticklabels(["invalid", "fail", middle, "pass"], fontsize=8)
    return fig


def _status_grid(points: list[dict], budget: list[str], xs: list, ys: list,
                 facet: str | None, value) -> np.ndarray:
    """The best status in each (x, y) cell among the points at ``facet = value``."""
    grid = np.full((len(ys), len(xs)), np.nan)
    for p in points:
        if p["status"] in STATUS_CODE and (facet is None or p["params"][facet] == value):
            cell = (ys.index(p["params"][budget[1]]), xs.index(p["params"][budget[0]]))
            grid[cell] = np.fmax(grid[cell], STATUS_CODE[p["status"]])
    return grid


def _num(v) -> float:
    return {"inf": np.inf, "-inf": -np.inf, None: np.nan}.get(v, v) if not isinstance(
        v, int | float) else float(v)


def report_markdown(summary: dict[str, Any], plots: list[tuple[str, str]]) -> str:
    """The answer, the statistics used, a table of every point, and the plots."""
    quick = " (quick look)" if summary.get("quick") else ""
    lines = [f"# Study {summary['study']}{quick}", "", summary.get("description", ""), ""]
    if summary.get("asked"):
        lines += [f"Asked as: `{summary['asked']}` (the whole study, as run: `study.toml`).", ""]
    lines += ["## Answer" + (", one per condition" if len(summary["answer"]) > 1 else ""), ""]
    lines += [f"- {line}" for line in answer_lines(summary)]
    if "sensitivity" in summary:
        lines += [""] + sensitivity_markdown(summary)
    lines += ["", f"Requirement: {' and '.join(summary['requirement']) or '(none)'} at "
              f"{summary['confidence']:.0%} confidence (one-sided bounds). Search: "
              f"{summary['search']}. Replicates per point: {summary['replicates']} "
              f"({'every replicate another chip' if summary['vary_chip'] else 'one chip'}).", ""]
    lines += ["Statistics: " + "; ".join(f"{k}: {v}" for k, v in summary["statistics"].items()
                                         if v), ""]
    r = summary["runs"]
    lines += [f"Runs: {r['total']} stored ({r['ok']} ok, {r['invalid']} invalid, {r['error']} "
              f"error); {r.get('computed', 0)} computed in {summary['wall_time_s']:.1f} s on "
              f"{summary['executor']['kind']} × {summary['executor']['workers']}.", ""]
    if "stop_early" in summary:
        lines += [stop_early_line(summary["stop_early"]), ""]
    lines += ["## Points", "", "The requirement a point fails comes first (– where it fails "
              "none).", "", "| fails | point | status | n | " + " | ".join(_metric_cols(summary))
              + " |", "|---|---|---|---|" + "---|" * len(_metric_cols(summary))]
    for p in summary["points"]:
        label = ", ".join(f"{k}={v}" for k, v in p["params"].items())
        cells = [_cell(p["metrics"].get(m)) for m in _metric_cols(summary)]
        lines.append(f"| {failing(p)} | {label} | {p['status']} | {p['replicates']} | "
                     + " | ".join(cells) + " |")
    bad = [p for p in summary["points"] if p["message"]]
    if bad:
        lines += ["", "## Invalid or failed points", ""]
        lines += [f"- {', '.join(f'{k}={v}' for k, v in p['params'].items())}: {p['message']}"
                  for p in bad]
    lines += ["", "## Plots", ""]
    lines += [f"![{cap}]({name})\n\n*{cap}*\n" for name, cap in plots]
    return "\n".join(lines) + "\n"


def stop_early_line(se: dict[str, Any]) -> str:
    """The runs a grid that stops early saved, and where its points stopped."""
    looks = se["looks"]
    stops = ", ".join(f"{k['points_stopped']} at {k['replicates']}" for k in looks
                      if k["points_stopped"])
    return (f"Stopped early: {se['runs']} runs of the whole grid's {se['runs_whole_grid']} "
            f"({se['runs_saved']} saved, {se['runs_saved'] / se['runs_whole_grid']:.0%}); "
            f"points stopped (count at replicates): {stops}; {len(looks)} looks of "
            f"{se['batch']}, interim at {100 * looks[0]['confidence']:.4g} %, the last at "
            f"{100 * looks[-1]['confidence']:.4g} %.")


def failing(point: dict) -> str:
    """The requirements a point fails (``frames_dropped <= 0``), or ``–``."""
    failed = [q for q, d in point.get("decisions", {}).items() if d == "fail"]
    return "; ".join(failed) or "–"


def _metric_cols(summary: dict) -> list[str]:
    """Every metric of the points, those a requirement names first."""
    required = [q.split()[0] for q in summary["requirement"]]
    shown = dict.fromkeys(m for p in summary["points"] for m in p["metrics"])
    return [m for m in required if m in shown] + [m for m in shown if m not in required]


def _cell(e: dict | None) -> str:
    if e is None:
        return "–"
    if "k" in e:
        if e["k"] == 0:
            return f"0/{e['trials']} (< {e['upper']:.2g})"
        return f"{e['k']}/{e['trials']} [{e['lo']:.2g}, {e['hi']:.2g}]"
    lo, hi = _num(e.get("lo")), _num(e.get("hi"))
    return f"{_num(e['value']):.4g} [{lo:.4g}, {hi:.4g}]"
