"""Read a scenario TOML file, apply ``--set`` overrides, and build the validated :class:`Scenario`.

Overrides go into the raw table before validation, so ``--set chip.adc.bits=40`` meets exactly the
checks a file saying ``bits = 40`` would.
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import difflib
import functools
import tomllib
import typing
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from chiptwin.config.catalog import resolve_scenario
from chiptwin.config.chemistry import with_chemistry
from chiptwin.config.consistency import check_consistency
from chiptwin.config.datasheet import (
    apply_datasheet,
    datasheet_values,
    probe_table,
    read_datasheet,
)
from chiptwin.config.fields import ScenarioError, check_value
from chiptwin.config.schema import ASSAY_COMMON_KEYS, ASSAY_KIND_KEYS, Scenario

REQUIRED_SECTIONS = ("scenario", "assay", "run")


def load_scenario(
    path: str | Path, overrides: Iterable[str] = (), seed: int | None = None
) -> Scenario:
    """Load and validate a scenario file.

    Parameters
    ----------
    path : str or Path
        The TOML file, or the name of a bundled scenario (``"pyro_1fmol"``, as on the command
        line: :func:`chiptwin.config.catalog.resolve_scenario`).
    overrides : iterable of str
        ``"section.key=value"`` strings; the value is read as TOML (``12``, ``1e-3``, ``"x"``,
        ``true``), falling back to a bare string.
    seed : int, optional
        Replaces ``scenario.seed``.

    Raises
    ------
    ScenarioError
        Naming the file, the key, the value and what is allowed; an override's key is named by
        the override (``--set chip.pitch_um=80: …``), not by the file it was not in.
    """
    if isinstance(path, str):
        path = resolve_scenario(path)
    source = str(path)
    raw = read_toml(path)
    overrides = list(overrides)
    for text in overrides:
        apply_override(raw, text, OVERRIDE_SOURCE)
    if seed is not None:
        raw.setdefault("scenario", {})["seed"] = seed
    with named_overrides(source, overrides):
        return scenario_from_dict(raw, source)


#: What a malformed ``--set`` names instead of a file.
OVERRIDE_SOURCE = "command line"


@contextlib.contextmanager
def named_overrides(source: str, overrides: list[str]):
    """Re-raise a refusal of ``source`` by what caused it: a key an override set is named by
    that override (``--set chip.pitch_um=80``); another key, refused once overrides were
    applied, by the file and the overrides (``pyro_1fmol.toml with --set …``)."""
    try:
        yield
    except ScenarioError as err:
        if not overrides or err.source != source:
            raise
        keys = {text.partition("=")[0].strip(): text for text in overrides}
        hit = next((text for k, text in keys.items()
                    if err.key == k or err.key.startswith(k + ".")), None)
        shown = (f"--set {hit}" if hit is not None else
                 f"{source} with " + ", ".join(f"--set {t}" for t in overrides))
        raise ScenarioError(shown, err.key, err.value, err.allowed) from None


def read_toml(path: str | Path) -> dict[str, Any]:
    """Parse a TOML file; unreadable or malformed files are :class:`ScenarioError`."""
    source = str(path)
    try:
        text = Path(path).read_bytes().decode("utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ScenarioError(
            source, "(file)", source, f"must be a readable UTF-8 file ({exc})") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(source, "(file)", source, f"must be valid TOML ({exc})") from None


def apply_override(raw: dict[str, Any], text: str, source: str) -> None:
    """Set ``a.b.c=value`` in the raw table (validation happens later, on the whole)."""
    key, sep, value_text = text.partition("=")
    key = key.strip()
    if not sep or not key or any(not part for part in key.split(".")):
        raise ScenarioError(source, "--set", text, "must look like section.key=value")
    try:
        value = tomllib.loads(f"v = {value_text.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        value = value_text.strip()
    *sections, leaf = key.split(".")
    table = raw
    for i, name in enumerate(sections):
        table = table.setdefault(name, {})
        if not isinstance(table, dict):
            prefix = ".".join(sections[: i + 1])
            raise ScenarioError(source, prefix, table, "is a value, not a section")
    table[leaf] = value


def scenario_from_dict(raw: dict[str, Any], source: str = "<scenario>") -> Scenario:
    """Build and check a :class:`Scenario` from an already parsed table.

    ``[chip.pixel] from_datasheet = "FILE.json"`` is replaced, in a copy of the table and before
    validation (as ``--set`` overrides are), by the pixel and ADC values of that EMVA 1288
    datasheet (:func:`chiptwin.config.datasheet.apply_datasheet`: path relative to the scenario's
    folder, else the working folder; values the scenario also sets must agree).
    """
    chip = raw.get("chip")
    pixel = chip.get("pixel") if isinstance(chip, dict) else None
    if isinstance(pixel, dict) and "from_datasheet" in pixel:
        raw = apply_datasheet(raw, source, lambda table: _scenario(table, source))
    return _scenario(raw, source)


def _scenario(raw: dict[str, Any], source: str) -> Scenario:
    for name in REQUIRED_SECTIONS:
        if name not in raw:
            raise ScenarioError(source, f"[{name}]", dataclasses.MISSING, "section is required")
    raw = with_chemistry(raw)  # a named chemistry's keys, under the scene's own
    scenario = _build(Scenario, raw, source, "", skip={"source"})
    scenario = _resolve_capacitance(dataclasses.replace(scenario, source=source))
    _check_assay_keys(raw["assay"], scenario.assay.kind, source)
    scenario = _draw_template(scenario, raw["assay"], source)
    check_consistency(scenario)
    return scenario


def _resolve_capacitance(s: Scenario) -> Scenario:
    """``[chip.pixel] capacitance_fF = 0`` (not given): the node capacitance the diode gives
    (:attr:`chiptwin.config.schema_chip.Pixel.derived_capacitance_fF`), resolved once here so
    every stage reads one number; a value given wins."""
    px = s.chip.pixel
    if px.capacitance_fF > 0:
        return s
    pixel = dataclasses.replace(px, capacitance_fF=px.derived_capacitance_fF)
    return dataclasses.replace(s, chip=dataclasses.replace(s.chip, pixel=pixel))


def _draw_template(s: Scenario, raw_assay: dict[str, Any], source: str) -> Scenario:
    """``[assay] template_length > 0``: the template is the key plus a drawn insert
    (:func:`chiptwin.kinetics.templates.drawn_template`), resolved once here."""
    a = s.assay
    if a.kind != "pyrosequencing" or not a.template_length:
        return s
    if raw_assay.get("template", "") not in ("", a.key):
        raise ScenarioError(source, "assay.template", a.template[:40],
                            "give a template or template_length (a drawn one), not both")
    from chiptwin.kinetics.templates import drawn_template

    if not a.key or set(a.key.upper()) - set("ACGT"):
        raise ScenarioError(source, "assay.key", a.key, "must be 1 or more of A, C, G, T")
    template = drawn_template(a.key, a.template_length, a.template_gc,
                              a.template_homopolymer_p, a.template_homopolymer_max,
                              a.template_seed)
    return dataclasses.replace(s, assay=dataclasses.replace(a, template=template))


def _build(cls: type, raw: Any, source: str, prefix: str, skip: frozenset | set = frozenset()):
    """Recursively build dataclass ``cls`` from table ``raw``, checking every key."""
    if not isinstance(raw, dict):
        raise ScenarioError(source, prefix.rstrip(".") or "(top)", raw, "must be a table")
    fields, sections = _layout(cls, frozenset(skip))
    for key in raw:
        if key not in fields:
            raise ScenarioError(source, prefix + key, raw[key], _unknown_key_hint(key, fields))
    values = {}
    for name, f in fields.items():
        key = prefix + name
        if name in sections:
            values[name] = _build(sections[name], raw.get(name, {}), source, key + ".")
        elif name in raw:
            values[name] = check_value(f, raw[name], source, key)
        elif f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
            raise ScenarioError(source, key, dataclasses.MISSING, "is required")
    return cls(**values)


@functools.cache
def _layout(cls: type, skip: frozenset) -> tuple[dict[str, dataclasses.Field], dict[str, type]]:
    """A schema class's fields by name (``skip`` left out) and its sub-sections' classes, once:
    a study or a mutation sweep builds thousands of scenarios from the same classes."""
    fields = {f.name: f for f in dataclasses.fields(cls) if f.name not in skip}
    hints = type_hints(cls)
    return fields, {n: hints[n] for n in fields if dataclasses.is_dataclass(hints[n])}


@functools.cache
def type_hints(cls: type) -> dict[str, Any]:
    """``typing.get_type_hints`` of a schema class, once: it evaluates every string annotation
    (``from __future__ import annotations``) and was two thirds of a validation's time."""
    return typing.get_type_hints(cls)


