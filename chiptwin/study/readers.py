"""The study file's field readers: every ``[study]`` value read, checked and refused the same way.

Shared by :mod:`chiptwin.study.spec` (budget and sensitivity studies) and
:mod:`chiptwin.study.calibrate_spec` (``kind = "calibrate"``): each error is a
:class:`~chiptwin.config.ScenarioError` naming the study file, the key, the value and what is
allowed, raised before anything runs or is written.
"""

from __future__ import annotations

import dataclasses
import difflib
import json
import math
import re
import typing
from pathlib import Path
from typing import Any

from chiptwin.config import Scenario, ScenarioError
from chiptwin.config.fields import allowed_text, check_value
from chiptwin.config.load import apply_override, type_hints
from chiptwin.config.schema import ASSAY_COMMON_KEYS, ASSAY_KIND_KEYS


def pin_datasheet(base_raw: dict[str, Any], scenario_path: Path) -> str:
    """A base scenario configured from an EMVA 1288 datasheet: the file is pinned by its
    absolute path (points carry another source name) and its text returned, so a changed
    datasheet changes the study's identity and is refused for resumption like a changed file."""
    pixel = base_raw.get("chip", {}).get("pixel", {})
    if not isinstance(pixel, dict) or "from_datasheet" not in pixel:
        return ""
    from chiptwin.config.datasheet import resolve_path

    path = resolve_path(pixel["from_datasheet"], str(scenario_path)).resolve()
    pixel["from_datasheet"] = str(path)
    return path.read_text(encoding="utf-8")


def put_key(raw: dict[str, Any], key: str, value: Any, source: str) -> None:
    apply_override(raw, f"{key}={json.dumps(value)}", source)


class Errors:
    """Reads fields of ``[study]`` and raises ScenarioError naming this file."""

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, key: str, value: Any, allowed: str) -> typing.NoReturn:
        raise ScenarioError(self.source, key, value, allowed)

    def string(self, t: dict, key: str, pattern: str, allowed: str) -> str:
        v = t.get(key, dataclasses.MISSING)
        if not isinstance(v, str) or not re.fullmatch(pattern, v) or v in (".", ".."):
            self.fail(f"study.{key}", v, f"must be {allowed}")
        return v

    def text(self, t: dict, key: str) -> str:
        v = t.get(key, "")
        if not isinstance(v, str):
            self.fail(f"study.{key}", v, "must be text (a string)")
        return v

    def integer(self, t: dict, key: str, lo: int, hi: int, why: str, default=None) -> int:
        v = t.get(key, dataclasses.MISSING if default is None else default)
        if type(v) is not int or not lo <= v <= hi:
            self.fail(f"study.{key}", v, f"must be an integer in [{lo}, {hi}] ({why})")
        return v

    def boolean(self, t: dict, key: str, default: bool) -> bool:
        v = t.get(key, default)
        if not isinstance(v, bool):
            self.fail(f"study.{key}", v, "must be true or false")
        return v

    def choice(self, t: dict, key: str, choices: tuple, default: str) -> str:
        v = t.get(key, default)
        if v not in choices:
            self.fail(f"study.{key}", v, "must be one of " + ", ".join(map(repr, choices)))
        return v


def unknown(key: str, allowed: set[str]) -> str:
    close = difflib.get_close_matches(key, sorted(allowed), n=1, cutoff=0.6)
    hint = f"did you mean {close[0]!r}? " if close else ""
    return f"unknown key; {hint}allowed: {', '.join(sorted(allowed))}"


def inline_table(err: Errors, st: dict, key: str) -> dict[str, Any]:
    """An inline table of scenario keys; ``{ chip.adc.bits = 20 }`` (nested by TOML) and
    ``{ "chip.adc.bits" = 20 }`` (one dotted key) read the same."""
    v = st.get(key, {})
    if not isinstance(v, dict):
        err.fail(f"study.{key}", v, 'must be an inline table of "section.key" = value')
    flat: dict[str, Any] = {}

    def walk(t: dict, prefix: str) -> None:
        for k, x in t.items():
            if isinstance(x, dict):
                walk(x, f"{prefix}{k}.")
            else:
                flat[prefix + k] = x

    walk(v, "")
    return flat


def table_list(err: Errors, st: dict, key: str) -> list[dict]:
    v = st.get(key, [])
    if not isinstance(v, list) or not all(isinstance(x, dict) for x in v):
        err.fail(f"study.{key}", v, f"must be [[study.{key}]] tables")
    return v


def scenario_path_of(err: Errors, st: dict, folder: Path, resolve) -> Path:
    v = st.get("scenario", dataclasses.MISSING)
    if not isinstance(v, str) or not v:
        err.fail("study.scenario", v, "must be a bundled scenario name or a path to a TOML file")
    for candidate in (folder / v, Path(v)):
        if candidate.is_file():
            return candidate
    found = resolve(v) if resolve else None
    if found is not None and Path(found).is_file():
        return Path(found)
    err.fail("study.scenario", v, f"no such file (looked in {folder} and the working folder) "
             "and no bundled scenario of that name; `chiptwin list` shows them")


