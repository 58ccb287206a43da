"""A sensitivity study's outputs: the tornado chart and the table of report.md.

Reads only study.json's ``sensitivity`` section (:func:`chiptwin.study.sensitivity.analyse`).
One bar per assumption, from the answer at its low end to the answer at its high end, through
the reference answer (the dashed line), the widest swing on top (the tornado diagram of
Saltelli et al., *Global Sensitivity Analysis: The Primer*, Wiley 2008, ch. 1). An end where no
budget on the axis meets the requirement is drawn one step past the top of the axis, with a
triangle and "none met".
"""

from __future__ import annotations

import textwrap
from pathlib import Path
from typing import Any

from chiptwin.study.sensitivity import is_integer_axis
from chiptwin.twin.figures import save_figure

#: Colours of the two ends of a bar.
LOW_COLOUR, HIGH_COLOUR = "tab:blue", "tab:orange"


def tornado_plot(summary: dict[str, Any], folder: Path) -> tuple[str, str]:
    """``sensitivity.png`` in ``folder``; returns ``(name, caption)`` for the report."""
    fig = tornado_figure(summary)
    sens = summary["sensitivity"]
    return save_figure(fig, folder, "sensitivity.png",
                       f"Tornado: {sens['answer_axis']} (the answer) at each assumption's low end "
                       f"(blue) and high end (orange), the others at their reference values; "
                       "dashed: the reference answer; ranked by swing. A triangle past the "
                       "axis's top: no budget on the axis meets the requirement (off-scale).")


def tornado_figure(summary: dict[str, Any]):
    """The tornado chart, one panel per combination of the study's own given axes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sens = summary["sensitivity"]
    axis = next(a for a in summary["axes"] if not a["given"])
    values = list(axis["values"])
    sections = sens["results"]
    height = max(2.0, 0.55 * len(sens["assumptions"]) + 1.4)
    fig, axes = plt.subplots(len(sections), 1, figsize=(8.0, height * len(sections)),
                             squeeze=False)
    for ax, sec in zip(axes[:, 0], sections, strict=True):
        _panel(ax, sec, values, sens["answer_axis"])
    return fig


def _panel(ax, sec: dict[str, Any], values: list, axis_key: str) -> None:
    from matplotlib.patches import Patch

    ranking = sec["ranking"]
    log = not is_integer_axis(values) and min(values) > 0  # its swing is a ratio
    off = values[-1] * (values[-1] / values[-2]) if log and len(values) > 1 else \
        values[-1] + (values[-1] - values[-2] if len(values) > 1 else 1.0)

    def x(end: dict) -> float:
        return off if end["off_scale"] else float(end["value"])

    ref = x(sec["reference"])
    n = len(ranking)
    for i, r in enumerate(ranking):
        y = n - 1 - i  # the widest swing on top
        for end, colour in ((r["low"], LOW_COLOUR), (r["high"], HIGH_COLOUR)):
            xe = x(end)
            ax.barh(y, xe - ref, left=ref, height=0.6, color=colour, alpha=0.75)
            ax.plot(xe, y, ">" if end["off_scale"] else "|", color=colour, ms=10, mew=2)
            ax.annotate(end["text"], (xe, y), xytext=(4 if xe >= ref else -4, 7),
                        textcoords="offset points", fontsize=7,
                        ha="left" if xe >= ref else "right")
    ax.axvline(ref, color="k", ls="--", lw=1, label=f"reference: {sec['reference']['text']}")
    ax.axvline(values[-1], color="grey", ls=":", lw=1, label=f"top of the axis ({values[-1]:g})")
    ax.set_yticks(range(n), [f"{r['key']}\n[{r['range'][0]:g} … {r['range'][1]:g}]"
                             for r in reversed(ranking)], fontsize=7)
    if log:
        ax.set_xscale("log")
    lo = min([ref, *(x(e) for r in ranking for e in (r["low"], r["high"]))])
    hi = max([ref, *(x(e) for r in ranking for e in (r["low"], r["high"]))])
    pad = (hi / lo) ** 0.15 if log and lo > 0 else 0.12 * (hi - lo or 1.0)
    ax.set_xlim(*((lo / pad, hi * pad) if log and lo > 0 else (lo - pad, hi + pad)))
    ax.set_ylim(-0.7, n - 0.3)
    given = ", ".join(f"{k} = {v}" for k, v in sec["given"].items())
    ax.set_xlabel(axis_key + (f"   [{given}]" if given else ""))
    ax.set_title("\n".join(textwrap.wrap(sec["verdict"], 95)), fontsize=8)
    handles = [Patch(color=LOW_COLOUR, alpha=0.75, label="answer at the low end"),
               Patch(color=HIGH_COLOUR, alpha=0.75, label="answer at the high end"),
               *ax.get_legend_handles_labels()[0]]
    ax.legend(handles=handles, fontsize=7, loc="lower right")


def sensitivity_markdown(summary: dict[str, Any]) -> list[str]:
    """report.md's sensitivity section: the verdict, the rule, and one table row per
    assumption (range, why, the answer at low, reference and high with their bounds, swing)."""
    sens = summary["sensitivity"]
    lines = ["## Sensitivity", "", f"**Verdict:** {sens['verdict']}", "",
             f"Design: {sens['design']}. Swing: {sens['measure']} of {sens['answer_axis']} over "
             f"the low end, the reference and the high end. Rule: {sens['rule']} (tolerance "
             f"{sens['tolerance_steps']} step(s) of the axis).", ""]
    for sec in sens["results"]:
        if sec["given"]:
            lines += [f"### {', '.join(f'{k} = {v}' for k, v in sec['given'].items())}", "",
                      f"Verdict: {sec['verdict']}", ""]
        lines += ["| rank | assumption | range (reference) | why | answer at low | reference "
                  "| answer at high | swing |", "|---|---|---|---|---|---|---|---|"]
        for i, r in enumerate(sec["ranking"], 1):
            lines.append(f"| {i} | `{r['key']}` | {r['range'][0]:g} … {r['range'][1]:g} "
                         f"({r['reference_value']:g}) | {_cell(r['why'])} | "
                         f"{_answer(r['low'])} | {_answer(r['reference'])} | "
                         f"{_answer(r['high'])} | {r['swing_text']} ({r['steps']} step(s)) |")
        lines.append("")
    return lines


def _answer(end: dict[str, Any]) -> str:
    return _cell(end.get("statement", end["text"]))


def _cell(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")
