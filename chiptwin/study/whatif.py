"""What-ifs: a study re-asked from the command line, as another study file.

``chiptwin study adc_bits_pyro --set chip.adc.comparator_noise_uV=45 --given
chip.pixel.diode_w_um=50,100`` edits the study's ``[study]`` table: ``--set`` a key of the base
scene (an axis of that key, a condition, is then pinned at that value), ``--axis`` the values of
an axis (``KEY=v1,v2,…`` or ``KEY=lo:hi:step``; a new key is a budget axis after the others),
``--given`` a condition (one answer per value), ``--replicates`` the runs per point, ``--quick`` a
smaller study for a first look (:func:`quick`). Every value is checked against its scenario key's
own range (the schema's) before anything runs; a refusal names the override
(``--set chip.adc.bits=40: chip.adc.bits = 40: must be an integer in [1, 24] …``, exit 2).

The result is an ordinary :class:`~chiptwin.study.spec.Study`: its table, and so its identity
(:attr:`~chiptwin.study.spec.Study.hash`), holds every override, and its name a digest of them
(its own output folder: a store is never resumed with other overrides' rows).
:func:`study_toml` writes a study out as a file that runs as it is (``study.toml`` beside the
results) and is the same study, hash and rows.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from chiptwin.config import ScenarioError
from chiptwin.config.fields import check_value
from chiptwin.config.load import apply_override, read_toml
from chiptwin.study.readers import (
    Errors,
    check_key,
    identity_table,
    inline_table,
    scenario_path_of,
)
from chiptwin.study.spec import MAX_AXIS_VALUES, MAX_REPLICATES, Study, study_from_dict
from chiptwin.study.toml_text import toml_key, toml_value

#: ``--quick``: replicates per point at most (a mean's Student-t interval at 10 runs is ≈ 3×
#: as wide as at 90; a rate's bound at 0 errors is 9× as high, so a requirement sized for the
#: full study's replicates may not be met by any quick point).
QUICK_REPLICATES = 10
#: ``--quick``: values a budget axis keeps at most, spread over it, both ends kept (the answer is
#: then one of them); conditions (given axes) are the question and keep every value.
QUICK_AXIS_VALUES = 4
#: The kinds a what-if applies to: a calibration fits keys, it has no axes or replicates of its
#: own to re-ask.
KINDS = ("budget", "sensitivity")
#: Where an axis's values come from in a ``[[study.axis]]`` table (replaced by ``values``).
_VALUE_KEYS = ("values", "range", "scale", "n")


@dataclass(frozen=True)
class Overrides:
    """What the command line changes in a study (``chiptwin study --help``)."""

    set: tuple[str, ...] = ()  # "KEY=VALUE"
    axis: tuple[str, ...] = ()  # "KEY=v1,v2,…" or "KEY=lo:hi:step"
    given: tuple[str, ...] = ()  # the same, as a condition
    replicates: int | None = None
    quick: bool = False

    def __bool__(self) -> bool:
        return bool(self.set or self.axis or self.given or self.quick
                    or self.replicates is not None)

    def words(self) -> list[str]:
        """The overrides as one would type them."""
        return ([f"--set {s}" for s in self.set] + [f"--axis {a}" for a in self.axis]
                + [f"--given {g}" for g in self.given]
                + ([f"--replicates {self.replicates}"] if self.replicates is not None else [])
                + (["--quick"] if self.quick else []))


def study_with(path: str | Path, overrides: Overrides, resolve_scenario=None,
               asked_as: str | None = None) -> Study:
    """The study file ``path`` with ``overrides`` applied, validated (raises ScenarioError
    naming the override); without overrides, the file as it is."""
    path = Path(path)
    raw = read_toml(path)
    if not overrides:
        return study_from_dict(raw, str(path), path.read_text(encoding="utf-8"), path.parent,
                               resolve_scenario)
    st = raw.get("study")
    kind = st.get("kind", "budget") if isinstance(st, dict) else None
    if kind not in KINDS:
        raise ScenarioError(" ".join(overrides.words()), "study.kind", kind,
                            "overrides apply to a study of kind " + " or ".join(map(repr, KINDS))
                            + "; edit a copy of the file instead")
    _apply(st, overrides, read_toml(scenario_path_of(Errors(str(path)), st, path.parent,
                                                     resolve_scenario)))
    source = f"{' '.join(overrides.words())} (on {path})"  # a refusal names the overrides first
    if overrides.quick:
        study = _load(raw, source, None, path.parent, resolve_scenario)
        st["quick"] = quick(st, study, shrink_replicates=overrides.replicates is None)
    digest = hashlib.sha256(json.dumps(identity_table({k: v for k, v in st.items() if k != "name"}),
                                       sort_keys=True).encode()).hexdigest()[:6]
    st["name"] = f"{st.get('name')}-{'quick-' if overrides.quick else ''}{digest}"
    st["asked"] = " ".join(["chiptwin study", asked_as or str(path), *map(_quoted,
                                                                         overrides.words())])
    study = _load(raw, source, None, path.parent, resolve_scenario)
    return _load(raw, source, study_toml(study), path.parent, resolve_scenario)


def _apply(st: dict, overrides: Overrides, base_raw: dict) -> None:
    """Every override but ``--quick`` into the ``[study]`` table ``st``, each checked against
    its key's rule in the scene ``base_raw`` (the key's range, the assay kind's keys)."""
    for text in overrides.set:
        _set(st, text, base_raw)
    for text in overrides.axis:
        _axis(st, "--axis", text, base_raw)
    for text in overrides.given:
        _axis(st, "--given", text, base_raw)
    if overrides.replicates is not None:
        n = overrides.replicates
        if not 1 <= n <= MAX_REPLICATES:
            raise ScenarioError(f"--replicates {n}", "replicates", n, f"must be an integer in "
                                f"[1, {MAX_REPLICATES}] (runs per point)")
        st["replicates"] = n


