"""A calibration's outputs beside its database: ``results.csv`` (every evaluation),
``calibrated.toml``, ``convergence.png``, ``residuals.png``, ``report.md``, ``study.json``.

Written as a budget study's are (:mod:`chiptwin.study.outputs`): each file through a temporary
name and a rename, ``study.json`` (the mark of a finished study) last. ``calibrated.toml`` is the
study's scenario (its ``set`` applied) with the fitted values in place, each with its interval in
a comment; it is checked to load before it is written.
"""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path
from typing import Any

import numpy as np

from chiptwin.study.files import write_atomic
from chiptwin.study.toml_text import toml_key, toml_value
from chiptwin.twin.figures import save_figure

CALIBRATED = "calibrated.toml"


def write_calibrate_outputs(result: Any, out: Path) -> None:
    """Every output of a finished calibration into ``out`` (which holds its results.sqlite)."""
    summary = result.summary
    write_atomic(out / "results.csv", evaluations_csv(result))
    write_atomic(out / CALIBRATED, calibrated_toml(result.study, summary))
    plots = [convergence_plot(summary, out), residuals_plot(summary, out)]
    write_atomic(out / "report.md", report_markdown(summary, plots))
    write_atomic(out / "study.json", json.dumps(summary, indent=1, default=str) + "\n")


def evaluations_csv(result: Any) -> str:
    """One line per candidate, in the order the fit first asked for it."""
    from chiptwin.study.calibrate import table_rows

    keys = result.study.calibration.keys
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["n", "stage", "status", "objective", "wall_s", *keys])
    w.writerows(table_rows(result.table, keys))
    return buf.getvalue()


def answer_lines(summary: dict[str, Any]) -> list[str]:
    """What the CLI prints: the fitted values, the fit's quality, the inseparable pairs."""
    lines = []
    for p in summary["parameters"]:
        lo, hi = p["interval"]
        ends = [f"{v:.4g}" + (" (open)" if o else "") for v, o in zip((lo, hi), p["open"],
                                                                      strict=True)]
        lines.append(f"{p['key']} = {p['value']:.5g} [{ends[0]}, {ends[1]}] "
                     f"(scenario: {p['scenario_value']:.5g})")
    o = summary["objective"]
    quality = f"χ² = {o['chi2_unscaled']:.4g} for {o['dof']} degrees of freedom"
    if o.get("p_value") is not None:
        quality += f" (p = {o['p_value']:.2g})"
    scaled = [b["name"] for b in o["blocks"] if b["scale"] != 1.0]
    if scaled and o["kind"] == "chi2":
        quality += "; errors scaled by their Birge ratio: " + ", ".join(
            f"{b['name']} ×{b['scale']:.3g}" for b in o["blocks"] if b["scale"] != 1.0)
    lines.append(f"{summary['confidence']:.0%} profile-likelihood intervals; {quality}")
    lines += [f"WARNING: {w}" for w in summary.get("warnings", [])]
    lines += [f"CORRELATED: {p['statement']}" for p in summary["correlation"]["inseparable"]]
    lines += [f"note: {n}" for n in summary["fit"]["notes"]]
    return lines


# ---------------------------------------------------------------- calibrated.toml


def _tables(raw: dict[str, Any], prefix: str = ""):
    """(section, its non-table keys), parents before their sub-tables."""
    scalars = {k: v for k, v in raw.items() if not isinstance(v, dict)}
    if prefix and scalars:
        yield prefix, scalars
    for k, v in raw.items():
        if isinstance(v, dict):
            yield from _tables(v, f"{prefix}.{toml_key(k)}" if prefix else toml_key(k))


