"""Sensitivity studies: which assumption moves a study's answer, and how far.

A study of ``kind = "sensitivity"`` lists assumptions (scenario keys whose true value is not
known, each with a plausible low and high end). The design is one-at-a-time around the
reference (Saltelli et al., *Global Sensitivity Analysis: The Primer*, Wiley 2008, §1.2.2 and
the tornado diagram of its chapter 1): the reference condition (every assumption at the base
scenario's own value), then each assumption at its low end and at its high end with the others
at their reference values, ``1 + 2k`` conditions for ``k`` assumptions (fewer when an end is
the reference value itself). Each condition is one combination of given (condition) axes, so
the study's own search (grid or bisection) answers it with its own confidence machinery.

The answer of each condition is the budget it needs (``None``: no budget on the axis meets the
requirement, "none met"). An assumption's *swing* is how far its three answers (low end,
reference, high end) spread: in the axis's own units for an integer axis (ADC bits: bits), as
the ratio of the largest to the smallest for a continuous one (a limit of detection: ×2), and in
steps along the axis for both. The verdict is ``robust`` when no assumption moves the answer by
more than the axis can resolve (:func:`tolerance_steps`), else ``decided by <key>``, the
assumption with the largest swing.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any

#: What the verdict tolerates, in words (study.json states it beside the verdict).
RULE = ("robust when no assumption moves the answer by more than the axis resolves: an integer "
        "axis (bits, frames) resolves every step, so the answer must be identical in every "
        "condition; a sampled continuous axis (a bisected amount) resolves only its step, so "
        "answers one step apart (a ratio within the bracket's resolution) count as the same; "
        "an answer no budget meets (none met) is off-scale, beyond the top of the axis")


@dataclass(frozen=True)
class Assumption:
    """One unpublished scenario value: its plausible range and the base scenario's value."""

    key: str
    lo: float
    hi: float
    reference: float
    why: str


def conditions(assumptions: tuple[Assumption, ...]) -> list[dict[str, float]]:
    """The one-at-a-time design: the reference first, then each assumption's low and high end
    with the others at their reference values; an end equal to the reference is the reference
    condition itself (not repeated)."""
    ref = {a.key: a.reference for a in assumptions}
    out = [ref]
    for a in assumptions:
        for end in (a.lo, a.hi):
            if end != a.reference:
                out.append({**ref, a.key: end})
    return out


def is_integer_axis(values: list) -> bool:
    """An axis of integers (bits, frames): its answer moves in the axis's own units."""
    return all(isinstance(v, int) and not isinstance(v, bool) for v in values)


def tolerance_steps(values: list) -> int:
    """Steps along the budget axis a robust answer may move: 0 on an integer axis (each step
    is a value the answer can take), 1 on a sampled continuous axis (the answer is the top of a
    bracket one step wide: answers one step apart may be the same true value)."""
    return 0 if is_integer_axis(values) else 1


def analyse(summary: dict[str, Any], assumptions: tuple[Assumption, ...]) -> dict[str, Any]:
    """study.json's ``sensitivity`` section from the answers of a finished study: per
    combination of the study's own given axes, every assumption's answers at its low end, the
    reference and its high end, ranked by swing, and the verdict."""
    budget = next(a for a in summary["axes"] if not a["given"])
    values, keys = list(budget["values"]), {a.key for a in assumptions}
    # conditions where a pass is followed by a failure along the budget axis: their answer is
    # above that failure (the study's answer rule), said beside it
    broken = {json.dumps({k: v for k, v in x["passes"].items() if k != budget["key"]},
                         sort_keys=True)
              for x in summary.get("monotonicity", {}).get("violations", [])
              if x["kind"] == "decision"}
    results: dict[str, dict[str, Any]] = {}
    for answer in summary["answer"]:
        own = {k: v for k, v in answer["given"].items() if k not in keys}
        at = {k: v for k, v in answer["given"].items() if k in keys}
        monotone = json.dumps(answer["given"], sort_keys=True) not in broken
        results.setdefault(repr(own), {"given": own, "by_condition": []})["by_condition"].append(
            (at, {**answer, "monotone": monotone}))
    sections = [_section(r["given"], r["by_condition"], assumptions, budget["key"], values,
                         summary["confidence"]) for r in results.values()]
    integer = is_integer_axis(values)
    return {
        "design": f"one at a time (Saltelli et al. 2008): the reference and each of the "
                  f"{len(assumptions)} assumptions at its low and high end, the others at "
                  "their reference values",
        "answer_axis": budget["key"],
        "measure": "difference in the axis's units" if integer else
                   "ratio of the largest to the smallest answer",
        "tolerance_steps": tolerance_steps(values),
        "rule": RULE,
        "assumptions": [{"key": a.key, "range": [a.lo, a.hi], "reference": a.reference,
                         "why": a.why} for a in assumptions],
        "results": sections,
        "verdict": "; ".join((_given_text(s["given"]) + s["verdict"]) for s in sections),
    }


