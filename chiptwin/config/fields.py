"""Declarative field checks for scenario dataclasses.

A scenario section is a frozen dataclass whose fields are made with :func:`param`; the loader reads
the metadata to check type, range and choices, so each rule is written once, beside the field.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import MISSING, Field
from typing import Any


class ScenarioError(ValueError):
    """A scenario that cannot be run: names the file, the key, the value and what is allowed."""

    def __init__(self, source: str, key: str, value: Any, allowed: str) -> None:
        self.source, self.key, self.value, self.allowed = source, key, value, allowed
        shown = "(missing)" if value is MISSING else repr(value)
        if isinstance(value, (int, float)) and not isinstance(value, bool) and unit_of(key):
            shown += f" {unit_of(key)}"  # in the key's own unit: "frame_period_s = 0.001 s"
        super().__init__(f"{source}: {key} = {shown}: {allowed}")


def param(
    default: Any = MISSING,
    *,
    kind: type | tuple[type, ...] = float,
    lo: float | None = None,
    hi: float | None = None,
    lo_open: bool = False,
    choices: tuple[Any, ...] | None = None,
    zero: str = "",
    doc: str = "",
) -> Any:
    """A dataclass field that carries its own validation rule.

    Parameters
    ----------
    default : Any
        The default; omit for a required key.
    kind : type or tuple of types
        Allowed Python type(s). ``float`` also accepts ``int``; ``bool`` is never a number.
    lo, hi : float, optional
        Inclusive bounds (``lo`` exclusive when ``lo_open``).
    choices : tuple, optional
        The allowed values.
    zero : str, optional
        What 0 means when 0 is allowed outside ``lo … hi`` ("derived from the diode").
    doc : str
        Unit and source of the default, shown in error messages and docs.
    """
    meta = {"kind": kind, "lo": lo, "hi": hi, "lo_open": lo_open, "choices": choices,
            "zero": zero, "doc": doc}
    if default is MISSING:
        return dataclasses.field(metadata=meta)
    if isinstance(default, list):
        return dataclasses.field(default_factory=lambda: list(default), metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


def _kind_name(kind: type | tuple[type, ...]) -> str:
    kinds = kind if isinstance(kind, tuple) else (kind,)
    names = {float: "a number", int: "an integer", str: "a string", bool: "true or false"}
    return " or ".join(names.get(k, k.__name__) for k in kinds)


def _type_ok(value: Any, kind: type | tuple[type, ...]) -> bool:
    kinds = kind if isinstance(kind, tuple) else (kind,)
    if isinstance(value, bool):
        return bool in kinds
    if isinstance(value, int) and float in kinds:
        return True
    return isinstance(value, kinds)


def allowed_text(f: Field) -> str:
    """The rule of a field, in words: what an error message says is allowed."""
    m = f.metadata
    if m.get("choices"):
        return "must be one of " + ", ".join(repr(c) for c in m["choices"])
    text = "must be " + (f"0 ({m['zero']}) or " if m.get("zero") else "") + _kind_name(m["kind"])
    lo, hi = m.get("lo"), m.get("hi")
    if lo is not None and hi is not None:
        text += f" in {'(' if m['lo_open'] else '['}{lo:g}, {hi:g}]"
    elif lo is not None:
        text += f" {'>' if m['lo_open'] else '≥'} {lo:g}"
    elif hi is not None:
        text += f" ≤ {hi:g}"
    return text + (f" ({m['doc']})" if m.get("doc") else "")


def check_value(f: Field, value: Any, source: str, key: str) -> Any:
    """Check one value against its field's rule; return it (ints widened to float for floats)."""
    m = f.metadata
    if m.get("choices") is not None:
        if value not in m["choices"]:
            raise ScenarioError(source, key, value, allowed_text(f))
        return value
    if not _type_ok(value, m["kind"]):
        raise ScenarioError(source, key, value, allowed_text(f))
    if isinstance(value, float) and not math.isfinite(value):
        raise ScenarioError(source, key, value, allowed_text(f) + "; must be finite")
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        lo, hi = m.get("lo"), m.get("hi")
        below = lo is not None and (value <= lo if m["lo_open"] else value < lo)
        if (below and not (value == 0 and m.get("zero"))) or (hi is not None and value > hi):
            raise ScenarioError(source, key, value, out_of_range(f, key, value))
        if m["kind"] is float:
            return float(value)
    return value


#: The unit a key's name ends with (STYLE: units in the names), as a message shows it.
UNITS = (("_per_um2", "/µm²"), ("_per_um", "/µm"), ("_per_s", "1/s"), ("_s", "s"),
         ("_um", "µm"), ("_nm", "nm"), ("_hz", "Hz"), ("_fF", "fF"), ("_uV", "µV"),
         ("_V", "V"), ("_C", "°C"), ("_e", "e⁻"), ("_lsb", "LSB"), ("_db", "dB"))


def unit_of(key: str) -> str:
    """The unit a key's name carries (``chip.timing.frame_period_s`` → ``s``; ``fF_per_um2``
    → ``fF/µm²``), "" when it carries none."""
    name = key.rsplit(".", 1)[-1]
    for suffix, unit in UNITS:
        if name.endswith(suffix):
            if unit.startswith("/"):  # a per-length key: the unit before it, "fF" + "/µm²"
                head = name[: -len(suffix)].rsplit("_", 1)[-1]
                return head + unit if head in ("fF", "aF", "e", "V") else ""
            return unit
    return ""


def with_unit(value: float, key: str) -> str:
    """A value as a message shows it, with its key's unit: ``1.5033 s``, ``80 µm``."""
    unit = unit_of(key)
    return f"{value:.5g}" + (f" {unit}" if unit else "")


def out_of_range(f: Field, key: str, value: float) -> str:
    """A refused range, its bound first: "below the smallest allowed, 1e-09 s (why); must be a
    number in [1e-09, 1e+07]"."""
    m = f.metadata
    lo, hi = m.get("lo"), m.get("hi")
    if hi is not None and value > hi:
        bound = f"is above the largest allowed, {with_unit(hi, key)}"
    elif m["lo_open"]:
        return allowed_text(f)  # "(0, 1]" already says it: nothing equal to 0 is allowed
    else:
        bound = f"is below the smallest allowed, {with_unit(lo, key)}"
    return f"{bound}; {allowed_text(f)}"
