"""Calibrate study files: ``kind = "calibrate"`` → a validated :class:`Calibration`.

A calibration fits numeric scenario keys to measured data (the fit itself:
:mod:`chiptwin.study.calibrate_fit`)::

    [study]
    name = "calibrate_emva_set001"
    kind = "calibrate"
    scenario = "../measured_camera_set001.toml"
    seed = 1                       # the common random numbers of every candidate's simulation
    objective = "chi2"             # default: chi2 where the data carry standard errors, else wls

    [[study.parameter]]
    key = "chip.pixel.read_noise_e"
    range = [1.0, 40.0]            # inside the key's own schema range; > 1 decade: log space
    why = "a CCD's read noise: a few e⁻ (cooled, slow) to tens of e⁻ (fast)"

    [study.target]
    kind = "emva1288"              # or "table" (a CSV: chiptwin.study.calibrate_targets), or
                                   # "adc1241" (an ADC bench: chiptwin.study.calibrate_adc)
    path = "${CHIPTWIN_DATA}/emva1288/set001_ccd_12bit_crop128"   # a ${VAR} is the environment's

Every error names the study file (or the target's file), the key, the value and what is allowed
(:class:`~chiptwin.config.ScenarioError`), before anything runs or is written.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace
from typing import Any

from chiptwin.config.fields import allowed_text
from chiptwin.config.load import scenario_from_dict
from chiptwin.study.calibrate_adc import AdcTarget, check_noise_ranges, read_adc1241
from chiptwin.study.calibrate_targets import SERIES, EmvaTarget, TableTarget, read_emva, read_table
from chiptwin.study.metrics import CATALOGUE, check_metric_applies
from chiptwin.study.readers import (
    Errors,
    check_key,
    in_rule,
    inline_table,
    numeric_range,
    table_list,
    unknown,
)

#: The fit's method, as ``Study.search`` and study.json name it.
METHOD = "differential_evolution+least_squares"
OBJECTIVES = ("chi2", "wls")
TARGET_KINDS = ("table", "emva1288", "adc1241")
#: Target kinds named in the field but not built: the refusal says what is missing.
NOT_BUILT = {"flowgram": "the reads' calibration (SFF/BAM flowgrams) is not built"}
#: A range whose ends are more than this ratio apart (over one decade) is searched in log space.
LOG_RATIO = 10.0
#: Fewest pixels of the twin an EMVA replay may read per image (the pair statistics' n).
MIN_REPLAY_PIXELS = 64

#: Every key of ``[study]`` in a calibrate study, with its rule and default.
CALIBRATE_KEYS: dict[str, str] = {
    "name": "required; letters, digits, '_', '-', '.'; names the output folder",
    "description": "optional text",
    "kind": '"calibrate"',
    "scenario": "required; a bundled scenario name, or a TOML path relative to the study file",
    "seed": "required; integer in [0, 2^63 − 1]; the root of the common random numbers (every "
            "candidate simulated with the same streams) and of the optimiser's own",
    "set": "inline table of scenario keys, default {}; overrides applied before the fit",
    "parameter": "[[study.parameter]] tables, at least one: the keys fitted",
    "target": "[study.target] table: the measured data (kind table, emva1288 or adc1241)",
    "objective": '"chi2" (the measured standard errors: a likelihood; default where the data '
                 'carry them) or "wls" (equal weights, the error scale from the residuals)',
    "replicates": "integer in [2, 1000], default 4; table target with a scenario key as x: runs "
                  "per x value and candidate (their spread is the simulated mean's standard "
                  "error)",
    "optimiser": "inline table: popsize (integer in [4, 50], default 8: members per fitted "
                 "key), generations (integer in [1, 1000], default 40), tol (in (0, 1], "
                 "default 0.01: differential evolution stops when the population's objectives "
                 "spread less than tol × their mean)",
    "confidence": "number in [0.5, 0.999], default 0.95: the intervals' two-sided level",
}
#: Every key of a ``[[study.parameter]]`` table.
PARAMETER_KEYS: dict[str, str] = {
    "key": "required; a numeric scenario key (a number or an integer, not a choice or a "
           "switch), not the table's x",
    "range": "required; [lo, hi], finite, lo < hi, both inside the key's own schema range: "
             "where the fit searches",
    "scale": '"lin" or "log"; default "log" when hi/lo > 10 (more than a decade), else "lin"',
    "why": "required; text: why this range is physically meaningful",
}
#: Every key of ``[study.target]``, by target kind.
TARGET_KEYS: dict[str, dict[str, str]] = {
    "table": {"kind": '"table"', "path": "required; the CSV, relative to the study file or "
              "absolute; ${NAME} is the environment's NAME",
              "x": "required; the x column: a scenario key, or \"time\"",
              "y": "required; the y column: a metric of kind mean, or \"light\" with x = time"},
    "emva1288": {"kind": '"emva1288"', "path": "required; the data set's folder, relative to "
                 "the study file or absolute; ${NAME} is the environment's NAME (e.g. "
                 "${CHIPTWIN_DATA})", "pixel_pitch_um": "optional; the camera's pixel "
                 "pitch (a data set does not carry it)", "max_pixels": "optional integer ≥ "
                 f"{MIN_REPLAY_PIXELS}: pixels of the twin read per image (fewer: faster, the "
                 "simulated statistics noisier, which the residuals carry)"},
    "adc1241": {"kind": '"adc1241"', "path": "required; an IEEE 1241 bench's folder (what "
                "chiptwin characterize SCENARIO --adc --out DIR writes: adc1241.json), relative "
                "to the study file or absolute; ${NAME} is the environment's NAME",
                "max_converters": "optional integer ≥ 2: converters compared, evenly spaced "
                "over those the bench measured (fewer: faster, a wider interval)"},
}


@dataclass(frozen=True)
class FitParameter:
    """One fitted key: its search range, scale and the base scenario's own value.

    The optimiser works in ``u ∈ [0, 1]`` (:meth:`value`, :meth:`unit`): linear over the range,
    or over its logarithm when ``log``; an integer key's value is rounded."""

    key: str
    lo: float
    hi: float
    log: bool
    integer: bool
    why: str
    reference: float

    def value(self, u: float) -> float | int:
        """The key's value at ``u`` (clipped to [0, 1])."""
        u = min(max(float(u), 0.0), 1.0)
        if self.log:
            x = math.exp(math.log(self.lo) + u * (math.log(self.hi) - math.log(self.lo)))
        else:
            x = self.lo + u * (self.hi - self.lo)
        x = min(max(x, self.lo), self.hi)
        return int(round(x)) if self.integer else x

    def unit(self, x: float) -> float:
        """``u`` of a value (outside the range: beyond [0, 1])."""
        if self.log:
            return (math.log(x) - math.log(self.lo)) / (math.log(self.hi) - math.log(self.lo))
        return (x - self.lo) / (self.hi - self.lo)


