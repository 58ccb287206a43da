"""Optimize study files: ``kind = "optimize"`` → the fields of a validated study.

A design search varies several scenario keys to trade objectives against each other under
constraints (the search itself: :mod:`chiptwin.study.optimize`)::

    [study]
    name = "optimize_assay_size"
    kind = "optimize"
    scenario = "pyro_1fmol"
    seed = 1                       # the rows' seeds and the sampler's own
    replicates = 4                 # runs per evaluated point: each metric with its interval
    evaluations = 60               # the budget: points evaluated at most
    batch = 8                      # points asked for at once (NSGA-II: its population)
    stop = { gain = 0.01, last = 16 }   # optional: stop early when the hypervolume stalls

    [[study.parameter]]            # a numeric key: range inside its own schema range, and why
    key = "chip.pitch_um"
    range = [60.0, 200.0]
    why = "..."

    [[study.parameter]]            # a named choice: a list of values
    key = "chip.adc.bits"
    values = [10, 12, 13]
    why = "..."

    [[study.objective]]
    metric = "snr_power"
    direction = "maximize"

    [[study.constraint]]
    metric = "base_error_rate"
    op = "<="
    bound = 1e-3

Every error names the study file, the key, the value and what is allowed
(:class:`~chiptwin.config.ScenarioError`, exit code 2), before anything runs or is written.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace
from typing import Any

from chiptwin.config.load import read_toml, scenario_from_dict
from chiptwin.study.metrics import CATALOGUE, check_metric_applies
from chiptwin.study.readers import (
    Errors,
    check_key,
    in_rule,
    inline_table,
    keyed_table,
    numeric_range,
    pin_datasheet,
    put_key,
    scenario_path_of,
    table_list,
    unknown,
)

#: The search method as ``Study.search`` and study.json name it.
METHOD = "optuna"
DIRECTIONS = ("maximize", "minimize")
OPS = ("<=", ">=")
JUDGED = ("bound", "estimate")
#: A range whose ends are more than this ratio apart (over one decade) is searched in log space.
LOG_RATIO = 10.0
#: Evaluations a study may ask for: 10⁴ points × a few replicates of a 1 s run is a day on two
#: cores; a larger design space is a different tool (a surrogate model), not more evaluations.
MAX_EVALUATIONS = 10_000
#: Replicates per point: the budget study's cap (a rate of 3e-4 resolved at 95 %).
MAX_REPLICATES = 10_000
#: Values of a named-choice key: more is a numeric range.
MAX_CHOICES = 100
#: Rows (evaluations × replicates) a study may hold: the budget study's cap (≈ 14 h on 2 cores
#: at 0.1 s a run).
MAX_ROWS = 1_000_000

#: Every key of ``[study]`` in an optimize study, with its rule and default.
OPTIMIZE_KEYS: dict[str, str] = {
    "name": "required; letters, digits, '_', '-', '.'; names the output folder",
    "description": "optional text",
    "kind": '"optimize"',
    "scenario": "required; a bundled scenario name, or a TOML path relative to the study file",
    "seed": "required; integer in [0, 2^63 − 1]; the root of every row's seed and of the "
            "sampler's",
    "set": "inline table of scenario keys, default {}; overrides applied to every point",
    "replicates": f"required; integer in [1, {MAX_REPLICATES}]; runs per evaluated point",
    "vary_chip": "true or false, default false; true: every replicate another chip",
    "confidence": "number in [0.5, 0.9999], default 0.95: the one-sided level of a "
                  "constraint's bound and the two-sided level of every interval",
    "evaluations": f"required; integer in [2, {MAX_EVALUATIONS}]: the budget, points evaluated "
                   "at most",
    "batch": "integer in [2, 256], default 8: points asked for at once and evaluated in "
             "parallel (NSGA-II's population); the points do not depend on the workers",
    "stop": "optional inline table { gain = g, last = k }: stop before the budget once the "
            "feasible front's hypervolume grew by less than the fraction g (in (0, 1)) over "
            "the last k evaluations (k ≥ batch)",
    "parameter": "[[study.parameter]] tables, at least one: the keys varied",
    "objective": "[[study.objective]] tables, at least one: metric and direction",
    "constraint": "[[study.constraint]] tables, optional: metric, op and bound",
}
PARAMETER_KEYS: dict[str, str] = {
    "key": "required; a scenario key: with range a number or an integer (integers stay "
           "integers), with values any key",
    "range": "[lo, hi], finite, lo < hi, inside the key's own schema range (exactly one of "
             "range or values)",
    "values": f"a list of 2 to {MAX_CHOICES} distinct values, each allowed by the key's own "
              "rule: a named choice (exactly one of range or values)",
    "scale": '"lin" or "log" with range; default "log" when hi/lo > 10, else "lin"',
    "why": "required; text: why this range is physically meaningful",
}
OBJECTIVE_KEYS: dict[str, str] = {
    "metric": "required; a metric of the catalogue (rate or mean) the scenario can give",
    "direction": '"maximize" or "minimize"',
    "reference": "optional finite number: the objective's end of the hypervolume's reference "
                 "point (default: the worst feasible value seen, pushed out by 10 % of the "
                 "span)",
}
CONSTRAINT_KEYS: dict[str, str] = {
    "metric": "required; a metric of the catalogue (rate or mean) the scenario can give",
    "op": '"<=" or ">="',
    "bound": "required; a finite number",
    "judged": '"bound" (default: the one-sided bound at `confidence` must meet it, as a '
              'budget study\'s requirement) or "estimate" (the point estimate must)',
}


@dataclass(frozen=True)
class Parameter:
    """One varied key: a numeric range (``lo``, ``hi``, ``log``, ``integer``) or named
    ``choices``."""

    key: str
    why: str
    lo: float = 0.0
    hi: float = 0.0
    log: bool = False
    integer: bool = False
    choices: tuple = ()


@dataclass(frozen=True)
class Objective:
    metric: str
    direction: str
    reference: float | None = None

    @property
    def sign(self) -> float:
        """+1 to minimise, −1 to maximise: ``sign · value`` is always minimised."""
        return 1.0 if self.direction == "minimize" else -1.0


@dataclass(frozen=True)
class Constraint:
    metric: str
    op: str
    bound: float
    judged: str = "bound"

    def __str__(self) -> str:
        return f"{self.metric} {self.op} {self.bound:g}"


@dataclass(frozen=True)
class StopRule:
    """Stop once the hypervolume grew by less than ``gain`` (a fraction) over the last
    ``last`` evaluations; ``gain = 0`` means the budget alone."""

    gain: float = 0.0
    last: int = 0

    def __str__(self) -> str:
        if not self.gain:
            return "the budget of evaluations"
        return (f"the budget, or earlier once the feasible front's hypervolume grew by less "
                f"than {self.gain:g} of itself over the last {self.last} evaluations")


@dataclass(frozen=True)
class Optimization:
    """A validated optimize study's search."""

    parameters: tuple[Parameter, ...]
    objectives: tuple[Objective, ...]
    constraints: tuple[Constraint, ...]
    evaluations: int
    batch: int
    stop: StopRule

    @property
    def sampler(self) -> str:
        return "NSGAIISampler" if len(self.objectives) > 1 else "TPESampler"

    @property
    def metrics(self) -> tuple[str, ...]:
        names = [o.metric for o in self.objectives] + [c.metric for c in self.constraints]
        return tuple(dict.fromkeys(names))


