"""Study files: TOML → a validated :class:`Study`, with the strictness of scenario files.

A study is a base scenario plus axes (which scenario keys vary, over which values), replicates,
metrics and a requirement. Every error names the file, the key, the value and what is allowed
(:class:`~chiptwin.config.ScenarioError`, exit code 2), before anything is run or written.

Layout (``scenarios/studies/*.toml`` are worked examples)::

    [study]
    name = "adc_bits_pyro"          # output folder name
    scenario = "pyro_1fmol"         # a bundled scenario, or a path (relative to this file)
    seed = 1                        # root of every row's seed
    replicates = 40                 # per point (the cap per point with search = "bisect")
    vary_chip = false               # true: every replicate another chip (PRNU/DSNU redrawn)
    reference = { "chip.adc.bits" = 20 }   # the ideal that losses are measured against
    set = { "run.fidelity.photons" = "binned" }  # overrides applied to every point
    search = "grid"                 # or "bisect" on the one budget axis
    stop_early = false              # true: looks of `batch` replicates; decided points stop

    [[study.axis]]                  # axes in order of cost significance: the first is the budget
    key = "chip.adc.bits"
    range = [6, 14]
    scale = "int"                   # "lin" / "log" (with n) or "int" (every integer)

    [[study.axis]]
    key = "assay.dna_fmol"
    values = [1.0, 0.1]
    given = true                    # a condition: one answer per value, not a budget

    [[study.metric]]
    name = "base_error_rate"

    [study.requirement]
    base_error_rate = "<= 1e-3"
    confidence = 0.95

A study of ``kind = "sensitivity"`` (one budget axis, a requirement) adds assumptions, each
expanded one at a time around the base scenario's own value (:mod:`chiptwin.study.sensitivity`)::

    [[study.assumption]]
    key = "chip.pixel.read_noise_e"
    range = [30.0, 300.0]
    why = "not published; 30 e⁻ (a quiet readout) … 300 e⁻ (a simple source follower)"
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from chiptwin.config import Scenario, ScenarioError
from chiptwin.config.load import read_toml, scenario_from_dict
from chiptwin.study.metrics import CATALOGUE, check_metric_applies
from chiptwin.study.readers import (
    Errors,
    check_key,
    finite_pair,
    identity_table,
    inline_table,
    keyed_table,
    pin_datasheet,
    put_key,
    scenario_path_of,
    table_list,
    unknown,
)
from chiptwin.study.sensitivity import Assumption, conditions
from chiptwin.study.spec_sensitivity import assumptions_of

#: Rows a study may hold: 10⁶ runs of the 0.1 s reference scene is ≈ 14 h on 2 cores, beyond
#: any interactive use; more is refused before anything runs.
MAX_ROWS = 1_000_000
#: Points an axis may have (a grid multiplies them): more than anyone reads on a plot.
MAX_AXIS_VALUES = 1000
#: Replicates per point: 10⁴ resolves a rate of 3e-4 at 95 % (rule of three), enough for any
#: per-read requirement of a sequencing chip; more is a different experiment.
MAX_REPLICATES = 10_000
#: Characters of a point's label in its scenario's source (``file [key=value, …]``): stages ask
#: whether the source is a file, and a name past 255 bytes raises; a longer label names the
#: point by its id instead.
MAX_LABEL = 200
SCALES = ("lin", "log", "int")
SEARCHES = ("grid", "bisect")
KINDS = ("budget", "sensitivity", "calibrate", "optimize")
_REQ = re.compile(r"^\s*(<=|>=)\s*([-+0-9.eE]+|inf)\s*$")


@dataclass(frozen=True)
class Axis:
    """One varied scenario key and its values, cheapest first."""

    key: str
    values: tuple
    given: bool = False
    zip: bool = False


@dataclass(frozen=True)
class Requirement:
    """``metric op threshold``: met when the metric's one-sided confidence bound is on the
    allowed side (the upper bound for ``<=``, the lower bound for ``>=``)."""

    metric: str
    op: str
    threshold: float

    def __str__(self) -> str:
        return f"{self.metric} {self.op} {self.threshold:g}"


@dataclass(frozen=True)
class Point:
    """One combination of axis values: its identity, parameters and place in the cost order."""

    id: str
    params: dict[str, Any]
    given: tuple  # the values of the given (condition) axes
    cost: tuple[int, ...]  # indices along the budget axes, most significant first
    reference: bool = False


@dataclass(frozen=True)
class Study:
    """A validated study file."""

    name: str
    source: str
    text: str
    scenario_path: str
    base_raw: dict[str, Any]
    seed: int
    replicates: int
    axes: tuple[Axis, ...]
    metrics: tuple[str, ...]
    requirements: tuple[Requirement, ...] = ()
    confidence: float = 0.95
    vary_chip: bool = False
    reference: dict[str, Any] = field(default_factory=dict)
    overrides: dict[str, Any] = field(default_factory=dict)
    search: str = "grid"
    stop_early: bool = False
    batch: int = 10
    verify: int = 1
    description: str = ""
    datasheet_text: str = ""  # the base scenario's from_datasheet file, part of the identity
    kind: str = "budget"
    assumptions: tuple[Assumption, ...] = ()  # kind "sensitivity": their axes end ``axes``
    calibration: Any = None  # kind "calibrate": a chiptwin.study.calibrate_spec.Calibration
    table: dict[str, Any] = field(default_factory=dict)  # the [study] table as read: its identity
    quick: str = ""  # what `chiptwin study --quick` shrank ("" : the study as asked)
    asked: str = ""  # the command line that made this study from another ("" : none)
    optimization: Any = None  # kind "optimize": a chiptwin.study.optimize_spec.Optimization

    @property
    def budget_axes(self) -> tuple[Axis, ...]:
        return tuple(a for a in self.axes if not a.given)

    @property
    def given_axes(self) -> tuple[Axis, ...]:
        return tuple(a for a in self.axes if a.given)

    @property
    def hash(self) -> str:
        """Identity of what the rows depend on: the ``[study]`` table (not its comments or
        layout, nor where its files are: :func:`identity_table`), the resolved base scenario and
        its datasheet; a study read without its table falls back on its text."""
        table = identity_table(self.table) if self.table else self.text
        parts = [table, self.base_raw, self.datasheet_text]
        if self.calibration is not None:  # the measured data are part of what it depends on
            parts.append(self.calibration.target.hash)
        blob = json.dumps(parts, sort_keys=True, default=str)
        return hashlib.sha256(blob.encode()).hexdigest()[:16]

    def points(self) -> list[Point]:
        """Every point of the grid (zipped axes advance together), budget order inside each
        given combination."""
        return expand_points(self)

    def reference_point(self, p: Point) -> Point | None:
        """The point whose rows define the ideal for ``p`` (``p`` with the reference overrides)."""
        if not self.reference:
            return None
        params = {**p.params, **self.reference}
        return Point(point_id(params), params, p.given, (), reference=True)


#: Every key of ``[study]`` with what it means, its range and its default: the loader accepts
#: exactly these keys, and the documentation's study-file reference is generated from this table.
STUDY_KEYS: dict[str, str] = {
    "name": "required; letters, digits, '_', '-', '.'; names the output folder (out/<name>)",
    "description": "optional text; default \"\"",
    "scenario": "required; a bundled scenario name, or a TOML path relative to the study file",
    "seed": "required; integer in [0, 2^63 − 1]; the root of every row's seed",
    "replicates": f"required; integer in [1, {MAX_REPLICATES}]; runs per point (the cap per point "
                  "with search = \"bisect\")",
    "vary_chip": "true or false, default false; true: every replicate is another chip "
                 "(PRNU/DSNU redrawn), false: one chip from the study seed",
    "reference": "inline table of scenario keys, default {}; the ideal point that snr_loss_db "
                 "is measured against",
    "set": "inline table of scenario keys, default {}; overrides applied to every point",
    "search": "\"grid\" (default: every point) or \"bisect\" (the one budget axis, sequential "
              "looks)",
    "stop_early": "true or false, default false; a grid adds replicates in looks of `batch` to "
                  "every point not yet decided and stops a point once its requirement is "
                  "decided (the cap: replicates), at per-look levels that keep `confidence` "
                  "over the looks (chiptwin.detection.stats.look_levels); false runs every "
                  "replicate, one look (grid only; needs a requirement)",
    "batch": f"integer in [1, {MAX_REPLICATES}], default 10; replicates added per look (bisect, "
             "or a grid with stop_early)",
    "verify": "integer in [0, 10], default 1; points above a bisect answer re-checked for "
              "monotonicity",
    "kind": "\"budget\" (default: the cheapest budget per condition), \"sensitivity\" (the "
            "same answer, and how far each [[study.assumption]] moves it: one budget axis, a "
            "requirement, at least one assumption), \"calibrate\" (scenario keys fitted to "
            "measured data, with intervals: its own keys, chiptwin.study.calibrate_spec) or "
            "\"optimize\" (a design search over several keys, objectives and constraints with "
            "Optuna: its own keys, chiptwin.study.optimize_spec)",
    "axis": "[[study.axis]] tables, at least one; cheapest and most significant first",
    "quick": "optional text, default \"\"; written by `chiptwin study --quick`: what the "
             "quick look shrank (replicates, budget axes); every output is labelled with it",
    "asked": "optional text, default \"\"; written by `chiptwin study` with overrides: the "
             "command line that made this study from another; the report shows it",
    "assumption": "[[study.assumption]] tables (kind = \"sensitivity\" only): a scenario value "
                  "not known, its plausible range and why",
    "metric": "[[study.metric]] tables with one key, name (a metric of the catalogue), at least "
              "one",
    "requirement": "table metric = \"<= x\" or \">= x\", plus confidence in [0.5, 0.9999] "
                   "(default 0.95), the one-sided level of every bound",
}
#: Every key of a ``[[study.axis]]`` table (see :data:`STUDY_KEYS`).
AXIS_KEYS: dict[str, str] = {
    "key": 'required; a scenario key, e.g. "chip.adc.bits" (an [assay] key of the base '
           "scenario's kind)",
    "values": f"a list of 1 to {MAX_AXIS_VALUES} distinct values, cheapest first (exactly one of "
              "values or range)",
    "range": "[lo, hi], two finite numbers with lo < hi (exactly one of values or range)",
    "scale": "with range: \"lin\" or \"log\" (with n), or \"int\" (every integer from lo to hi)",
    "n": f"with scale lin or log: integer in [2, {MAX_AXIS_VALUES}], the number of values",
    "given": "true or false, default false; true: a condition with one answer per value, not "
             "a budget",
    "zip": "true or false, default false; zipped axes advance together (same number of values)",
}
_STUDY_KEYS = set(STUDY_KEYS)
_AXIS_KEYS = set(AXIS_KEYS)


def load_study(path: str | Path, resolve_scenario=None) -> Study:
    """Read and validate a study file.

    Parameters
    ----------
    path : the TOML file
    resolve_scenario : ``name -> Path`` for bundled scenario names (the CLI's resolver)

    Raises
    ------
    ScenarioError
        Naming the file, the key (``study.axis[1].range``), the value and what is allowed.
    """
    source = str(path)
    raw = read_toml(path)
    text = Path(path).read_text(encoding="utf-8")
    return study_from_dict(raw, source, text, Path(path).parent, resolve_scenario)


def study_from_dict(raw: dict[str, Any], source: str = "<study>", text: str | None = None,
                    folder: Path = Path("."), resolve_scenario=None) -> Study:
    """Build a :class:`Study` from a parsed table (see :func:`load_study`)."""
    err = Errors(source)
    for key in raw:
        if key != "study":
            err.fail(key, raw[key], unknown(key, {"study"}))
    st = raw.get("study")
    if not isinstance(st, dict):
        err.fail("[study]", st if st is not None else dataclasses.MISSING, "section is required")
    if st.get("kind") == "calibrate":  # its own keys and checks
        return _calibration_study(err, st, text if text is not None else json.dumps(raw),
                                  folder, resolve_scenario)
    if st.get("kind") == "optimize":  # its own keys and checks
        from chiptwin.study.optimize_spec import read_optimization

        return Study(source=source, text=text if text is not None else json.dumps(raw),
                     axes=(), kind="optimize", table=json.loads(json.dumps(st, default=str)),
                     **read_optimization(err, st, folder, resolve_scenario))
    for key in st:
        if key not in _STUDY_KEYS:
            err.fail(f"study.{key}", st[key], unknown(key, _STUDY_KEYS))
    name = err.string(st, "name", r"[A-Za-z0-9_.-]+", "letters, digits, '_', '-', '.' "
                      "(it names the output folder)")
    scen_path = scenario_path_of(err, st, folder, resolve_scenario)
    base_raw = read_toml(scen_path)
    datasheet_text = pin_datasheet(base_raw, scen_path)
    for k, v in inline_table(err, st, "set").items():
        check_key(err, "study.set", k, base_raw)
        put_key(base_raw, k, v, source)
    seed = err.integer(st, "seed", 0, 2**63 - 1, "the root of np.random.SeedSequence")
    replicates = err.integer(st, "replicates", 1, MAX_REPLICATES,
                             "runs per point; the cap per point with bisect")
    axes = tuple(_axis(err, i, a, base_raw) for i, a in enumerate(table_list(err, st, "axis")))
    if not axes:
        err.fail("study.axis", dataclasses.MISSING, "at least one [[study.axis]] is required")
    metrics = _metrics(err, st)
    reference = inline_table(err, st, "reference")
    for k in reference:
        check_key(err, "study.reference", k, base_raw)
    requirements, confidence = _requirements(err, st, metrics, reference)
    kind = err.choice(st, "kind", KINDS, "budget")
    assumptions = assumptions_of(err, st, kind, axes, base_raw, str(scen_path))
    study = Study(
        name=name, source=source, text=text if text is not None else json.dumps(raw),
        scenario_path=str(scen_path), base_raw=base_raw, seed=seed, replicates=replicates,
        axes=axes, metrics=metrics, requirements=requirements, confidence=confidence,
        vary_chip=err.boolean(st, "vary_chip", False), reference=reference,
        overrides=inline_table(err, st, "set"), search=err.choice(st, "search", SEARCHES, "grid"),
        stop_early=err.boolean(st, "stop_early", False),
        batch=err.integer(st, "batch", 1, MAX_REPLICATES, "replicates added per look",
                          default=10),
        verify=err.integer(st, "verify", 0, 10, "points above a bisect answer re-checked",
                           default=1),
        description=err.text(st, "description"), datasheet_text=datasheet_text,
        kind=kind, assumptions=assumptions, table=json.loads(json.dumps(st, default=str)),
        quick=err.text(st, "quick"), asked=err.text(st, "asked"),
    )
    if kind == "sensitivity":
        study = _with_design(err, study)
    _check_whole(err, study)
    return study


def _calibration_study(err: Errors, st: dict, text: str, folder: Path, resolve) -> Study:
    """A study of ``kind = "calibrate"``: its keys read by
    :func:`chiptwin.study.calibrate_spec.read_calibration`; a table target's x values are its
    one axis (every point's scenario is checked as a budget study's are)."""
    from chiptwin.study.calibrate_spec import read_calibration

    name = err.string(st, "name", r"[A-Za-z0-9_.-]+", "letters, digits, '_', '-', '.' "
                      "(it names the output folder)")
    scen_path = scenario_path_of(err, st, folder, resolve)
    base_raw = read_toml(scen_path)
    datasheet_text = pin_datasheet(base_raw, scen_path)
    overrides = inline_table(err, st, "set")
    for k, v in overrides.items():
        check_key(err, "study.set", k, base_raw)
        put_key(base_raw, k, v, err.source)
    seed = err.integer(st, "seed", 0, 2**63 - 1, "the root of np.random.SeedSequence")
    cal = read_calibration(err, st, base_raw, str(scen_path), folder)
    return Study(name=name, source=err.source, text=text, scenario_path=str(scen_path),
                 base_raw=base_raw, seed=seed, replicates=cal.replicates,
                 axes=tuple(Axis(k, v) for k, v in cal.axes),
                 metrics=cal.metrics, overrides=overrides, search=cal.method,
                 description=err.text(st, "description"), datasheet_text=datasheet_text,
                 kind="calibrate", calibration=cal, table=json.loads(json.dumps(st, default=str)))


def _check_whole(err: Errors, study: Study) -> None:
    """Rules between fields: sizes, the bisect shape, metrics the base scenario can give."""
    lengths = {len(a.values) for a in study.axes if a.zip}
    if len(lengths) > 1:
        err.fail("study.axis", [a.key for a in study.axes if a.zip],
                 f"zipped axes must have the same number of values (have {sorted(lengths)})")
    if len({a.given for a in study.axes if a.zip}) > 1:  # one group: a budget or a condition
        err.fail("study.axis", [a.key for a in study.axes if a.zip], "zipped axes advance "
                 "together: all conditions (given = true) or all budget axes, not both")
    if study.search == "bisect":
        budget = study.budget_axes
        if len(budget) != 1 or budget[0].zip:
            err.fail("study.search", "bisect", "bisects exactly one budget axis (mark the "
                     "others given = true); have " + str([a.key for a in budget]))
        if not study.requirements:
            err.fail("study.search", "bisect", "needs a [study.requirement] to decide points")
    if study.stop_early and study.search != "grid":
        err.fail("study.stop_early", True, "applies to search = \"grid\"; a bisection stops "
                 "each point at its own looks already")
    if study.stop_early and not study.requirements:
        err.fail("study.stop_early", True, "needs a [study.requirement]: a point is stopped "
                 "once it is decided, and with none nothing is decided")
    # counted, not expanded: a grid too large to hold is refused before it is built
    n_points = math.prod(len(g[0].values) for g in _axis_groups(study.axes))
    n_points *= 2 if study.reference else 1
    rows = n_points * study.replicates
    if rows > MAX_ROWS:
        err.fail("study.replicates", study.replicates,
                 f"{n_points} points × {study.replicates} replicates = {rows} rows; at most "
                 f"{MAX_ROWS} (≈ 14 h on 2 cores at 0.1 s a run)")
    if study.vary_chip and study.base_raw.get("chip", {}).get("fixed_pattern_seed", -1) >= 0:
        err.fail("study.vary_chip", True, "the scenario pins chip.fixed_pattern_seed (one chip); "
                 "remove it, or set vary_chip = false")
    base = scenario_from_dict(json.loads(json.dumps(study.base_raw)), study.scenario_path)
    refs = {p.id: p for p in map(study.reference_point, expand_points(study)) if p}
    for ref in refs.values():  # every loss is measured against it: it must be a valid scene
        try:
            point_scenario(study, ref.params, study.seed, None)
        except ScenarioError as exc:
            err.fail("study.reference", study.reference, f"gives an inconsistent scenario: {exc}")
    for m in study.metrics:
        problem = check_metric_applies(m, base, study)
        if problem:
            err.fail("study.metric", m, problem)


def _axis_groups(axes: tuple[Axis, ...]) -> list[list[Axis]]:
    """The grid's dimensions: each axis alone, and every zipped axis in one group at the place
    of the first of them."""
    groups: list[list[Axis]] = []
    for a in axes:
        zipped = next((g for g in groups if g[0].zip), None) if a.zip else None
        if zipped is None:
            groups.append([a])
        else:
            zipped.append(a)
    return groups


def expand_points(study: Study) -> list[Point]:
    """The grid: the product of the axis groups (:func:`_axis_groups`)."""
    groups = _axis_groups(study.axes)
    ranges = [range(len(g[0].values)) for g in groups]
    points = []
    for idx in itertools.product(*ranges):
        params: dict[str, Any] = {}
        given: list = []
        cost: list[int] = []
        for g, i in zip(groups, idx, strict=True):
            for a in g:
                params[a.key] = a.values[i]
            if g[0].given:
                given.extend(a.values[i] for a in g)
            else:
                cost.append(i)
        points.append(Point(point_id(params), params, tuple(given), tuple(cost)))
    return points


def point_id(params: dict[str, Any]) -> str:
    """A point's identity: the hash of its parameters (order-free), 16 hex digits."""
    blob = json.dumps(params, sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def point_scenario(study: Study, params: dict[str, Any], seed: int,
                   fixed_pattern_seed: int | None) -> Scenario:
    """The validated scenario of one point and seed (raises ScenarioError when inconsistent)."""
    raw = json.loads(json.dumps(study.base_raw))  # a deep copy of plain TOML data
    for key, value in params.items():
        put_key(raw, key, value, study.source)
    raw.setdefault("scenario", {})["seed"] = seed
    if fixed_pattern_seed is not None:
        raw.setdefault("chip", {})["fixed_pattern_seed"] = fixed_pattern_seed
    label = ", ".join(f"{k}={v}" for k, v in params.items())
    if len(Path(study.scenario_path).name) + len(label) > MAX_LABEL:
        label = f"point {point_id(params)}"  # the source is tried as a path: keep it a name
    return scenario_from_dict(raw, f"{study.scenario_path} [{label}]")


# ---------------------------------------------------------------- field readers


def _axis(err: Errors, i: int, a: dict, base_raw: dict) -> Axis:
    where = f"study.axis[{i}]"
    key, _ = keyed_table(err, where, a, _AXIS_KEYS, "chip.adc.bits", base_raw)
    if ("values" in a) == ("range" in a):
        err.fail(where, key, "needs exactly one of values = [...] or range = [lo, hi] + scale")
    values = _axis_values(err, where, a) if "range" in a else a["values"]
    if not isinstance(values, list) or not values or len(values) > MAX_AXIS_VALUES:
        err.fail(f"{where}.values", values, f"must be a list of 1 to {MAX_AXIS_VALUES} values")
    if len({json.dumps(v, sort_keys=True) for v in values}) != len(values):
        err.fail(f"{where}.values", values, "must not repeat a value")
    for flag in ("given", "zip"):
        if not isinstance(a.get(flag, False), bool):
            err.fail(f"{where}.{flag}", a[flag], "must be true or false")
    return Axis(key, tuple(values), a.get("given", False), a.get("zip", False))


def _axis_values(err: Errors, where: str, a: dict) -> list:
    r, scale = a["range"], a.get("scale", dataclasses.MISSING)
    if not (finite_pair(r) and r[0] < r[1]):
        err.fail(f"{where}.range", r, "must be [lo, hi], two finite numbers with lo < hi")
    if scale not in SCALES:
        err.fail(f"{where}.scale", scale, "must be one of 'lin', 'log' (with n) or 'int'")
    lo, hi = r
    if scale == "int":
        if any(type(x) is not int for x in r) or hi - lo >= MAX_AXIS_VALUES:
            err.fail(f"{where}.range", r, f"scale 'int' needs two integers less than "
                     f"{MAX_AXIS_VALUES} apart")
        return list(range(lo, hi + 1))
    n = a.get("n", dataclasses.MISSING)
    if type(n) is not int or not 2 <= n <= MAX_AXIS_VALUES:
        err.fail(f"{where}.n", n, f"must be an integer in [2, {MAX_AXIS_VALUES}] with scale "
                 f"{scale!r}: the number of values from lo to hi")
    if scale == "log":
        if lo <= 0:
            err.fail(f"{where}.range", r, "scale 'log' needs lo > 0")
        step = (math.log10(hi) - math.log10(lo)) / (n - 1)
        return [float(f"{10 ** (math.log10(lo) + i * step):.6g}") for i in range(n)]
    return [float(f"{lo + i * (hi - lo) / (n - 1):.10g}") for i in range(n)]


def _metrics(err: Errors, st: dict) -> tuple[str, ...]:
    names = []
    for i, m in enumerate(table_list(err, st, "metric")):
        for k in m:
            if k != "name":
                err.fail(f"study.metric[{i}].{k}", m[k], unknown(k, {"name"}))
        name = m.get("name", dataclasses.MISSING)
        if not isinstance(name, str):
            err.fail(f"study.metric[{i}].name", name, "must be the name of a metric (text), "
                     "one of " + ", ".join(sorted(CATALOGUE)))
        if name not in CATALOGUE:
            err.fail(f"study.metric[{i}].name", name, unknown(str(name), set(CATALOGUE))
                     .replace("unknown key", "unknown metric"))
        if name in names:
            err.fail(f"study.metric[{i}].name", name, "is listed twice")
        names.append(name)
    if not names:
        err.fail("study.metric", dataclasses.MISSING, "at least one [[study.metric]] is required")
    return tuple(names)


def _requirements(err: Errors, st: dict, metrics: tuple[str, ...], reference: dict
                  ) -> tuple[tuple[Requirement, ...], float]:
    req = inline_table(err, st, "requirement")
    confidence = req.pop("confidence", 0.95)
    if not isinstance(confidence, float) or not 0.5 <= confidence <= 0.9999:
        err.fail("study.requirement.confidence", confidence,
                 "must be a number in [0.5, 0.9999] (the one-sided level of every bound)")
    out = []
    for name, text in req.items():
        if name not in metrics:
            err.fail(f"study.requirement.{name}", text,
                     "is not a computed metric; add it as [[study.metric]] (computed: "
                     + ", ".join(metrics) + ")")
        m = _REQ.match(text) if isinstance(text, str) else None
        if not m:
            err.fail(f"study.requirement.{name}", text, 'must be a string "<= x" or ">= x"')
        out.append(Requirement(name, m.group(1), float(m.group(2))))
    if "snr_loss_db" in metrics and not reference:
        err.fail("study.metric", "snr_loss_db", "is measured against the ideal: set "
                 'study.reference, e.g. { "chip.adc.bits" = 20 }')
    return tuple(out), confidence




def _with_design(err: Errors, study: Study) -> Study:
    """A sensitivity study's conditions as given axes zipped together, after the study's own
    axes (:func:`~chiptwin.study.sensitivity.conditions`); every condition checked."""
    budget = study.budget_axes
    if len(budget) != 1:
        err.fail("study.kind", "sensitivity", "answers one budget: exactly one budget axis (mark "
                 "the others given = true); have " + str([a.key for a in budget]))
    if not all(isinstance(v, int | float) and not isinstance(v, bool) for v in budget[0].values):
        err.fail("study.kind", "sensitivity", f"measures how far the answer moves: the budget "
                 f"axis {budget[0].key} needs numeric values")
    zipped = [a.key for a in study.axes if a.zip]
    if zipped:
        err.fail("study.axis", zipped, "a sensitivity study zips its assumptions' conditions "
                 "together; no axis of its own may be zipped")
    if not study.requirements:
        err.fail("study.requirement", dataclasses.MISSING, "a sensitivity study needs a "
                 "requirement: the answer it moves is the cheapest budget that meets it")
    conds = conditions(study.assumptions)
    extra = tuple(Axis(a.key, tuple(c[a.key] for c in conds), given=True, zip=True)
                  for a in study.assumptions)
    study = dataclasses.replace(study, axes=study.axes + extra)
    for c in conds[1:]:  # an end that makes the base scenario inconsistent: refused now
        i, a = next((i, a) for i, a in enumerate(study.assumptions) if c[a.key] != a.reference)
        try:
            point_scenario(study, c, study.seed, None)
        except ScenarioError as exc:
            err.fail(f"study.assumption[{i}].range", [a.lo, a.hi],
                     f"{a.key} = {c[a.key]!r} gives an inconsistent scenario: {exc}")
    return study