@dataclass(frozen=True)
class Calibration:
    """A validated calibration: what is fitted, to what, and how."""

    parameters: tuple[FitParameter, ...]
    target: TableTarget | EmvaTarget | AdcTarget
    objective: str
    replicates: int
    popsize: int
    generations: int
    tol: float
    confidence: float
    axes: tuple = ()  # ((key, values),): a table target's x values, the study's one axis
    metrics: tuple[str, ...] = ()
    method: str = METHOD

    @property
    def keys(self) -> tuple[str, ...]:
        return tuple(p.key for p in self.parameters)

    @property
    def nuisance(self) -> int:
        """Parameters fitted beside the keys: an EMVA data set's dark offset."""
        return 1 if self.target.kind == "emva1288" else 0

    @property
    def max_evaluations(self) -> int:
        """The evaluations the fit is expected to take (the progress's total, the wall-time
        estimate): the evolution's generations and its first population, then the polish and
        the profiles with up to two restarts, about 3·(30·(k + 1) + 40·k) (measured: ≈ 30 at
        k = 1, 1,200–1,450 at k = 5 on set 001); a fit may take more."""
        k = len(self.parameters)
        return self.popsize * k * (self.generations + 1) + 3 * (30 * (k + 1) + 40 * k)


def _expand(err: Errors, given: str) -> str:
    """``${NAME}`` in a target's path replaced by the environment's ``NAME`` (measured data live
    outside the project: a bundled study names them by ``${CHIPTWIN_DATA}``, the folder that
    holds the data sets)."""
    import os
    import re

    def value(m: re.Match) -> str:
        name = m.group(1)
        if not os.environ.get(name):
            err.fail("study.target.path", given, f"names ${{{name}}}, which is not set: set "
                     f"{name} to the folder that holds the data (measured data sets are not "
                     "part of the project: docs/howto/calibrate.md says where to get them)")
        return os.environ[name]

    return re.sub(r"\$\{(\w+)\}", value, given)