def read_optimization(err: Errors, st: dict, folder: Path, resolve) -> dict[str, Any]:
    """The keys of an optimize study's ``[study]`` (:data:`OPTIMIZE_KEYS`), checked against
    the base scenario (with ``set`` applied); returns the fields of its
    :class:`~chiptwin.study.spec.Study`."""
    for k in st:
        if k not in OPTIMIZE_KEYS:
            err.fail(f"study.{k}", st[k], unknown(k, set(OPTIMIZE_KEYS)).replace(
                "unknown key", 'not a key of a study of kind = "optimize"'))
    name = err.string(st, "name", r"[A-Za-z0-9_.-]+", "letters, digits, '_', '-', '.' "
                      "(it names the output folder)")
    scen_path = scenario_path_of(err, st, folder, resolve)
    base_raw = read_toml(scen_path)
    datasheet_text = pin_datasheet(base_raw, scen_path)
    overrides = inline_table(err, st, "set")
    for k, v in overrides.items():
        check_key(err, "study.set", k, base_raw)
        put_key(base_raw, k, v, err.source)
    base = scenario_from_dict(json.loads(json.dumps(base_raw)), str(scen_path))
    params = _parameters(err, st, base_raw, set(overrides))
    probe = SimpleNamespace(axes=tuple(SimpleNamespace(key=p.key, values=p.choices)
                                       for p in params))
    objectives = tuple(_objective(err, i, t, base, probe)
                       for i, t in enumerate(table_list(err, st, "objective")))
    if not objectives:
        err.fail("study.objective", dataclasses.MISSING, "at least one [[study.objective]] is "
                 "required: metric and direction")
    if len({o.metric for o in objectives}) < len(objectives):
        err.fail("study.objective", [o.metric for o in objectives], "names a metric twice")
    constraints = tuple(_constraint(err, i, t, base, probe)
                        for i, t in enumerate(table_list(err, st, "constraint")))
    replicates = err.integer(st, "replicates", 1, MAX_REPLICATES, "runs per evaluated point")
    evaluations = err.integer(st, "evaluations", 2, MAX_EVALUATIONS, "the budget: points "
                              "evaluated at most")
    if evaluations * replicates > MAX_ROWS:
        err.fail("study.evaluations", evaluations, f"{evaluations} points × {replicates} "
                 f"replicates = {evaluations * replicates} rows; at most {MAX_ROWS}")
    for i, c in enumerate(constraints):
        if replicates < 2 and c.judged == "bound" and CATALOGUE[c.metric].kind == "mean":
            err.fail(f"study.constraint[{i}].judged", "bound", f"{c.metric} is a mean over "
                     "runs: its bound needs replicates ≥ 2 (Student t), have 1; add "
                     "replicates, or judge the estimate (judged = \"estimate\")")
    batch = err.integer(st, "batch", 2, 256, "points asked for at once", default=8)
    confidence = st.get("confidence", 0.95)
    if not isinstance(confidence, float) or not 0.5 <= confidence <= 0.9999:
        err.fail("study.confidence", confidence, "must be a number in [0.5, 0.9999] (a "
                 "constraint bound's one-sided level)")
    vary_chip = err.boolean(st, "vary_chip", False)
    if vary_chip and base_raw.get("chip", {}).get("fixed_pattern_seed", -1) >= 0:
        err.fail("study.vary_chip", True, "the scenario pins chip.fixed_pattern_seed (one "
                 "chip); remove it, or set vary_chip = false")
    opt = Optimization(params, objectives, constraints, evaluations, batch,
                       _stop(err, st, batch, evaluations))
    return dict(name=name, scenario_path=str(scen_path), base_raw=base_raw,
                seed=err.integer(st, "seed", 0, 2**63 - 1, "the root of np.random.SeedSequence"),
                replicates=replicates, metrics=opt.metrics, overrides=overrides,
                description=err.text(st, "description"), datasheet_text=datasheet_text,
                vary_chip=vary_chip, confidence=confidence, search=METHOD, optimization=opt)