def _load(raw: dict, source: str, text: str | None, folder: Path, resolve) -> Study:
    """:func:`study_from_dict`, a refusal naming the overrides (the base scene they made
    inconsistent names its own file: the overrides are named before it)."""
    try:
        return study_from_dict(json.loads(json.dumps(raw)), source, text, folder, resolve)
    except ScenarioError as exc:
        if exc.source == source:
            raise
        raise ScenarioError(f"{source}: {exc.source}", exc.key, exc.value, exc.allowed) from None


def quick(st: dict, study: Study, shrink_replicates: bool = True) -> str:
    """Shrink ``st`` (the study ``study``'s table) for a first look: replicates (and a look's
    batch) to :data:`QUICK_REPLICATES`, every budget axis to :data:`QUICK_AXIS_VALUES` values.
    Returns what it shrank, in words (every output is labelled with it)."""
    changes = []
    if shrink_replicates and study.replicates > QUICK_REPLICATES:
        st["replicates"] = QUICK_REPLICATES
        changes.append(f"replicates {study.replicates} → {QUICK_REPLICATES}")
    if st.get("batch", 0) > st.get("replicates", 0):
        changes.append(f"batch {st['batch']} → {st['replicates']}")
        st["batch"] = st["replicates"]
    for table, axis in zip(st.get("axis", []), study.axes, strict=False):
        n = len(axis.values)
        if axis.given or n <= QUICK_AXIS_VALUES:
            continue
        keep = sorted({round(j * (n - 1) / (QUICK_AXIS_VALUES - 1))
                       for j in range(QUICK_AXIS_VALUES)})
        values = [axis.values[j] for j in keep]
        _put_values(table, values)
        changes.append(f"{axis.key} {n} values → {', '.join(map(str, values))}")
    return "; ".join(changes) or (f"nothing to shrink (≤ {QUICK_REPLICATES} replicates, ≤ "
                                  f"{QUICK_AXIS_VALUES} values a budget axis already)")


def _set(st: dict, text: str, base_raw: dict) -> None:
    """``--set KEY=VALUE``: into the study's ``set``; an axis of that key, a condition, is
    pinned (removed); a budget axis is refused (``--axis KEY=VALUE`` asks at one value)."""
    err = Errors(f"--set {text}")
    scratch: dict[str, Any] = {}
    apply_override(scratch, text, err.source)  # the parsing `chiptwin run --set` does
    key = text.partition("=")[0].strip()
    value = scratch
    for part in key.split("."):
        value = value[part]
    value = check_value(check_key(err, "key", key, base_raw), value, err.source, key)
    axes = st.get("axis", [])
    for a in axes if isinstance(axes, list) else []:
        if isinstance(a, dict) and a.get("key") == key and not a.get("given", False):
            err.fail(key, value, "is the study's budget axis; --axis "
                     f"{key}={_text(value)} asks at that value alone")
    if isinstance(axes, list):
        st["axis"] = [a for a in axes if not (isinstance(a, dict) and a.get("key") == key)]
    flat = inline_table(err, st, "set")
    flat[key] = value
    st["set"] = flat


def _axis(st: dict, flag: str, text: str, base_raw: dict) -> None:
    """``--axis``/``--given KEY=…``: the values of the axis of KEY (a budget axis stays one,
    ``--given`` makes it a condition), or a new axis after the others. ``KEY1+KEY2=…``: both
    keys take the values together (zipped: a square diode's two sides)."""
    err = Errors(f"{flag} {text}")
    keys, sep, values_text = (s.strip() for s in text.partition("="))
    if not sep or not keys or not values_text:
        err.fail(flag, text, "must look like KEY=v1,v2,… or KEY=lo:hi:step")
    axes = st.setdefault("axis", [])
    if not isinstance(axes, list):
        err.fail("study.axis", axes, "must be [[study.axis]] tables")
    zipped = "+" in keys
    if zipped and any(isinstance(a, dict) and a.get("zip") for a in axes):
        err.fail(keys, text, "the study zips axes already (one group of zipped axes a study); "
                 "give the keys one at a time")
    for key in (k.strip() for k in keys.split("+")):
        rule = check_key(err, "key", key, base_raw)
        values = [check_value(rule, v, err.source, key)
                  for v in parse_values(err, key, values_text)]
        if len({json.dumps(v) for v in values}) != len(values):
            err.fail(key, values, "must not repeat a value")
        mine = next((a for a in axes if isinstance(a, dict) and a.get("key") == key), None)
        if mine is None:
            mine = {"key": key}
            axes.append(mine)
        _put_values(mine, values)
        if flag == "--given":
            mine["given"] = True
        if zipped:
            mine["zip"] = True