def read_calibration(err: Errors, st: dict, base_raw: dict, scenario_path: str,
                     folder: Path) -> Calibration:
    """The calibrate keys of ``[study]`` (:data:`CALIBRATE_KEYS`), checked against the base
    scenario (with ``set`` applied) and the target's data."""
    for k in st:
        if k not in CALIBRATE_KEYS:
            err.fail(f"study.{k}", st[k], unknown(k, set(CALIBRATE_KEYS)).replace(
                "unknown key", 'not a key of a study of kind = "calibrate"'))
    base = scenario_from_dict(_copy(base_raw), scenario_path)
    target = _target(err, st, base_raw, base, folder)
    params = _parameters(err, st, base_raw, base, target)
    if target.kind == "adc1241":
        check_noise_ranges(err, target, params, base)
    objective = err.choice(st, "objective", OBJECTIVES,
                           "wls" if target.kind == "table" and target.se is None else "chi2")
    if objective == "chi2" and target.kind == "table" and target.se is None:
        err.fail("study.objective", "chi2", f"needs the measured standard errors: {target.path} "
                 f"has no {target.y}_se column; add it, or use \"wls\" (equal weights)")
    replicates = _replicates(err, st, target)
    opt = _optimiser(err, st)
    confidence = st.get("confidence", 0.95)
    if not isinstance(confidence, float) or not 0.5 <= confidence <= 0.999:
        err.fail("study.confidence", confidence, "must be a number in [0.5, 0.999] (the "
                 "intervals' two-sided level)")
    needed = len(params) + (1 if target.kind == "emva1288" else 0) + 1
    if target.n_points < needed:
        err.fail("study.target.path", target.path, f"{target.n_points} data points: fewer points "
                 f"than a fit needs ({needed}: one more than the {needed - 1} fitted "
                 "parameters, so that the fit has a residual to judge it by)")
    axes, metrics = (), ()
    if target.kind == "table" and not target.series:  # spec.py makes it a study.Axis
        axes, metrics = ((target.x, target.x_values),), (target.y,)
    return Calibration(params, target, objective, replicates, *opt, confidence, axes, metrics)


def _copy(raw: dict) -> dict:
    import json

    return json.loads(json.dumps(raw))