def _parameters(err: Errors, st: dict, base_raw: dict, fixed: set[str]
                ) -> tuple[Parameter, ...]:
    tables = table_list(err, st, "parameter")
    if not tables:
        err.fail("study.parameter", dataclasses.MISSING, "at least one [[study.parameter]] is "
                 "required: a scenario key, its range (or values) and why")
    out: list[Parameter] = []
    for i, t in enumerate(tables):
        taken = {k: "is fixed by study.set: vary it or set it, not both" for k in fixed}
        taken.update({p.key: "is listed twice" for p in out})
        out.append(_parameter(err, f"study.parameter[{i}]", t, base_raw, taken))
    return tuple(out)


def _parameter(err: Errors, where: str, t: dict, base_raw: dict, taken: dict[str, str]
               ) -> Parameter:
    if isinstance(t, dict) and ("range" in t) == ("values" in t):
        err.fail(where, t.get("key", dataclasses.MISSING), "needs exactly one of range = "
                 "[lo, hi] (a numeric key) or values = [...] (named choices)")
    why = t.get("why", dataclasses.MISSING)
    if "values" in t:
        return _choices(err, where, t, base_raw, taken, why)
    key, rule, r = numeric_range(err, where, t, set(PARAMETER_KEYS), base_raw, taken,
                                 "a key with a range is a number or an integer; list a "
                                 "choice's values instead (values = [...])")
    integer = rule.metadata.get("kind") is int
    if integer and not all(float(x).is_integer() for x in r):
        err.fail(f"{where}.range", r, f"{key} is an integer: its range ends are integers")
    lo, hi = (float(in_rule(err, f"{where}.range", r, rule, key, x)) for x in r)
    scale = t.get("scale", "log" if lo > 0 and hi / lo > LOG_RATIO else "lin")
    if scale not in ("lin", "log"):
        err.fail(f"{where}.scale", scale, 'must be "lin" or "log"')
    if scale == "log" and lo <= 0:
        err.fail(f"{where}.scale", scale, f"{key}: a log scale needs lo > 0 (range {r})")
    return Parameter(key, _why(err, where, key, why), lo, hi, scale == "log", integer)