def _same_swing(a: float | None, b: float | None) -> bool:
    """Two swings alike: both absent, or equal but for rounding: a geometric grid's ratios of
    different pairs of its points (0.316/0.0681 and 0.215/0.0464: ×4.6416 both) differ in the
    6th digit its values are stored to, far below its step (×1.47 for sensitivity_lod)."""
    return (a is None and b is None) or (a is not None and b is not None
                                         and math.isclose(a, b, rel_tol=1e-4))


def _given_text(given: dict[str, Any]) -> str:
    return "[" + ", ".join(f"{k} = {v}" for k, v in given.items()) + "] " if given else ""


def _section(given: dict, by_condition: list, assumptions: tuple[Assumption, ...], axis: str,
             values: list, confidence: float) -> dict[str, Any]:
    ref_at = {a.key: a.reference for a in assumptions}

    def answer_at(key: str, value: float) -> dict[str, Any]:
        want = {**ref_at, key: value}
        found = next(ans for at, ans in by_condition if at == want)
        return end_answer(found, axis, values, confidence)

    reference = end_answer(next(ans for at, ans in by_condition if at == ref_at), axis, values,
                           confidence)
    ranking = [_swing(a, answer_at(a.key, a.lo), reference, answer_at(a.key, a.hi), values)
               for a in assumptions]
    ranking.sort(key=lambda r: (-r["steps"], -(r["swing"] if r["swing"] is not None
                                                 else math.inf), r["key"]))
    ranking.sort(key=lambda r: not r["off_scale"])  # an end no budget meets ranks first
    top = ranking[0] if ranking else None
    tol = tolerance_steps(values)
    if top is None or (top["steps"] <= tol and not top["off_scale"]):
        verdict = (f"robust: no assumption moves {axis} beyond "
                   + ("the reference answer" if tol == 0 else "one step of the axis")
                   + f" (reference answer {reference['text']})")
    else:
        tied = [r["key"] for r in ranking[1:]  # the same swing: equal steps of the axis and
                if (r["off_scale"], r["steps"]) == (top["off_scale"], top["steps"])  # a ratio
                and _same_swing(r["swing"], top["swing"])]  # equal to float rounding
        verdict = (f"decided by {top['key']}: {top['low']['text']} at {top['range'][0]:g}, "
                   f"{top['high']['text']} at {top['range'][1]:g} (swing {top['swing_text']})"
                   + (f"; tied with {', '.join(tied)}" if tied else ""))
    return {"given": given, "reference": reference, "ranking": ranking, "verdict": verdict}


def end_answer(answer: dict[str, Any], axis: str, values: list, confidence: float
               ) -> dict[str, Any]:
    """One condition's answer: the budget value (None: none met), its index along the axis
    (``len(values)``: off the top), and a text with every requirement's bound, as the study
    states it."""
    point = answer.get("point")
    monotone = answer.get("monotone", True)
    note = "" if monotone else " (non-monotone: a failure below it)"
    if point is None:
        return {"value": None, "index": len(values), "off_scale": True, "monotone": monotone,
                "text": f"none met (> {values[-1]:g})" + note, "bounds": {}}
    v = point[axis]
    shown_v = f"{v:g}" if isinstance(v, int) else f"{v:.3g}"
    bounds = answer.get("bounds", {})
    shown = "; ".join(f"{q.split()[0]} {_seen(b)}, {confidence:.0%} bound {b['bound']:.3g}"
                      for q, b in bounds.items())
    return {"value": v, "index": values.index(v), "off_scale": False, "monotone": monotone,
            "text": shown_v + note, "bounds": bounds, "statement": f"{shown_v} ({shown}){note}"}


def _seen(b: dict) -> str:
    return f"{b['k']}/{b['trials']}" if "k" in b else f"{b['estimate']:.3g}"


def _swing(a: Assumption, low: dict, reference: dict, high: dict, values: list
           ) -> dict[str, Any]:
    """How far one assumption moves the answer (None: off-scale, an end none met)."""
    ends = [low, reference, high]
    idx = [e["index"] for e in ends]
    met = [e["value"] for e in ends if not e["off_scale"]]
    off = 0 < len(met) < 3  # some ends none met, not all: moved past the top of the axis
    integer = is_integer_axis(values)
    if not met:
        swing, text = (0 if integer else 1.0), "none met at any end"
    elif off:  # at least one step past the top: a lower bound
        swing = None
        text = (f"≥ {values[-1] + 1 - min(met):g}" if integer else
                f"> ×{values[-1] / min(met):.3g}") + " (an end none met: off-scale)"
    elif integer:
        swing = max(met) - min(met)
        text = f"{swing:g}"
    else:
        swing = max(met) / min(met) if min(met) > 0 else None
        text = f"×{swing:.3g}" if swing is not None else "undefined (an answer ≤ 0)"
    return {"key": a.key, "range": [a.lo, a.hi], "reference_value": a.reference, "why": a.why,
            "low": low, "reference": reference, "high": high, "swing": swing,
            "swing_text": text, "steps": max(idx) - min(idx), "off_scale": off}
