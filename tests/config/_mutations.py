"""Mutations of the bundled scenarios, one key at a time.

Shared by ``test_mutations.py`` and the one-off count script (``python -m
tests.config._mutations``, which runs every mutation and prints the counts by outcome). A mutation
is ``(scenario file, dotted key, value)``; :data:`MISSING` deletes the key. The mutated table is
written back as TOML (:func:`dumps`) and given to ``chiptwin.cli.main`` like any user file.
"""

from __future__ import annotations

import copy
import dataclasses
import json
import math
import tomllib
import typing
from pathlib import Path
from typing import Any

from chiptwin.config.schema import ASSAY_COMMON_KEYS, ASSAY_KIND_KEYS, Scenario

ROOT = Path(__file__).resolve().parents[2]
SCENARIO_FILES = sorted((ROOT / "scenarios").glob("*.toml"))

MISSING = object()
"""Delete the key instead of setting it."""

#: The values the issue lists: NaN, ±inf, −1, 0, 1e±300, 2^63, wrong types, a missing key.
GENERIC: tuple[Any, ...] = (
    math.nan, math.inf, -math.inf, -1, 0, 1e300, 1e-300, -1e300, 2**63, 2**63 - 1, 1e19,
    "x", True, [1], {}, MISSING,
)


def read(path: Path) -> dict[str, Any]:
    return tomllib.loads(path.read_text(encoding="utf-8"))


def _field_keys(cls: type, prefix: str, skip: frozenset = frozenset()) -> list[tuple[str, Any]]:
    """Dotted leaf keys of a schema dataclass with their fields, sections as ``(key, None)``."""
    out: list[tuple[str, Any]] = []
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        if f.name in skip:
            continue
        key = prefix + f.name
        if dataclasses.is_dataclass(hints[f.name]):
            out.append((key, None))
            out += _field_keys(hints[f.name], key + ".")
        else:
            out.append((key, f))
    return out


def keys_of(raw: dict[str, Any]) -> list[tuple[str, Any]]:
    """Every key a scenario of this assay kind may hold (present or not), with its field."""
    kind = raw["assay"]["kind"]
    allowed = ASSAY_KIND_KEYS[kind] | ASSAY_COMMON_KEYS
    return [(k, f) for k, f in _field_keys(Scenario, "", frozenset({"source"}))
            if not k.startswith("assay.") or k.split(".", 1)[1] in allowed]


def _get(raw: dict[str, Any], key: str) -> Any:
    table: Any = raw
    for part in key.split("."):
        if not isinstance(table, dict) or part not in table:
            return MISSING
        table = table[part]
    return table


def extremes(f: Any) -> list[Any]:
    """The ends of a field's declared range (and just outside them), or all of its choices."""
    if f is None:
        return []
    m = f.metadata
    if m.get("choices"):
        return list(m["choices"])
    out: list[Any] = []
    integral = m["kind"] is int
    for end, step in ((m.get("lo"), -1), (m.get("hi"), 1)):
        if end is None:
            continue
        if integral:
            out += [int(end), int(end) + step]
        else:
            out += [float(end), math.nextafter(float(end), step * math.inf)]
            if m.get("lo_open") and step < 0:
                out.append(math.nextafter(float(end), math.inf))
    return out


def mutations(path: Path, with_extremes: bool = True) -> list[tuple[Path, str, Any]]:
    """Every (file, key, value) mutation of one bundled scenario."""
    raw = read(path)
    out, seen = [], set()
    for key, f in keys_of(raw):
        values = list(GENERIC) + (extremes(f) if with_extremes else [])
        present = _get(raw, key) is not MISSING
        for v in values:
            if (v is MISSING and not present) or label(key, v) in seen:
                continue
            seen.add(label(key, v))
            out.append((path, key, v))
    return out


def all_mutations(with_extremes: bool = True) -> list[tuple[Path, str, Any]]:
    return [m for p in SCENARIO_FILES for m in mutations(p, with_extremes)]


def mutate(raw: dict[str, Any], key: str, value: Any) -> dict[str, Any]:
    """A deep copy of ``raw`` with ``key`` set to ``value`` (deleted for :data:`MISSING`)."""
    return mutate_shallow(copy.deepcopy(raw), key, value)