def parse_values(err: Errors, key: str, text: str) -> list:
    """``v1,v2,…`` (each a TOML value, else text), a TOML array ``[…]``, or ``lo:hi:step``
    (every step from lo up to hi, hi included when a step lands on it)."""
    if text.startswith("["):
        try:
            values = tomllib.loads(f"v = {text}")["v"]
        except tomllib.TOMLDecodeError:
            err.fail(key, text, "must be a TOML array of values, e.g. [10, 12, 14]")
    elif re.fullmatch(r"[^,:]+:[^,:]+:[^,:]+", text):
        values = _steps(err, key, text)
    else:
        values = [_scalar(v.strip()) for v in text.split(",")]
        if any(v == "" for v in values):
            err.fail(key, text, "must be values separated by commas, none empty")
    if not isinstance(values, list) or not 1 <= len(values) <= MAX_AXIS_VALUES:
        err.fail(key, text, f"must give 1 to {MAX_AXIS_VALUES} values")
    return values


def _steps(err: Errors, key: str, text: str) -> list:
    lo, hi, step = (_scalar(x.strip()) for x in text.split(":"))
    numbers = all(isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)
                  for x in (lo, hi, step))
    if not numbers or step <= 0 or hi < lo:
        err.fail(key, text, "lo:hi:step must be three finite numbers, lo ≤ hi, step > 0")
    n = math.floor((hi - lo) / step * (1 + 1e-12)) + 1
    if n > MAX_AXIS_VALUES:
        err.fail(key, text, f"gives {n} values; at most {MAX_AXIS_VALUES}")
    if all(type(x) is int for x in (lo, hi, step)):
        return list(range(lo, hi + 1, step))
    return [float(f"{lo + i * step:.10g}") for i in range(n)]


def _scalar(text: str) -> Any:
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def _put_values(table: dict, values: list) -> None:
    for k in _VALUE_KEYS:
        table.pop(k, None)
    table["values"] = list(values)


def _text(value: Any) -> str:
    return value if isinstance(value, str) else toml_value(value)


def _quoted(word: str) -> str:
    """A shell word quoted where it holds what a shell would split or expand."""
    return word if re.fullmatch(r"[-\w.,:=/+]+( [-\w.,:=/+]+)?", word) else \
        word.split(" ", 1)[0] + " '" + word.split(" ", 1)[1] + "'"


# ------------------------------------------------------------------- the study as a file


def study_toml(study: Study) -> str:
    """The study as a file that runs as it is, from wherever it is written: its table with the
    scenario (and a calibration's measured data) by absolute path unless it is named as a
    bundled one. Reading it back gives the same study (:func:`identity_table`). A study read
    without its table (a kind that keeps none) is written as its own text."""
    if not study.table:
        return study.text
    table = json.loads(json.dumps(study.table, default=str))
    folder = Path(study.source).parent  # a calibration's (which takes no overrides)
    scen = table.get("scenario")
    if isinstance(scen, str) and (Path(scen).suffix or "/" in scen):
        table["scenario"] = str(Path(study.scenario_path).resolve())
    target = table.get("target")
    if isinstance(target, dict) and isinstance(target.get("path"), str) \
            and not target["path"].startswith("$") and not Path(target["path"]).is_absolute():
        target["path"] = str((folder / target["path"]).resolve())
    head = [f"# The study {study.name}, as run from {study.source}."]
    if study.asked:
        head.append(f"# Asked as: {study.asked}")
    if study.quick:
        head.append(f"# QUICK LOOK, not the study's answer: {study.quick}")
    head.append("# Run it as it is: chiptwin study study.toml (the same study, its rows resumed).")
    return "\n".join(head) + "\n\n" + render_toml({"study": table})


def render_toml(doc: dict[str, Any]) -> str:
    """A document of tables (``[study]``), its keys' values plain or inline, arrays of tables as
    ``[[study.axis]]``: what study files hold (:func:`tomllib.loads` reads it back equal)."""
    out: list[str] = []
    for name, table in doc.items():
        _table(out, name, table)
    return "\n".join(out).rstrip("\n") + "\n"


def _table(out: list[str], name: str, table: dict) -> None:
    arrays = {k: v for k, v in table.items()
              if isinstance(v, list) and v and all(isinstance(x, dict) for x in v)}
    out.append(f"[{name}]")
    out += [f"{toml_key(k)} = {toml_value(v)}" for k, v in table.items() if k not in arrays]
    out.append("")
    for k, items in arrays.items():
        for item in items:
            out.append(f"[[{name}.{toml_key(k)}]]")
            out += [f"{toml_key(ik)} = {toml_value(iv)}" for ik, iv in item.items()]
            out.append("")