def _target(err: Errors, st: dict, base_raw: dict, base, folder: Path
            ) -> TableTarget | EmvaTarget | AdcTarget:
    t = st.get("target", dataclasses.MISSING)
    if not isinstance(t, dict):
        err.fail("study.target", t, "a [study.target] table is required: kind = \"table\" (a "
                 "CSV), \"emva1288\" (a data set's folder) or \"adc1241\" (an ADC bench's "
                 "folder), and its path")
    kind = t.get("kind", dataclasses.MISSING)
    if kind in NOT_BUILT:
        err.fail("study.target.kind", kind, f"not built yet: {NOT_BUILT[kind]}; targets "
                 "supported: " + ", ".join(TARGET_KINDS))
    if kind not in TARGET_KINDS:
        err.fail("study.target.kind", kind, "must be one of " + ", ".join(map(repr,
                                                                             TARGET_KINDS)))
    allowed = TARGET_KEYS[kind]
    for k in t:
        if k not in allowed:
            err.fail(f"study.target.{k}", t[k], unknown(k, set(allowed)))
    given = t.get("path", dataclasses.MISSING)
    if not isinstance(given, str) or not given:
        err.fail("study.target.path", given, "must be a path (text), relative to the study "
                 "file or absolute")
    path = Path(_expand(err, given))
    path = path if path.is_absolute() else folder / path
    if kind == "emva1288":
        return read_emva(err.source, "study.target.path", given, path, _pitch(err, t),
                         _max_pixels(err, t))
    if kind == "adc1241":
        return read_adc1241(err.source, "study.target.path", given, path, base,
                            _max_converters(err, t))
    x, y, rule = _table_columns(err, t, base_raw, base)
    if not path.is_file():
        err.fail("study.target.path", given, f"no such file: looked for {path.resolve()}")
    target = read_table(path, x, y, rule)
    if target.series:
        late = [v for v in target.x_values if v > base.run.duration_s]
        if late:
            err.fail("study.target.path", given, f"{path.name}: time {late[0]} s is after the "
                     f"scenario's run ({base.run.duration_s} s): a time series is of one run")
    return target


def _table_columns(err: Errors, t: dict, base_raw: dict, base) -> tuple[str, str, Any]:
    """The table's x and y: a scenario key and a metric of kind mean, or time and a series."""
    x, y = t.get("x", dataclasses.MISSING), t.get("y", dataclasses.MISSING)
    if not isinstance(x, str):
        err.fail("study.target.x", x, 'must be a scenario key (e.g. "chip.adc.bits") or '
                 '"time"')
    if not isinstance(y, str):
        err.fail("study.target.y", y, "must be a metric name, or \"light\" with x = \"time\"")
    if x == "time":
        if y not in SERIES:
            err.fail("study.target.y", y, "with x = \"time\" (a time series of one run): one of "
                     + ", ".join(f"{k} [{u}] ({why})" for k, (u, why) in SERIES.items()))
        return x, y, None
    rule = check_key(err, "study.target.x", x, base_raw)
    if rule.metadata.get("choices") or rule.metadata.get("kind") not in (float, int):
        err.fail("study.target.x", x, f"is not a number ({allowed_text(rule)}); x is a "
                 "numeric scenario key, or \"time\"")
    means = sorted(n for n, m in CATALOGUE.items() if m.kind == "mean")
    if y not in means:
        err.fail("study.target.y", y, "must be a metric with a number per run: one of "
                 + ", ".join(means) + (" (a rate or a loss is not a fit target yet)"
                                       if y in CATALOGUE else ""))
    problem = check_metric_applies(y, base, SimpleNamespace(axes=()))
    if problem:
        err.fail("study.target.y", y, problem)
    return x, y, rule


def _pitch(err: Errors, t: dict) -> float | None:
    v = t.get("pixel_pitch_um")
    if v is not None and (not isinstance(v, int | float) or isinstance(v, bool)
                          or not 0.1 <= v <= 1.0e4):
        err.fail("study.target.pixel_pitch_um", v, "must be a number in [0.1, 1e4] µm")
    return None if v is None else float(v)


def _max_pixels(err: Errors, t: dict) -> int | None:
    v = t.get("max_pixels")
    if v is not None and (type(v) is not int or not MIN_REPLAY_PIXELS <= v <= 2**31):
        err.fail("study.target.max_pixels", v, f"must be an integer ≥ {MIN_REPLAY_PIXELS} (the "
                 "pixels of the twin read per image)")
    return v


def _max_converters(err: Errors, t: dict) -> int | None:
    v = t.get("max_converters")
    if v is not None and (type(v) is not int or not 2 <= v <= 2**16):
        err.fail("study.target.max_converters", v, "must be an integer ≥ 2 (the converters "
                 "compared)")
    return v