def calibrated_toml(study: Any, summary: dict[str, Any]) -> str:
    """The study's scenario with the fitted values set, each with its interval beside it."""
    from chiptwin.config.load import scenario_from_dict
    from chiptwin.study.readers import put_key

    raw = json.loads(json.dumps(study.base_raw))
    comments = {}
    for p in summary["parameters"]:
        put_key(raw, p["key"], p["value"], study.source)
        lo, hi = p["interval"]
        ends = [f"{v:.6g}" + (" (open: the range's end)" if o else "")
                for v, o in zip((lo, hi), p["open"], strict=True)]
        comments[p["key"]] = (f"fitted: {summary['confidence']:.0%} interval [{ends[0]}, "
                              f"{ends[1]}], was {p['scenario_value']:.6g}")
    scenario_from_dict(json.loads(json.dumps(raw)), CALIBRATED)  # what is written loads
    o = summary["objective"]
    lines = [f"# {Path(study.scenario_path).name} calibrated by the study {study.name} "
             f"({Path(study.source).name}),",
             f"# fitted to {summary['target']['description']};",
             f"# χ² = {o['chi2_unscaled']:.5g} for {o['dof']} degrees of freedom. Fitted keys "
             "carry their profile-likelihood interval;",
             "# the rest is the study's scenario with its `set` applied.", ""]
    for section, table in _tables(raw):
        lines.append(f"[{section}]")
        for leaf, value in table.items():
            key = f"{section}.{leaf}".replace('"', "")
            note = f"  # {comments[key]}" if key in comments else ""
            lines.append(f"{toml_key(leaf)} = {toml_value(value)}{note}")
        lines.append("")
    return "\n".join(lines)


# ---------------------------------------------------------------- plots


def convergence_plot(summary: dict[str, Any], folder: Path) -> tuple[str, str]:
    """The best χ² (unscaled) against the evaluations, in the order the fit asked for them."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    curve = np.array(summary["convergence"], dtype=float).reshape(-1, 2)
    fig, ax = plt.subplots(figsize=(6.5, 3.4))
    if curve.size:
        n_last = summary["evaluations"]["total"]
        x = np.append(curve[:, 0], n_last)
        y = np.append(curve[:, 1], curve[-1, 1])
        ax.step(x, y, where="post", color="tab:blue")
        if curve[:, 1].min() > 0 and curve[:, 1].max() / curve[:, 1].min() > 30:
            ax.set_yscale("log")
    for stage, first, _ in summary["evaluations"]["stages"]:
        if stage == "reference":
            continue
        ax.axvline(first, color="grey", lw=0.6, ls=":")
        ax.text(first, 0.98, f" {stage}", transform=ax.get_xaxis_transform(), fontsize=7,
                va="top", rotation=90)
    ax.set(xlabel="evaluations (distinct candidates, in the order asked for)",
           ylabel="best χ² so far (unscaled)")
    ax.set_title(f"Convergence: {summary['evaluations']['total']} evaluations", fontsize=9)
    return save_figure(fig, folder, "convergence.png", "The best objective so far against the "
                       "evaluations; dotted lines: where a stage (evolution, polish, profile) "
                       "began asking for candidates")


def residuals_plot(summary: dict[str, Any], folder: Path) -> tuple[str, str]:
    """Per statistic: measured and fitted against x, and the residuals in units of σ."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    r = summary["residuals"]
    block = np.asarray(r["block"])
    names = r["blocks"]
    fig, axes = plt.subplots(len(names), 2, figsize=(9.0, 2.3 * len(names) + 0.6),
                             squeeze=False)
    for b, name in enumerate(names):
        sel = block == b
        x = np.asarray(r["x"])[sel]
        order = np.argsort(x)
        x = x[order]
        meas, se = (np.asarray(r[k])[sel][order] for k in ("measured", "se"))
        fitted, z = (np.asarray(r[k])[sel][order] for k in ("fitted", "normalised"))
        left, right = axes[b]
        left.errorbar(x, meas, yerr=se if r["weighted"] else None, fmt="o", ms=3,
                      label="measured")
        left.plot(x, fitted, "-" if x.size > 1 else "s", color="tab:red", mfc="none",
                  label="fitted twin")  # a one-value statistic (K, R) as a marker
        left.set(ylabel=name, xlabel=r["x_label"])
        left.legend(fontsize=7)
        right.axhline(0, color="k", lw=0.6)
        for k in (-2, 2):
            right.axhline(k, color="grey", lw=0.6, ls="--")
        right.plot(x, z, "o", ms=3)
        right.set(ylabel="residual / σ", xlabel=r["x_label"])
    fig.suptitle("Measured against the fitted twin", fontsize=10)
    return save_figure(fig, folder, "residuals.png", "Left: each statistic measured (with its "
                       "standard error) and the fitted twin; right: the residuals in units of "
                       "their σ (measured and simulated standard errors, scaled by the "
                       "statistic's Birge ratio where it is > 1)")