def check_key(err: Errors, where: str, key: str, base_raw: dict) -> dataclasses.Field:
    """``key`` must name a scenario field (``chip.adc.bits``), and an assay key of the base
    scenario's kind; returns the field (its metadata is the key's rule)."""
    cls: Any = Scenario
    parts = key.split(".")
    for i, part in enumerate(parts):
        hints = type_hints(cls) if dataclasses.is_dataclass(cls) else {}
        fields = {f.name: f for f in dataclasses.fields(cls) if f.name != "source"} \
            if hints else {}
        if part not in fields:
            prefix = ".".join(parts[:i]) or "(top)"
            err.fail(where, key, f"{part!r} is not a key of {prefix}; " +
                     unknown(part, set(fields)))
        cls, found = hints[part], fields[part]
    if dataclasses.is_dataclass(cls):
        err.fail(where, key, "names a section; name one of its keys")
    if parts[0] == "assay" and len(parts) == 2:
        kind = base_raw.get("assay", {}).get("kind")
        allowed = ASSAY_KIND_KEYS.get(kind, frozenset()) | ASSAY_COMMON_KEYS
        if parts[1] not in allowed:
            err.fail(where, key, f"not used by the scenario's assay kind {kind!r}; its keys: "
                     + ", ".join(sorted(allowed)))
    return found


def keyed_table(err: Errors, where: str, table: dict, allowed: set[str], example: str,
                 base_raw: dict) -> tuple[str, dataclasses.Field]:
    """A ``[[study.axis]]`` or ``[[study.assumption]]`` table's own keys checked against
    ``allowed``, and its ``key``: a scenario key (:func:`check_key`). Returns it and its rule."""
    for k in table:
        if k not in allowed:
            err.fail(f"{where}.{k}", table[k], unknown(k, allowed))
    key = table.get("key", dataclasses.MISSING)
    if not isinstance(key, str):
        err.fail(f"{where}.key", key, f'must be a scenario key, e.g. "{example}"')
    return key, check_key(err, f"{where}.key", key, base_raw)


def numeric_range(err: Errors, where: str, t: dict, allowed: set[str], base_raw: dict,
                  taken: dict[str, str], what: str) -> tuple[str, dataclasses.Field, list]:
    """A table that names a numeric scenario key and a range of it (a fitted key, an
    assumption): the key (a number or an integer, not a choice or a switch; not ``taken``) and
    ``[lo, hi]``, finite, low end first. Returns the key, its rule and the range; ``what`` says
    in the refusal what the table is for."""
    key, rule = keyed_table(err, where, t, allowed, "chip.pixel.read_noise_e", base_raw)
    if rule.metadata.get("choices") or rule.metadata.get("kind") not in (float, int):
        err.fail(f"{where}.key", key, f"is not a number ({allowed_text(rule)}); {what}")
    if key in taken:
        err.fail(f"{where}.key", key, taken[key])
    r = t.get("range", dataclasses.MISSING)
    if not finite_pair(r):
        err.fail(f"{where}.range", r, f"{key}: must be [lo, hi], two finite numbers")
    if r[0] >= r[1]:
        err.fail(f"{where}.range", r, f"{key}: lo must be below hi (the low end first)")
    return key, rule, r


def finite_pair(r: Any) -> bool:
    """``[lo, hi]``: a list of two finite numbers (not booleans)."""
    return isinstance(r, list) and len(r) == 2 and all(
        isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x) for x in r)


def in_rule(err: Errors, where: str, r: list, rule: dataclasses.Field, key: str, x):
    """One end of a range checked by the key's own rule (the scenario schema's)."""
    try:
        return check_value(rule, x, where, key)
    except ScenarioError:
        err.fail(where, r, f"{key} = {x!r} is outside the key's own range: {allowed_text(rule)}")


#: Keys of a ``[study]`` table that say where a file is or how the study was asked, not what
#: the rows are: the scenario's content and the measured data's hash are in the identity instead,
#: and the same overrides typed in another order are the same study (:func:`identity_table`).
WHERE_KEYS = (("scenario",), ("target", "path"), ("asked",))


def identity_table(table: dict[str, Any]) -> dict[str, Any]:
    """The ``[study]`` table without :data:`WHERE_KEYS`: a study written elsewhere (its
    ``study.toml`` beside the results, the scenario by its absolute path) is the same study."""
    out = json.loads(json.dumps(table, default=str))
    for path in WHERE_KEYS:
        t = out
        for k in path[:-1]:
            t = t.get(k) if isinstance(t, dict) else None
        if isinstance(t, dict):
            t.pop(path[-1], None)
    return out