def _parameters(err: Errors, st: dict, base_raw: dict, base, target) -> tuple[FitParameter, ...]:
    tables = table_list(err, st, "parameter")
    if not tables:
        err.fail("study.parameter", dataclasses.MISSING, "at least one [[study.parameter]] is "
                 "required: a numeric scenario key, its range and why")
    fixed = set(inline_table(err, st, "set"))
    out: list[FitParameter] = []
    for i, t in enumerate(tables):
        taken = {k: "is fixed by study.set: fit it or set it, not both" for k in fixed}
        taken.update({p.key: "is listed twice" for p in out})
        if target.kind == "table" and not target.series:
            taken[target.x] = "is the table's x: each row sets it"
        out.append(_parameter(err, f"study.parameter[{i}]", t, base_raw, base, taken))
    return tuple(out)


def _parameter(err: Errors, where: str, t: dict, base_raw: dict, base,
               taken: dict[str, str]) -> FitParameter:
    key, rule, r = numeric_range(err, where, t, set(PARAMETER_KEYS), base_raw, taken,
                                 "a fitted key is a number or an integer, not a choice or a "
                                 "switch")
    kind = rule.metadata.get("kind")
    if kind is int and not all(float(x).is_integer() for x in r):
        err.fail(f"{where}.range", r, f"{key} is an integer: its range ends are integers")
    lo, hi = (float(in_rule(err, f"{where}.range", r, rule, key, x)) for x in r)
    wide = lo > 0 and hi / lo > LOG_RATIO
    scale = t.get("scale", "log" if wide else "lin")
    if scale not in ("lin", "log"):
        err.fail(f"{where}.scale", scale, "must be \"lin\" or \"log\"")
    if scale == "log" and lo <= 0:
        err.fail(f"{where}.scale", scale, f"{key}: a log scale needs lo > 0 (range {r})")
    why = t.get("why", dataclasses.MISSING)
    if not isinstance(why, str) or not why.strip():
        err.fail(f"{where}.why", why, f"{key}: say why the range is physically meaningful "
                 "and where its ends come from (text)")
    ref: Any = base
    for part in key.split("."):
        ref = getattr(ref, part)
    return FitParameter(key, lo, hi, scale == "log", kind is int, why.strip(), float(ref))


def _replicates(err: Errors, st: dict, target) -> int:
    if target.kind == "table" and not target.series:
        return err.integer(st, "replicates", 2, 1000, "runs per x value and candidate: their "
                           "spread is the simulated mean's standard error", default=4)
    if "replicates" in st:
        err.fail("study.replicates", st["replicates"], "applies to a table target with a "
                 "scenario key as x; " + {"emva1288": "an EMVA replay's statistics carry "
                                          "their own standard errors", "adc1241": "a "
                                          "bench's transition noise carries its own standard "
                                          "error"}.get(target.kind, "a time series of the "
                                                       "kinetics draws nothing"))
    return 1


def _optimiser(err: Errors, st: dict) -> tuple[int, int, float]:
    opt = st.get("optimiser", {})
    if not isinstance(opt, dict):
        err.fail("study.optimiser", opt, "must be an inline table { popsize = 8, generations = "
                 "40, tol = 0.01 }")
    for k in opt:
        if k not in ("popsize", "generations", "tol"):
            err.fail(f"study.optimiser.{k}", opt[k], unknown(k, {"popsize", "generations",
                                                                 "tol"}))
    out = []
    for k, lo, hi, default in (("popsize", 4, 50, 8), ("generations", 1, 1000, 40)):
        v = opt.get(k, default)
        if type(v) is not int or not lo <= v <= hi:
            err.fail(f"study.optimiser.{k}", v, f"must be an integer in [{lo}, {hi}]")
        out.append(v)
    tol = opt.get("tol", 0.01)
    if not isinstance(tol, float) or not 0.0 < tol <= 1.0:
        err.fail("study.optimiser.tol", tol, "must be a number in (0, 1]")
    return out[0], out[1], tol