def _unknown_key_hint(key: str, fields: dict) -> str:
    close = difflib.get_close_matches(key, list(fields), n=1, cutoff=0.6)
    hint = f"did you mean {close[0]!r}? " if close else ""
    return f"unknown key; {hint}allowed: {', '.join(sorted(fields))}"


def _check_assay_keys(raw_assay: dict[str, Any], kind: str, source: str) -> None:
    """Keys of another assay kind are errors: they would be silently ignored otherwise."""
    allowed = ASSAY_KIND_KEYS[kind] | ASSAY_COMMON_KEYS
    for key in raw_assay:
        if key not in allowed:
            raise ScenarioError(
                source, f"assay.{key}", raw_assay[key],
                f"not used by assay kind {kind!r}; its keys: {', '.join(sorted(allowed))}",
            )


def load_with_datasheet(path: str | Path, datasheet: str | Path, overrides: Iterable[str] = (),
                        seed: int | None = None) -> Scenario:
    """A scenario file whose chip takes its pixel and ADC values from a datasheet
    (``chiptwin characterize --from``): the datasheet's values replace the file's own, as a
    command-line option should; an override (``--set``) of one of them is a conflict."""
    source = str(path)
    datasheet = Path(datasheet)
    doc = read_datasheet(datasheet)
    raw = read_toml(path)
    base_raw = copy.deepcopy(raw)
    overrides = list(overrides)
    for text in overrides:
        apply_override(base_raw, text, OVERRIDE_SOURCE)
    pixel_raw = (base_raw.get("chip") or {}).get("pixel")
    if isinstance(pixel_raw, dict):
        pixel_raw.pop("from_datasheet", None)
    with named_overrides(source, overrides):
        targets = datasheet_values(doc, scenario_from_dict(probe_table(base_raw), source))
    for key in targets:
        section = raw.get("chip", {}).get(key.split(".")[1])
        if isinstance(section, dict):
            section.pop(key.rsplit(".", 1)[1], None)
    for text in overrides:
        apply_override(raw, text, OVERRIDE_SOURCE)
    raw.setdefault("chip", {}).setdefault("pixel", {})["from_datasheet"] = str(datasheet.resolve())
    if seed is not None:
        raw.setdefault("scenario", {})["seed"] = seed
    with named_overrides(source, overrides):
        return scenario_from_dict(raw, source)