def _choices(err: Errors, where: str, t: dict, base_raw: dict, taken: dict[str, str],
             why: Any) -> Parameter:
    key, rule = keyed_table(err, where, t, set(PARAMETER_KEYS), "chip.adc.bits", base_raw)
    if key in taken:
        err.fail(f"{where}.key", key, taken[key])
    values = t["values"]
    if not isinstance(values, list) or not 2 <= len(values) <= MAX_CHOICES:
        err.fail(f"{where}.values", values, f"must be a list of 2 to {MAX_CHOICES} values")
    if len({json.dumps(v, sort_keys=True) for v in values}) != len(values):
        err.fail(f"{where}.values", values, "must not repeat a value")
    if any(isinstance(v, dict | list) for v in values):
        err.fail(f"{where}.values", values, "each value a number, text or true/false (a "
                 "choice Optuna can store)")
    checked = tuple(in_rule(err, f"{where}.values", values, rule, key, v) for v in values)
    if "scale" in t:
        err.fail(f"{where}.scale", t["scale"], "applies to a range; values are taken as listed")
    return Parameter(key, _why(err, where, key, why), choices=checked)


def _why(err: Errors, where: str, key: str, why: Any) -> str:
    if not isinstance(why, str) or not why.strip():
        err.fail(f"{where}.why", why, f"{key}: say why the range is physically meaningful and "
                 "where its ends come from (text)")
    return why.strip()


def _metric(err: Errors, where: str, t: dict, allowed: dict[str, str], base, probe) -> str:
    """A table's own keys, and its metric: in the catalogue, a rate or a mean, one the base
    scenario can give at every point."""
    for k in t:
        if k not in allowed:
            err.fail(f"{where}.{k}", t[k], unknown(k, set(allowed)))
    name = t.get("metric", dataclasses.MISSING)
    usable = sorted(n for n, m in CATALOGUE.items() if m.kind != "loss")
    if not isinstance(name, str) or name not in CATALOGUE:
        err.fail(f"{where}.metric", name, "must be a metric of the catalogue: one of "
                 + ", ".join(usable))
    if CATALOGUE[name].kind == "loss":
        err.fail(f"{where}.metric", name, "is measured against a reference point, which an "
                 "optimize study has none of; use snr_power (its own scale) instead")
    problem = check_metric_applies(name, base, probe)
    if problem:
        err.fail(f"{where}.metric", name, problem)
    return name


def _objective(err: Errors, i: int, t: Any, base, probe) -> Objective:
    where = f"study.objective[{i}]"
    name = _metric(err, where, t, OBJECTIVE_KEYS, base, probe)
    direction = t.get("direction", dataclasses.MISSING)
    if direction not in DIRECTIONS:
        err.fail(f"{where}.direction", direction, 'must be "maximize" or "minimize"')
    ref = t.get("reference")
    if ref is not None and not _finite(ref):
        err.fail(f"{where}.reference", ref, "must be a finite number (the hypervolume's "
                 "reference value of this objective)")
    return Objective(name, direction, None if ref is None else float(ref))


def _constraint(err: Errors, i: int, t: Any, base, probe) -> Constraint:
    where = f"study.constraint[{i}]"
    name = _metric(err, where, t, CONSTRAINT_KEYS, base, probe)
    op = t.get("op", dataclasses.MISSING)
    if op not in OPS:
        err.fail(f"{where}.op", op, 'must be "<=" or ">="')
    bound = t.get("bound", dataclasses.MISSING)
    if not _finite(bound):
        err.fail(f"{where}.bound", bound, "must be a finite number")
    judged = t.get("judged", "bound")
    if judged not in JUDGED:
        err.fail(f"{where}.judged", judged, 'must be "bound" or "estimate"')
    return Constraint(name, op, float(bound), judged)


def _stop(err: Errors, st: dict, batch: int, evaluations: int) -> StopRule:
    s = st.get("stop")
    if s is None:
        return StopRule()
    if not isinstance(s, dict) or set(s) != {"gain", "last"}:
        err.fail("study.stop", s, "must be an inline table { gain = 0.01, last = 16 }")
    gain, last = s["gain"], s["last"]
    if not _finite(gain) or not 0.0 < gain < 1.0:
        err.fail("study.stop.gain", gain, "must be a number in (0, 1): the hypervolume's "
                 "relative gain below which the search has stalled")
    if type(last) is not int or not batch <= last < evaluations:
        err.fail("study.stop.last", last, f"must be an integer in [batch = {batch}, "
                 f"evaluations = {evaluations}): the evaluations the gain is measured over")
    return StopRule(float(gain), last)


def _finite(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
