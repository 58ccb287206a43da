"""The assumptions of a study of ``kind = "sensitivity"``: each ``[[study.assumption]]`` table
parsed and checked against the scenario's own value and the key's schema range (the study file's
other keys: :mod:`chiptwin.study.spec`)."""

from __future__ import annotations

import dataclasses
import json
from typing import Any

from chiptwin.config import Scenario
from chiptwin.config.load import scenario_from_dict
from chiptwin.study.readers import Errors, in_rule, numeric_range, table_list
from chiptwin.study.sensitivity import Assumption

#: Every key of a ``[[study.assumption]]`` table (see :data:`chiptwin.study.spec.STUDY_KEYS`).
ASSUMPTION_KEYS: dict[str, str] = {
    "key": "required; a numeric scenario key not on an axis, e.g. \"chip.pixel.read_noise_e\" "
           "(in study.reference too: the ideal point keeps the reference's value in every "
           "condition)",
    "range": "required; [lo, hi], lo < hi, both inside the key's own range in the scenario "
             "schema, with the base scenario's value inside [lo, hi] (the tornado's bars run "
             "through it)",
    "why": "required; text: why the value is not known and where the two ends come from",
}
_ASSUMPTION_KEYS = set(ASSUMPTION_KEYS)


def assumptions_of(err: Errors, st: dict, kind: str, axes: tuple[Any, ...], base_raw: dict,
                 scenario_path: str) -> tuple[Assumption, ...]:
    """The ``[[study.assumption]]`` tables, each checked against its key's own rule and the base
    scenario's value (:class:`~chiptwin.study.sensitivity.Assumption`). A key also in
    ``study.reference`` keeps that value in every condition's ideal point: the ideal does not
    move with the assumption (an ideal converter has no INL whatever the chip's is)."""
    tables = table_list(err, st, "assumption")
    if kind != "sensitivity":
        if tables:
            err.fail("study.assumption", [t.get("key") for t in tables],
                     'only a study of kind = "sensitivity" takes assumptions')
        return ()
    if not tables:
        err.fail("study.assumption", dataclasses.MISSING,
                 "a sensitivity study needs at least one [[study.assumption]]")
    base = scenario_from_dict(json.loads(json.dumps(base_raw)), scenario_path)
    out: list[Assumption] = []
    for i, t in enumerate(tables):
        taken = {a.key: "is on a [[study.axis]]: the study varies it already" for a in axes}
        taken.update({a.key: "is listed twice" for a in out})
        out.append(_assumption(err, f"study.assumption[{i}]", t, base_raw, base, taken))
    return tuple(out)


def _assumption(err: Errors, where: str, t: dict, base_raw: dict, base: Scenario,
                taken: dict[str, str]) -> Assumption:
    key, rule, r = numeric_range(err, where, t, _ASSUMPTION_KEYS, base_raw, taken,
                                 "an assumption spans a numeric range")
    lo, hi = (in_rule(err, f"{where}.range", r, rule, key, x) for x in r)
    ref = base
    for part in key.split("."):
        ref = getattr(ref, part)
    if not lo <= ref <= hi:
        err.fail(f"{where}.range", r, f"{key}: the base scenario's value {ref!r} is outside "
                 "[lo, hi]; the tornado needs the reference inside (widen the range to hold it)")
    why = t.get("why", dataclasses.MISSING)
    if not isinstance(why, str) or not why.strip():
        err.fail(f"{where}.why", why, f"{key}: say why the value is not known and where the "
                 "two ends come from (text)")
    return Assumption(key, lo, hi, ref, why.strip())