# ---------------------------------------------------------------- report.md


def report_markdown(summary: dict[str, Any], plots: list[tuple[str, str]]) -> str:
    """The fitted values, the fit's quality, correlations, methods and the plots."""
    lines = [f"# Calibration {summary['study']}", "", summary.get("description", ""), "",
             "## Fitted values", ""]
    lines += [f"- {line}" for line in answer_lines(summary)]
    lines += ["", f"Target: {summary['target']['description']}.", "",
              "| key | fitted | interval | scenario's value | range | why |",
              "|---|---|---|---|---|---|"]
    for p in summary["parameters"]:
        lo, hi = p["interval"]
        ends = [f"{v:.4g}" + (" (open)" if o else "") for v, o in zip((lo, hi), p["open"],
                                                                      strict=True)]
        lines.append(f"| {p['key']} | {p['value']:.5g} | [{ends[0]}, {ends[1]}] | "
                     f"{p['scenario_value']:.5g} | [{p['range'][0]:g}, {p['range'][1]:g}] "
                     f"({p['scale']}) | {p['why']} |")
    lines += ["", "## How well the data fit", "", _blocks_table(summary["objective"]), ""]
    lines += ["## Correlations at the optimum", "", _correlation_table(summary["correlation"]),
              ""]
    lines += [f"- {p['statement']}" for p in summary["correlation"]["inseparable"]] or \
        [f"No pair with |ρ| > {summary['correlation']['threshold']}: the data separate every "
         "pair of keys."]
    lines += ["", "## Methods", ""]
    lines += [f"- **{k}**: {v}" for k, v in summary["methods"].items()]
    ev = summary["evaluations"]
    lines += ["", f"Evaluations: {ev['total']} ({ev['computed']} computed, {ev['resumed']} "
              f"from the store; {ev['invalid']} invalid, {ev['error']} failed); by stage: "
              + ", ".join(f"{k} {v}" for k, v in ev["by_stage"].items())
              + f"; {summary['wall_time_s']:.1f} s on {summary['executor']['kind']} × "
              f"{summary['executor']['workers']}.", "", "## Plots", ""]
    lines += [f"![{cap}]({name})\n\n*{cap}*\n" for name, cap in plots]
    return "\n".join(lines) + "\n"


def _blocks_table(o: dict[str, Any]) -> str:
    rows = ["| statistic | values | χ² | Birge ratio used |", "|---|---|---|---|"]
    rows += [f"| {b['name']} | {b['n']} | {b['chi2']:.4g} | {b['scale']:.3g} |"
             for b in o["blocks"]]
    tail = f"\n\nχ² = {o['chi2_unscaled']:.5g} for {o['dof']} degrees of freedom"
    if o.get("p_value") is not None:
        tail += f" (p = {o['p_value']:.3g})"
    if "offset" in o:
        tail += f"; fitted offset of the means (the camera's black level against the twin's): " \
                f"{o['offset']:.4g}"
    return "\n".join(rows) + tail + "."


def _correlation_table(c: dict[str, Any]) -> str:
    keys = c["keys"]
    short = [k.rsplit(".", 1)[-1] for k in keys]
    rows = ["| | " + " | ".join(short) + " |", "|---|" + "---|" * len(keys)]
    for name, row in zip(short, c["matrix"], strict=True):
        rows.append(f"| {name} | " + " | ".join("–" if v is None else f"{v:+.3f}" for v in row)
                    + " |")
    return "\n".join(rows)
