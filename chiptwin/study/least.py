"""Each budget answer as the least value that meets the requirement, not as a grid point.

A grid (or a bisection over listed values) answers with the cheapest value it tried that passes;
the need lies between it and the dearest value below it that does not pass
(:func:`chiptwin.study.search.least_value`). The frame memory is the one budget whose need is known
exactly: the block of frames the schedule waits for plus what the DSP holds, the figure
validation refuses any smaller memory with
(:func:`chiptwin.config.consistency_chip.memory_needed_bits`). It is stated as the answer only
after a run at that size, with the seed of the answer's first replicate, drops no frame and gives
every metric the answer's run gave, bit for bit (a memory that drops no frame changes no frame).
"""

from __future__ import annotations

import json
from typing import Any

from chiptwin.config import ScenarioError
from chiptwin.config.consistency_chip import memory_needed_bits
from chiptwin.study.readers import Errors, check_key
from chiptwin.study.rows import RowTask, chip_seed, run_row
from chiptwin.study.search import least_value
from chiptwin.study.spec import Study, point_scenario

#: The budget key whose least value the schedule fixes exactly.
MEMORY_KEY = "chip.memory.capacity_bits"
#: Metrics that name the memory itself, not what the chip made with it.
_OF_THE_MEMORY = ("memory_capacity_frames",)


def least_values(study: Study, summary: dict[str, Any], table: list[dict[str, Any]]) -> None:
    """Give each answer of ``summary`` (a budget or sensitivity study's) its ``least``: per
    budget axis, :func:`~chiptwin.study.search.least_value` along the line through the answer
    (the other axes at the answer's values); the frame memory's made exact where a run checks
    it (:func:`memory_need`)."""
    budget = [a for a in summary["axes"] if not a["given"]]
    for answer in summary["answer"]:
        if not answer.get("point"):
            continue
        least = {a["key"]: along(summary, answer["point"], a, _floor(study, a["key"]))
                 for a in budget}
        if least.get(MEMORY_KEY) and not least[MEMORY_KEY]["resolved"]:
            least[MEMORY_KEY] = memory_need(study, answer, table, least[MEMORY_KEY])
        answer["least"] = least


def along(summary: dict[str, Any], point: dict[str, Any], axis: dict[str, Any],
          floor: float | None = None) -> dict[str, Any] | None:
    """The least value of ``axis`` on the line through ``point``: each value's status from the
    points run (``not_visited`` where none ran)."""
    key, values = axis["key"], axis["values"]
    status = {}
    for p in summary["points"]:
        if all(p["params"].get(k) == v for k, v in point.items() if k != key):
            status[json_key(p["params"][key])] = p["status"]
    statuses = [status.get(json_key(v), "not_visited") for v in values]
    at = [json_key(v) for v in values].index(json_key(point[key]))
    return least_value(values, statuses, at, floor)


def json_key(v: Any) -> str:
    """A value as an axis and study.json both spell it (an int stays an int, 1.0 is 1.0)."""
    return repr(v)


def memory_need(study: Study, answer: dict[str, Any], table: list[dict[str, Any]],
                bracket: dict[str, Any]) -> dict[str, Any]:
    """The frame memory the answer's schedule needs, checked by a run at that size; the
    ``bracket`` (the grid's interval) where the need lies outside it or the run disagrees."""
    point, fps = answer["point"], _fixed_pattern_seed(study)
    try:
        need = memory_needed_bits(point_scenario(study, point, study.seed, fps))
        below, top = bracket["between"]
        if not (below is None or below < need) or need > top:
            return {**bracket, "text": bracket["text"] + f" (the schedule's need, {need:,} "
                    "bits, lies outside it)"}
        first = next(r for r in table if r["point"] == answer["id"] and r["replicate"] == 0)
        at_need = {**point, MEMORY_KEY: need}
        names = tuple(dict.fromkeys([*first["metrics"], "frames_dropped"]))
        check = run_row(RowTask("least", "check", 0, first["seed"], at_need, names,
                                point_scenario(study, at_need, study.seed, fps)))
    except (ScenarioError, StopIteration, TypeError):  # no stored run to compare: the grid's
        return bracket
    dropped = (check["metrics"] or {}).get("frames_dropped")
    same = check["status"] == "ok" and dropped == 0 and all(
        json.dumps(check["metrics"][k]) == json.dumps(v)  # NaN equal to NaN, as stored
        for k, v in first["metrics"].items() if k not in _OF_THE_MEMORY)
    if not same:
        return {**bracket, "text": bracket["text"] + f" (a run at the schedule's need, {need:,} "
                f"bits, differs from the answer's: status {check['status']}, frames dropped "
                f"{dropped})"}
    return {"least": need, "between": [need - 1, need], "resolved": True, "grid": bracket,
            "check": {"seed": first["seed"], "frames_dropped": dropped},
            "text": f"{need:,} bits: the block of frames the schedule waits for plus what the "
                    f"DSP holds (validation refuses less); a run at that size drops no frame "
                    f"and gives the answer's run bit for bit (seed {first['seed']}); the grid: "
                    + bracket["text"]}


def _floor(study: Study, key: str) -> float | None:
    """The least value the scenario key allows (closed lower bound of its rule), or None."""
    try:
        rule = check_key(Errors(study.source), "study.axis", key, study.base_raw).metadata
    except ScenarioError:
        return None
    return None if rule.get("lo_open") else rule.get("lo")


def _fixed_pattern_seed(study: Study) -> int | None:
    """The study's one chip (as its points ran), or None when every replicate is another."""
    if study.vary_chip:
        return None
    pinned = study.base_raw.get("chip", {}).get("fixed_pattern_seed", -1)
    return pinned if pinned >= 0 else chip_seed(study.seed)