def mutate_shallow(raw: dict[str, Any], key: str, value: Any) -> dict[str, Any]:
    """:func:`mutate` for a reader that never writes into its input: only the tables on the
    key's path are copied, everything else is shared with ``raw`` (a deep copy of a scenario
    is most of a one-key sweep's time). Callers check that ``raw`` came back unchanged."""
    out = dict(raw)
    *sections, leaf = key.split(".")
    table = out
    for name in sections:
        nxt = table.get(name, {})
        if not isinstance(nxt, dict):  # a parent was mutated away; not reachable from one key
            return out
        table[name] = nxt = dict(nxt)
        table = nxt
    if value is MISSING:
        table.pop(leaf, None)
    else:
        table[leaf] = copy.deepcopy(value)
    return out


# --- running at a reduced duration ----------------------------------------------------------------

#: Flows a reduced pyrosequencing run keeps: the key TCAG's 1-mers are within the first 8 of TACG.
SHORT_FLOWS = 8


def _num(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def shorten(raw: dict[str, Any], mutated: str, max_frames: int | None = None) -> dict[str, Any]:
    """The same scenario over fewer flows and a duration just long enough, leaving the mutated
    keys (comma-separated) alone: what the property test runs of a valid mutation.

    With ``max_frames``, a pyrosequencing run still longer than that gets flows of fewer whole
    N-frame blocks (pyro_paper_yield_fast: 8 flows of 60 s at 128 frames/s are 61,696 frames;
    of 2 s, 2,304), and another assay a duration of fewer blocks: the mutation runs through
    every stage, not the assay's whole light curve.
    """
    out = copy.deepcopy(raw)
    keys = set(mutated.split(","))
    a, r = out.get("assay"), out.get("run")
    if not isinstance(a, dict) or not isinstance(r, dict) or keys & {"run", "run.duration_s"}:
        return out
    if a.get("kind") == "pyrosequencing":
        n, period, start = a.get("n_flows", 16), a.get("flow_period_s", 60.0), a.get("start_s", 0)
        if not keys & {"assay", "assay.n_flows"} and _num(n):
            n = a["n_flows"] = min(int(n), SHORT_FLOWS)
        if max_frames and not keys & {"assay", "assay.flow_period_s"}:
            period = _fewer_blocks(out, keys, max_frames, n, period, start)
            a["flow_period_s"] = period
        if _num(n) and _num(period) and _num(start):
            r["duration_s"] = start + n * period
    elif max_frames and _num(a.get("start_s", 0)) and _num(r.get("duration_s")):
        start = a.get("start_s", 0)
        r["duration_s"] = start + _fewer_blocks(out, keys, max_frames, 1, r["duration_s"] - start,
                                                start)
    return out


def _fewer_blocks(raw: dict[str, Any], keys: set[str], max_frames: int, n: Any, span: Any,
                  start: Any) -> Any:
    """``span`` (s, ``n`` times after ``start``) cut to whole N-frame blocks so that the run
    keeps within ``max_frames`` frames; unchanged when it does, or when the timing is mutated."""
    chip = raw.get("chip", {})
    dsp = chip.get("dsp", {}) if isinstance(chip, dict) else {}
    timing = chip.get("timing", {}) if isinstance(chip, dict) else {}
    if not isinstance(dsp, dict) or not isinstance(timing, dict):
        return span
    frame, blocks = timing.get("frame_period_s", 1.0), dsp.get("average_frames", 4)
    timing_keys = {"chip", "chip.timing", "chip.timing.frame_period_s", "chip.dsp",
                   "chip.dsp.average_frames", "assay.start_s", "assay"}
    if keys & timing_keys or not all(_num(v) and v > 0 for v in (frame, blocks, n, span)) \
            or not _num(start) or isinstance(blocks, float):
        return span
    block_s = blocks * frame
    fit = int((max_frames * frame - start) / (n * block_s))
    if span * n + start <= max_frames * frame or fit < 1 or fit * block_s >= span:
        return span
    return fit * block_s


# --- writing TOML ----------------------------------------------------------------------------


def _value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return {"nan": "nan", "inf": "inf", "-inf": "-inf"}.get(repr(v), repr(v))
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{json.dumps(k)} = {_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(f"cannot write {v!r} as TOML")


def dumps(raw: dict[str, Any], prefix: str = "") -> str:
    """A TOML text that :func:`tomllib.loads` reads back as ``raw`` (tables become sections)."""
    lines = [f"{json.dumps(k)} = {_value(v)}" for k, v in raw.items() if not isinstance(v, dict)]
    for k, v in raw.items():
        if isinstance(v, dict):
            name = f"{prefix}.{json.dumps(k)}" if prefix else json.dumps(k)
            lines += ["", f"[{name}]", dumps(v, name)]
    return "\n".join(lines)


def label(key: str, value: Any) -> str:
    return f"{key}=(missing)" if value is MISSING else f"{key}={value!r}"
