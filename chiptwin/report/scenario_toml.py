"""A resolved scenario written back as TOML: every key at the value the run used.

The text goes into a run's dataset (``run.nc``, attribute ``scenario_toml``): loaded with
:func:`chiptwin.load_scenario` it gives the same :class:`~chiptwin.config.Scenario` (every bundled
scenario is checked, ``tests/report/test_dataset.py``), so a dataset says exactly what made it,
``--set`` overrides, the seed and the levels ``auto`` picked included. Defaults are written out
too: the text does not depend on what a later version's defaults are.

Left out: ``[assay]`` keys another assay kind uses (the loader refuses them), a drawn template
(``template_length`` > 0 draws it again from ``template_seed``, bit for bit) and keys whose value
is ``None`` (TOML has no null: an error budget's figures not budgeted).
"""

from __future__ import annotations

import dataclasses
import json
import math
from typing import Any

from chiptwin.config import Scenario
from chiptwin.config.schema import ASSAY_COMMON_KEYS, ASSAY_KIND_KEYS


def scenario_toml(s: Scenario) -> str:
    """``s`` as the text of a scenario file, one ``[section]`` per table, in the schema's order."""
    lines = []
    for name, keys in _tables(s, ""):
        lines += [f"[{name}]", *(f"{k} = {toml_value(v)}" for k, v in keys), ""]
    return "\n".join(lines)


def _tables(obj: Any, prefix: str) -> list[tuple[str, list[tuple[str, Any]]]]:
    """``(section, its keys and values)`` for ``obj`` and its sub-sections, parents first."""
    keys, subs = [], []
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        if f.name == "source" or value is None or not _written(obj, prefix, f.name):
            continue
        if dataclasses.is_dataclass(value):
            subs.append((f"{prefix}.{f.name}" if prefix else f.name, value))
        else:
            keys.append((f.name, value))
    out = [(prefix, keys)] if prefix else []
    for name, sub in subs:
        out += _tables(sub, name)
    return out


def _written(obj: Any, prefix: str, key: str) -> bool:
    """Whether ``[prefix] key`` goes in the text (the assay's kind keys and template rule)."""
    if prefix != "assay":
        return True
    if key not in ASSAY_KIND_KEYS[obj.kind] | ASSAY_COMMON_KEYS:
        return False
    return not (key == "template" and getattr(obj, "template_length", 0))


def toml_value(v: Any) -> str:
    """A TOML value: booleans, integers, floats (``repr``: exact), strings, arrays, inline
    tables."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        return repr(v) if math.isfinite(v) else ("inf" if v > 0 else "-inf")
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)  # a TOML basic string
    if isinstance(v, list | tuple):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_key(k)} = {toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(f"no TOML value for {type(v).__name__} {v!r}")


def _key(k: str) -> str:
    """A bare TOML key, or a quoted one."""
    return k if k and all(c.isalnum() or c in "_-" for c in k) and k.isascii() else json.dumps(k)
