"""An IEEE 1241 ADC bench's output as a fit's target: each converter's transition noise.

``[study.target] kind = "adc1241"`` names the folder that ``chiptwin characterize SCENARIO --adc
--out DIR`` writes (or a converter's own bench written in its layout): its ``adc1241.json``
holds, per measured converter, the **transition noise** (the rms over the swept transitions of
each transition's Gaussian width, from repeated conversions of DC levels across mid-scale:
:func:`chiptwin.characterize.adc1241.transition_noise`) with its standard error, and the DC
sweep it was measured with. That figure is the one the comparator's noise sets:

- the ramp histogram does not see it: with Gaussian noise the share of a uniform ramp's samples
  below each transition is unchanged (the bench's own note), so DNL, INL, offset and gain carry
  none of it;
- the sine fit's SINAD and ENOB carry it, but mixed with the quantisation and with the ramp's
  INL and distortion: a fit to them would move the noise to absorb any INL the twin lacks.

The measured vector is one transition noise per converter (LSB of the ideal converter,
input-referred). The simulated side is the same test on the same converters: the scenario's chip
at the candidate's values (:func:`chiptwin.twin.runner.chip_sensor`, the converters at the
measured pixels: :func:`~chiptwin.characterize.adc1241.bench.sub_converter`), driven by the
measured bench's DC sweep (its levels, step, margin and conversions per level, around the same
mid-scale transitions), its codes fitted by the same estimator. Two differences, both stated:

- the sweep is placed on the twin's configured transition levels
  (:func:`~chiptwin.characterize.adc1241.bench.configured_transitions_V`), not on levels
  measured by a ramp first: the ramp only places the sweep, which covers the transitions with
  a margin of several σ either way, and skipping it (and the sine) makes an evaluation four
  times cheaper (measured: 0.21 s against the whole bench's 0.87 s, 32 of pyro_1fmol's
  converters, one process);
- every candidate draws its comparator noise from one stream,
  ``stage_rng(row_seed(study seed, …), "calibrate.adc1241")``, one normal per conversion
  whatever the noise's size (:meth:`chiptwin.pixel.Converter.convert`): common random numbers,
  so two candidates differ by their noise, not by their draws. The sweep does not depend on
  the candidate (it is the measured one's). The whole bench, run at each candidate, would
  not keep them common: it sizes its ramp's overdrive and its sweep from the configured
  noise, so a candidate's noise moves every later draw and the objective jumps by the
  statistics' own noise.

Each converter's residual is ``(sim − meas)/√(se_meas² + se_sim²)`` (:mod:`.calibrate_data`).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from chiptwin.config import ScenarioError
from chiptwin.study.calibrate_data import Measured
from chiptwin.study.calibrate_targets import file_hash

JSON_NAME = "adc1241.json"
#: Fewest converters a target compares (one more than a one-key fit needs).
MIN_CONVERTERS: int = 2
#: Keys of the comparator's noise whose fitted range is checked against what the measured sweep
#: resolves (:func:`check_noise_ranges`).
NOISE_KEYS = ("chip.adc.comparator_noise_lsb", "chip.adc.comparator_noise_uV")
#: Seconds of one simulated conversion and of one converter's transition-noise fit, for the
#: wall-time estimate: measured 17 ns and 6.0 ms (128 converters × 115 levels × 200
#: conversions, pyro_1fmol's chip; 2-core machine, one process).
S_PER_CONVERSION: float = 1.7e-8
S_PER_CONVERTER: float = 6.0e-3


@dataclass(frozen=True)
class AdcPlan:
    """The measured bench's DC sweep and the converters compared: what the twin is read with.

    ``pixels``: the converters' flat indices on the array; ``first``/``last``: the mid-scale
    transitions the sweep straddles; ``step_lsb``, ``margin_lsb``, ``levels``, ``repeats``: its
    levels ``T[first] + (−margin + i·step)·slope``, i < levels, each converted ``repeats``
    times (slope: the converter's mean code width between ``first`` and ``last``)."""

    pixels: tuple[int, ...]
    bits: int
    v_min_V: float
    v_max_V: float
    first: int
    last: int
    step_lsb: float
    margin_lsb: float
    levels: int
    repeats: int

    @property
    def conversions(self) -> int:
        return len(self.pixels) * self.levels * self.repeats

    @property
    def resolved_lsb(self) -> tuple[float, float]:
        """The noise the sweep resolves: a level step at most σ, and ±4σ of the swept
        transitions inside the margin (:func:`chiptwin.characterize.adc1241.transition_noise`
        keeps only such transitions). LSB."""
        return self.step_lsb, self.margin_lsb / 4.0


@dataclass(frozen=True)
class AdcTarget:
    """An IEEE 1241 bench's transition noise per converter (``values`` ± ``se``, LSB)."""

    path: str
    hash: str
    scenario: str
    plan: AdcPlan
    values: tuple[float, ...]
    se: tuple[float, ...]
    measured: int = 0  # converters the bench measured (values: those compared)
    unresolved: int = 0  # of the compared, left out: no transition noise resolved
    kind: str = "adc1241"

    @property
    def n_points(self) -> int:
        return len(self.values)

    def describe(self) -> str:
        p = self.plan
        left = f", {self.unresolved} left out (not resolved)" if self.unresolved else ""
        return (f"IEEE 1241 bench {Path(self.path).name} ({self.scenario}): transition noise of "
                f"{self.n_points} of its {self.measured} converters{left}, each ± its standard "
                f"error; DC sweep of {p.levels} levels every {p.step_lsb:.4g} LSB across "
                f"transitions {p.first}…{p.last}, {p.repeats} conversions each")


def read_adc1241(src: str, where: str, given: str, path: Path, base: Any,
                 max_converters: int | None) -> AdcTarget:
    """The bench's folder (or its ``adc1241.json``) read and checked against the base scenario
    (its converter's bits and range, its array); ``max_converters``: compare at most that many
    of the measured converters, evenly spaced over them (None: all)."""
    file = path if path.is_file() else path / JSON_NAME
    if not file.is_file():
        raise ScenarioError(src, where, given, f"no IEEE 1241 bench output there: looked for "
                            f"{file.resolve()} (chiptwin characterize SCENARIO --adc --out DIR "
                            "writes it; name the folder, relative to this study file or absolute)")
    try:
        doc = json.loads(file.read_text(encoding="utf-8"))
        plan, values, se, measured, unresolved = _parse(doc, max_converters)
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ScenarioError(src, where, given, f"{file.name} is not an IEEE 1241 bench's "
                            f"adc1241.json ({type(exc).__name__}: {exc})") from None
    _check_converter(src, where, given, plan, base, doc)
    if len(values) < MIN_CONVERTERS:
        raise ScenarioError(src, where, given, f"{len(values)} converter(s) with a resolved "
                            f"transition noise, of {measured} measured: a fit needs at least "
                            f"{MIN_CONVERTERS} (a noise below the sweep's step "
                            f"{plan.step_lsb:g} LSB is not resolved: the bench's own NaN)")
    return AdcTarget(str(file.parent), file_hash([file], file.parent), str(doc["scenario"]),
                     plan, values, se, measured, unresolved)


def _parse(doc: dict[str, Any], max_converters: int | None
           ) -> tuple[AdcPlan, tuple[float, ...], tuple[float, ...], int, int]:
    sweep = doc["bench"]["transition_noise"]
    rows = doc["converters"]
    int(doc["bench"]["converters_on_chip"])
    for r in rows:  # where each converter sits (checked against the scenario's array)
        int(r["pixel"]), int(r["row"]), int(r["col"])
    pick = np.arange(len(rows)) if max_converters is None or len(rows) <= max_converters else \
        np.unique(np.round(np.linspace(0, len(rows) - 1, max_converters)).astype(int))
    chosen = [rows[i] for i in pick]
    ok = [r for r in chosen if _finite(r.get("transition_noise_lsb"))
          and _finite(r.get("transition_noise_lsb_sigma"))
          and r["transition_noise_lsb_sigma"] > 0]
    plan = AdcPlan(tuple(int(r["pixel"]) for r in ok), int(doc["bits"]), float(doc["v_min_V"]),
                   float(doc["v_max_V"]), int(sweep["first_transition"]),
                   int(sweep["last_transition"]), float(sweep["step_lsb"]),
                   float(sweep["margin_lsb"]), int(sweep["levels"]), int(sweep["repeats"]))
    if plan.levels < 4 or plan.repeats < 2 or not plan.last >= plan.first >= 1:
        raise ValueError(f"the DC sweep {sweep} is not one the bench makes")
    return (plan, tuple(float(r["transition_noise_lsb"]) for r in ok),
            tuple(float(r["transition_noise_lsb_sigma"]) for r in ok), len(rows),
            len(chosen) - len(ok))


def _finite(x: Any) -> bool:
    return isinstance(x, int | float) and math.isfinite(x)


def _check_converter(src: str, where: str, given: str, plan: AdcPlan, base: Any,
                     doc: dict[str, Any]) -> None:
    """The bench's converter is the scenario's: bits, range, and its array (as many
    converters, each pixel at its row and column)."""
    adc = base.chip.adc
    for key, bench, own in (("bits", plan.bits, adc.bits), ("v_min_V", plan.v_min_V,
                                                            adc.v_min_V),
                            ("v_max_V", plan.v_max_V, adc.v_max_V)):
        if bench != own:
            raise ScenarioError(src, where, given, f"the bench measured a converter with {key} "
                                f"= {bench!r}, the scenario's chip.adc.{key} is {own!r}: the "
                                "twin is compared with the converter measured; set "
                                f"chip.adc.{key} = {bench!r} (study.set)")
    rows, cols = int(base.chip.rows), int(base.chip.cols)
    on_chip = doc["bench"].get("converters_on_chip")
    placed = all(c["pixel"] == c["row"] * cols + c["col"] for c in doc["converters"])
    if on_chip != rows * cols or not placed:
        raise ScenarioError(src, where, given, f"the bench measured a chip of {on_chip} "
                            "converters" + ("" if placed else f" not {cols} columns wide")
                            + f"; the scenario's chip is {rows} × {cols}: the array must be "
                            "the one measured (the converters are compared pixel by pixel)")


def check_noise_ranges(err: Any, target: AdcTarget, params: tuple, base: Any) -> None:
    """A fitted comparator-noise key's range inside what the measured sweep resolves
    (:attr:`AdcPlan.resolved_lsb`): outside it the twin's own transition noise is not resolved
    by that sweep (its candidates would be refused one by one)."""
    adc = base.chip.adc
    lsb_uV = (adc.v_max_V - adc.v_min_V) / 2**adc.bits * 1e6
    lo_ok, hi_ok = target.plan.resolved_lsb
    for i, p in enumerate(params):
        if p.key not in NOISE_KEYS:
            continue
        ends = [_total_lsb(adc, p.key, x) for x in (p.lo, p.hi)]
        if ends[0] < lo_ok * (1 - 1e-9) or ends[1] > hi_ok * (1 + 1e-9):
            per = "" if p.key.endswith("_lsb") else f" ({lo_ok * lsb_uV:.4g} … " \
                f"{hi_ok * lsb_uV:.4g} µV here)"
            err.fail(f"study.parameter[{i}].range", [p.lo, p.hi],
                     f"{p.key}: the range is {ends[0]:.4g} … {ends[1]:.4g} LSB of comparator "
                     f"noise; the bench's DC sweep (step {target.plan.step_lsb:.4g} LSB, margin "
                     f"{target.plan.margin_lsb:.4g} LSB) resolves {lo_ok:.4g} … {hi_ok:.4g} "
                     f"LSB{per}: keep the range inside it, or measure with a sweep sized for "
                     "the noise (the bench sizes it from the configured noise)")


def _total_lsb(adc: Any, key: str, x: float) -> float:
    """The comparator noise in LSB with ``key`` (one of :data:`NOISE_KEYS`) at ``x``, the other
    key at the scenario's value (the converter adds the two)."""
    import dataclasses

    return dataclasses.replace(adc, **{key.rsplit(".", 1)[1]: x}).comparator_noise_total_lsb


def adc_measured(t: AdcTarget) -> Measured:
    """The measured vector: each compared converter's transition noise; x its pixel."""
    n = t.n_points
    return Measured(values=np.asarray(t.values), se=np.asarray(t.se),
                    block=np.zeros(n, dtype=np.int64), block_names=("transition noise [LSB]",),
                    offset=np.zeros(n, dtype=bool), x=np.asarray(t.plan.pixels, dtype=float),
                    x_label="converter (pixel, flat index)")


def candidate_seconds(plan: AdcPlan) -> float:
    """Estimated seconds of one candidate (:data:`S_PER_CONVERSION`, :data:`S_PER_CONVERTER`)."""
    return S_PER_CONVERSION * plan.conversions + S_PER_CONVERTER * len(plan.pixels)


def adc_stats(scenario: Any, plan: AdcPlan, rng: np.random.Generator
              ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The twin's transition noise at the plan's converters and its standard errors (LSB);
    a converter whose noise the sweep does not resolve refuses the candidate."""
    from chiptwin.characterize.adc1241.bench import configured_transitions_V, sub_converter
    from chiptwin.twin.runner import chip_sensor

    whole = chip_sensor(scenario).converter
    if (whole.bits, whole.v_min_V, whole.v_max_V) != (plan.bits, plan.v_min_V, plan.v_max_V):
        raise ScenarioError(scenario.source, "chip.adc", (whole.bits, whole.v_min_V,
                                                          whole.v_max_V),
                            f"the measured converter is {plan.bits} bits over "
                            f"{plan.v_min_V:g} … {plan.v_max_V:g} V: a fit moves its noise, "
                            "not its bits or range")
    pixels = np.asarray(plan.pixels, dtype=np.int64)
    conv, _ = sub_converter(whole, pixels)
    levels = sweep_levels(configured_transitions_V(conv, pixels.size), plan)
    return sweep_noise(conv, levels, plan.repeats, rng, scenario.source)


def sweep_levels(t_V: NDArray[np.float64], plan: AdcPlan) -> NDArray[np.float64]:
    """The DC levels of each converter, ``(levels, n)`` (V): from ``margin`` below its
    ``T[first]`` every ``step`` of its mean code width (``t_V`` column j is T[j + 1])."""
    a, b = t_V[:, plan.first - 1], t_V[:, plan.last - 1]
    width = (b - a) / (plan.last - plan.first) if plan.last > plan.first else \
        np.full(a.shape, (plan.v_max_V - plan.v_min_V) / 2**plan.bits)
    # as the bench's np.arange from −margin (its own rounding, so the same volts bit for bit)
    x = np.arange(-plan.margin_lsb, -plan.margin_lsb + (plan.levels - 0.5) * plan.step_lsb,
                  plan.step_lsb)[:plan.levels]
    return a[None, :] + x[:, None] * width[None, :]


def sweep_noise(conv: Any, levels: NDArray[np.float64], repeats: int, rng: np.random.Generator,
                source: str = "") -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Each converter's transition noise ± its standard error from ``repeats`` conversions at
    each of its ``levels`` ``(L, n)``, drawn in C order of (level, repeat, converter)."""
    from chiptwin.characterize.adc1241.noise import transition_noise

    n_levels, n = levels.shape
    codes = conv.convert(np.repeat(levels, repeats, axis=0), rng).reshape(n_levels, repeats, n)
    values, se = np.empty(n), np.empty(n)
    for i in range(n):
        tn = transition_noise(levels[:, i], codes[:, :, i], conv.bits, conv.v_min_V,
                              conv.v_max_V)
        values[i], se[i] = tn.transition_noise_lsb, tn.transition_noise_sigma_lsb
    if not (np.all(np.isfinite(values)) and np.all(se > 0)):
        raise ScenarioError(source, "chip.adc.comparator_noise", conv.comparator_noise_lsb,
                            f"LSB: the measured DC sweep does not resolve this noise at "
                            f"{int(np.sum(~np.isfinite(values)))} of {n} converters (its step "
                            "or margin): this candidate is outside what the data can test")
    return values, se


__all__ = ["AdcPlan", "AdcTarget", "adc_measured", "adc_stats", "check_noise_ranges",
           "read_adc1241", "sweep_levels", "sweep_noise"]
