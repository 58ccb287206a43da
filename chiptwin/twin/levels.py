"""The fidelity levels of each stage, and ``auto``'s choice among them from estimated errors.

A ``[run.fidelity]`` key set to ``"auto"`` is resolved before the run
(docs/background/speed-and-error.md). The error of a level is taken against the stage's most
faithful level the scene accepts (the ladder's reference, :func:`reference_levels`), figure by
figure (the ones
``[run] error_budget`` names, :data:`chiptwin.config.schema.BUDGET_FIGURES`):

* **kinetics** (closed_form vs cascade) and **optics** (na2 and psf vs raytrace where the scene
  accepts it, else na2 vs psf): a calibration, the scene
  run at the ``expected`` photon level (no draws, so the difference is the level's systematic
  error, exact on this scene) at both levels. Cached per scene hash in SQLite
  (``$XDG_CACHE_HOME/chiptwin/fidelity.sqlite``), so it is paid once. The optics reason also
  states the psf coupling's off-diagonal share at the site pixels: the cross-talk na2 misses.
* **photons**: ``events`` reads ``binned``'s counts (the same draws; it adds only the time each
  site pixel's well filled), so ``binned`` costs 0 against ``events``. ``expected`` draws
  nothing: it reports each figure's mean, where the reference's figure is spread around it;
  its error is how far the reference's figure strays, :data:`EXPECTED_SDS` standard
  deviations (the site signal's ``signal_sd_e``, a flow value's spread, a DSP output's noise).
* **shot** (gaussian vs poisson): what the rounded normal changes in the figures
  (:func:`gaussian_moment_errors`): a window total is a weighted sum of pixel-frame counts,
  light frames minus the dark reference, so its mean moves by at most ``2F·sup|E − λ|`` and its
  variance by at most ``2F²·sup|Var − λ|`` over the means ``λ ≥`` the smallest a site pixel
  holds in a frame (``F`` the window sum's gain in frames); the noise figure is propagated from
  the Poisson moments at both levels, so it does not move at all. The power SNR's mean moves by
  ``(2SΔm + Δm² + ΔVar)/S²``. The total-variation distance (:func:`gaussian_tv`), charged here
  before, bounds any probability of a count but overstated these moments ≈ 100-fold.
* **adc** (ideal vs as_built): exact 0 when ``[chip.adc]`` sets no as-built effect (the two
  levels are one converter); otherwise a calibration like kinetics and optics: the scene at the
  expected level with the converter as built (its transition tables summed against the
  Gaussian, :func:`chiptwin.pixel.cms_moments`) and with every effect zeroed.
* **dsp**: ``rtl`` equals ``fixed`` bit for bit (co-simulated, ``tests/rtl``); ``fixed`` differs
  from ``float`` by the chain's rounding (half an output LSB per rounding step, 0 when M, K and N
  are powers of two) and the program's further stages' bounds, per DSP output, carried to the
  window total the detection reads by the window sum's gain (N × the outputs in a window for
  the plain sum; :func:`chiptwin.fidelity.auto.window_gain`), unless the N-frame accumulator is
  narrower than its exact width (``[chip.dsp] acc_bits``), where it can wrap: unbounded.

An error is a distance between the laws of a figure at the two levels, not between two draws:
a level that samples the reference's law (binned for events) costs nothing even though its draws
differ; one that replaces the law by its mean (expected) costs the spread it leaves out.

This module holds the levels, the errors of the figures, the choice and the estimates cache; it
runs nothing. The calibration runs that fill the cache sit above the twin, in
:mod:`chiptwin.fidelity.auto` (:class:`~chiptwin.fidelity.auto.Calibrations`).

Errors of different stages add (the triangle inequality, an upper estimate); stages are chosen
in :data:`ORDER` (largest savings first on the ladder), each taking the cheapest level that keeps
every budgeted figure's total within the budget: its levels are tried in the order of the
scenario's estimated wall time at each (:func:`chiptwin.config.cost.wall_seconds`), not in
:data:`LEVELS`' order (under a top surface, over sites with a footprint, ``raytrace`` reads the
matrix it traced once where ``psf`` integrates the light over the footprints: luciferase_label
runs in 0.15 s at raytrace, 0.26 s at psf). Non-``auto`` stages' errors count against the
budget too.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import math
import sqlite3
import time
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from scipy import special

from chiptwin import __version__
from chiptwin.config import Scenario, ScenarioError
from chiptwin.config.consistency import check_consistency
from chiptwin.config.cost import format_seconds, wall_seconds
from chiptwin.config.schema import BUDGET_FIGURES, Adc

#: The levels of each stage, least faithful first (the last is the reference where the scene
#: accepts it: optics ``raytrace`` needs contact imaging and a physical emitter law, else ``psf``).
#: ``auto`` tries them cheapest first by the wall-time estimate; equal estimates keep this order.
LEVELS: dict[str, tuple[str, ...]] = {
    "kinetics": ("closed_form", "cascade"),
    "photons": ("expected", "binned", "events"),
    "optics": ("na2", "psf", "raytrace"),
    "shot": ("gaussian", "poisson"),
    "dsp": ("float", "fixed", "rtl"),
    "adc": ("ideal", "as_built"),
}


#: The order stages are chosen in: the largest saving first (ladder of pyro_1fmol: cascade
#: 2.6×, rtl DSP and events photons next; optics and shot noise save least).
ORDER = ("kinetics", "dsp", "photons", "adc", "optics", "shot")


#: How many standard deviations of the reference's figure the ``expected`` level is charged:
#: the reference's figure lies within 3 σ of the mean the expected level reports 99.7 % of the
#: time (normal figures: sums of many pixel-frames).
EXPECTED_SDS = 3.0


#: Budget figures in a fixed order.
FIGURES = tuple(BUDGET_FIGURES)


#: Above this mean the TV distance is scaled as 1/√λ from its value here (the Edgeworth term:
#: the normal misses the Poisson skewness 1/√λ), instead of summed over ≈ 80 √λ counts. Unit: e⁻.
TV_SUM_MAX_MEAN = 1e6


def with_levels(s: Scenario, levels: dict[str, str]) -> Scenario:
    """``s`` at the given stage levels (the DSP level set on the chip, as ``chip.dsp.mode``)."""
    fid = replace(s.run.fidelity, **{k: v for k, v in levels.items() if k != "dsp"}, dsp="")
    chip = replace(s.chip, dsp=replace(s.chip.dsp, mode=levels.get("dsp", s.dsp_level)))
    if fid.adc == "ideal":
        chip = replace(chip, adc=ideal_adc(chip.adc))
    return replace(s, run=replace(s.run, fidelity=fid), chip=chip)


def ideal_adc(adc: Adc) -> Adc:
    """``[chip.adc]`` with every as-built effect zeroed: today's rounding converter (the nominal
    range, offset and gain error stay)."""
    return replace(adc, comparator_noise_lsb=0.0, comparator_noise_uV=0.0, inl_max_lsb=0.0,
                   inl_shape="quadratic", inl_table="", dnl_rms_lsb=0.0, offset_sigma_lsb=0.0,
                   gain_sigma=0.0)


def reference_levels(s: Scenario) -> dict[str, str]:
    """The most faithful level of each stage that this scene accepts."""
    out = {}
    for stage, levels in LEVELS.items():
        for level in reversed(levels):
            try:
                check_consistency(with_levels(s, {**out, stage: level}))
            except ScenarioError:
                continue
            out[stage] = level
            break
    return out


def figures(sm: dict[str, Any], a: dict[str, np.ndarray], e_per_lsb: float
            ) -> dict[str, np.ndarray]:
    """The headline figures of one run (its summary and arrays) that the ladder and the
    calibrations compare between levels."""
    out = {name: np.array([site[key] for site in sm["sites"]]) for name, key in
           (("signal", "signal_e"), ("noise", "noise_e"), ("snr", "snr_power"))}
    out["dsp"] = a["site_signal_e"] / e_per_lsb
    if "flow_values" in a:
        out["flow_values"] = a["flow_values"]
        out["reads"] = np.array(sm["called_sequences"])
    return out


#: Sites whose relative figures the ladder compares: power SNR ≥ 10 in the reference (the
#: default detection threshold, ``run.detection_snr_power``): a relative error of a site the
#: reference does not detect is the noise over the noise.
SEEN_SNR_POWER = 10.0


def figure_errors(level: dict[str, np.ndarray], ref: dict[str, np.ndarray]) -> dict[str, float]:
    """Each figure's error against the reference run with the same seed; relative figures over
    the sites the reference sees (:data:`SEEN_SNR_POWER`), inf when it sees none."""
    seen = ref["snr"] >= SEEN_SNR_POWER

    def rel(x, y):
        x, y = x[seen], y[seen]
        return float(np.max(np.abs(x - y) / np.abs(y))) if y.size else math.inf

    out = {"signal_rel": rel(level["signal"], ref["signal"]),
           "noise_rel": rel(level["noise"], ref["noise"]),
           "snr_rel": rel(level["snr"], ref["snr"])}
    with np.errstate(divide="ignore", invalid="ignore"):
        db = np.abs(10 * np.log10(level["snr"][seen] / ref["snr"][seen]))
    out["snr_db"] = float(np.max(db)) if db.size and np.all(np.isfinite(db)) else math.inf
    if level["dsp"].shape == ref["dsp"].shape:
        out["dsp_lsb"] = float(np.max(np.abs(level["dsp"] - ref["dsp"]), initial=0.0))
    if "flow_values" in ref:
        out["flow_value_abs"] = float(np.max(np.abs(level["flow_values"] - ref["flow_values"])))
        out["calls_diff"] = float(np.mean(level["reads"] != ref["reads"]))
    return out


def gaussian_tv(lam: float) -> float:
    """Total-variation distance between Poisson(λ) and ``max(0, rint(λ + √λ·z))``, z ~ N(0, 1).

    The ``gaussian`` shot level's law (:func:`chiptwin.pixel.binned_codes`). Exact sum over the
    counts within 40 σ of the mean (what lies beyond is below 1e-300); above
    :data:`TV_SUM_MAX_MEAN` the 1/√λ scaling of the leading term. ≈ 0.13/√λ: 0.004 at λ = 1000.
    """
    if not math.isfinite(lam) or lam < 0:
        raise ValueError(f"lam = {lam!r}: must be a finite mean ≥ 0")
    if lam == 0.0:
        return 0.0  # both laws are the point mass at 0
    if lam > TV_SUM_MAX_MEAN:
        return gaussian_tv(TV_SUM_MAX_MEAN) * math.sqrt(TV_SUM_MAX_MEAN / lam)
    sd = math.sqrt(lam)
    lo, hi = max(0, int(lam - 40 * sd - 10)), int(lam + 40 * sd + 10)
    k = np.arange(lo, hi + 1)
    # scipy.stats.poisson.pmf and norm.cdf, bit for bit, without importing scipy.stats (≈ 0.6 s
    # of every process that imports the runner)
    p = np.exp(special.xlogy(k, lam) - special.gammaln(k + 1) - lam)
    upper = special.ndtr((k + 0.5 - lam) / sd)
    lower = np.where(k == 0, 0.0, special.ndtr((k - 0.5 - lam) / sd))
    return float(0.5 * np.sum(np.abs(p - (upper - lower))))


def gaussian_moment_errors(lam: float) -> tuple[float, float]:
    """How the ``gaussian`` shot level's count ``max(0, rint(λ + √λ·z))`` differs from
    Poisson(λ) in the two moments the figures read: ``(E − λ, Var − λ)``. Unit: e⁻, e⁻².

    Exact sums over the rounded normal's law (the mass below ½ at 0). For λ ≳ 10 the mean is
    Poisson's to ``exp(−λ/2)`` (the clip at 0) and the variance exceeds it by Sheppard's 1/12
    (the rounding; Kendall & Stuart, *The Advanced Theory of Statistics* I, §3.18); below, the
    clip lifts the mean (by at most 0.081 e⁻, at λ ≈ 0.5) and narrows the law (by at most
    0.173 e⁻², at λ ≈ 1.6).
    """
    if not math.isfinite(lam) or lam < 0:
        raise ValueError(f"lam = {lam!r}: must be a finite mean ≥ 0")
    if lam == 0.0:
        return 0.0, 0.0
    if lam > TV_SUM_MAX_MEAN:
        return 0.0, 1 / 12
    sd = math.sqrt(lam)
    k = np.arange(0, int(lam + 40 * sd + 20), dtype=float)
    p = special.ndtr((k + 0.5 - lam) / sd) - special.ndtr((k - 0.5 - lam) / sd)
    p[0] = special.ndtr((0.5 - lam) / sd)
    mean = float(np.dot(k, p))
    return mean - lam, float(np.dot(k * k, p) - mean * mean) - lam


def gaussian_moment_bounds(lam_min: float) -> tuple[float, float]:
    """``(sup |E − λ|, sup |Var − λ|)`` of :func:`gaussian_moment_errors` over every mean
    ``λ ≥ lam_min``: a grid of 241 means from ``lam_min`` to 100 e⁻ (both errors are smooth in
    λ) and, beyond, their limits 0 and 1/12 (reached to 1e-12 by λ = 100): from a ``lam_min``
    past 100 e⁻, that mean alone (241 copies of it, each an exact sum over ≈ λ + 40√λ counts,
    took 6.7 s of auto's resolution of pyro_1fmol, whose dimmest site mean is 25,683 e⁻)."""
    lo = max(lam_min, 1e-3)
    grid = np.geomspace(lo, 100.0, 241) if lo < 100.0 else np.array([lo])
    errs = np.array([gaussian_moment_errors(float(x)) for x in grid])
    return float(np.max(np.abs(errs[:, 0]))), float(max(np.max(np.abs(errs[:, 1])), 1 / 12))


@dataclass
class Estimate:
    """The error one level adds on this scene: figure → error, and how it was found."""

    errors: dict[str, float]
    how: str

    @classmethod
    def exact(cls, how: str) -> Estimate:
        """No error: the level is the reference, or provably gives the reference's law."""
        return cls(dict.fromkeys(FIGURES, 0.0), how)


@dataclass
class AutoChoice:
    """What ``auto`` picked: the levels, why each, and the estimated error of the run."""

    levels: dict[str, str]
    reasons: dict[str, str]
    estimate: dict[str, float]
    budget: dict[str, float]
    calibration_s: float = 0.0
    cached: list[str] = field(default_factory=list)

    def summary(self) -> dict[str, Any]:
        """The ``summary.json`` entries ``fidelity_reason`` and ``fidelity_error_estimate``."""
        return {"fidelity_reason": self.reasons,
                "fidelity_error_estimate": {f: _round(v) for f, v in self.estimate.items()},
                "error_budget": self.budget}


def _round(v: float) -> float | None:
    return float(f"{v:.4g}") if math.isfinite(v) else None


class CachedEstimates:
    """Each level's :class:`Estimate` on one scene: exact where the level provably gives the
    reference's law, else read from the estimates cache. A level with no cached estimate needs a
    calibration run of the scene: :meth:`calibrate` refuses here; the subclass above the twin
    (:class:`chiptwin.fidelity.auto.Calibrations`) runs it."""

    def __init__(self, s: Scenario, ref: dict[str, str], cache: Path | None) -> None:
        self.s, self.ref, self.cache = s, ref, cache
        self.calibration_s = 0.0
        self.cached: list[str] = []

    def estimate(self, stage: str, level: str, levels: dict[str, str]) -> Estimate:
        """The error of ``level`` against the stage's reference, with the other stages at
        ``levels``; read from the cache when this scene's was computed before."""
        if stage == "shot" and levels.get("photons") == "expected":
            return Estimate.exact("the expected photon level draws no counts")
        if level == self.ref[stage]:
            return Estimate.exact("the most faithful level this scene accepts")
        if stage == "adc" and not self.s.chip.adc.as_built_keys:
            return Estimate.exact("the scene's converter is ideal: both levels are one converter")
        key = _scene_hash(self.s, stage, level, self.ref[stage])
        hit = _cache_get(self.cache, key)
        if hit is not None:
            self.cached.append(stage)
            return Estimate(hit["errors"], hit["how"] + " (cached)")
        t0 = time.perf_counter()
        est = self.calibrate(stage, level)
        self.calibration_s += time.perf_counter() - t0
        _cache_put(self.cache, key, {"errors": est.errors, "how": est.how})
        return est

    def calibrate(self, stage: str, level: str) -> Estimate:
        """The estimate of a level the cache does not hold: here, a refusal."""
        raise ScenarioError(self.s.source, f"run.fidelity.{stage}", "auto",
                            f"the error of {level!r} on this scene is not in the estimates "
                            "cache: resolve auto with chiptwin.fidelity.resolve (chiptwin.run "
                            "and the CLI do)")


def resolve(s: Scenario, cache: Path | None = None,
            estimates: type[CachedEstimates] | None = None
            ) -> tuple[Scenario, AutoChoice | None]:
    """``s`` with every ``auto`` stage set to a level, and the choice; ``(s, None)`` when no
    stage is ``auto``. ``cache`` is the estimates database (default in the user cache);
    ``estimates`` the class that finds each level's error (default :class:`CachedEstimates`,
    which reads the cache and refuses a scene it has no estimate for; the calibration runs that
    fill it are :func:`chiptwin.fidelity.resolve`'s, above the twin)."""
    auto = s.run.fidelity.auto_stages()
    if not auto:
        return s, None
    budget = s.run.error_budget.items()
    ref = reference_levels(s)
    estimator = (estimates or CachedEstimates)(s, ref, cache)
    chosen = {st: (s.dsp_level if st == "dsp" else getattr(s.run.fidelity, st))
              for st in LEVELS if st not in auto}
    total = dict.fromkeys(FIGURES, 0.0)
    reasons = {}
    for stage, level in chosen.items():  # the levels not left to auto spend budget too
        est = estimator.estimate(stage, level, {**ref, **chosen})
        _add(total, est.errors)
        spent = ", ".join(f"{f} {_fmt(est.errors.get(f, math.inf))}" for f in budget)
        reasons[stage] = f"{level} (not auto): {est.how} → {spent}"
    for stage in (st for st in ORDER if st in auto):
        refused, picked = [], None
        timed = _by_estimated_time(s, stage, ref, chosen)
        for level, _ in timed:
            trial = {**ref, **chosen, stage: level}
            est = estimator.estimate(stage, level, trial)
            over = [f for f, b in budget.items() if total[f] + est.errors.get(f, math.inf) > b]
            if not over or level == ref[stage]:
                picked = level
                break
            refused.append(f"not {level}: {est.how} → "
                           + ", ".join(f"{f} {_fmt(total[f] + est.errors[f])} > {budget[f]:g}"
                                       for f in over))
        if picked is None:
            raise ScenarioError(s.source, f"run.fidelity.{stage}", "auto",
                                "no level of this stage is consistent with the other stages' "
                                f"levels {chosen}")
        chosen[stage] = picked
        _add(total, est.errors)
        spent = ", ".join(f"{f} {_fmt(est.errors[f])}" for f in budget)
        tried = "tried by estimated time: " + ", ".join(f"{lv} {format_seconds(t)}"
                                                        for lv, t in timed)
        reasons[stage] = " | ".join([f"{picked}: {est.how} → {spent}", *refused, tried])
    chosen = {st: chosen[st] for st in LEVELS}
    resolved = with_levels(s, chosen)
    check_consistency(resolved)
    choice = AutoChoice(chosen, {st: reasons[st] for st in LEVELS}, total, budget,
                        estimator.calibration_s, estimator.cached)
    return resolved, choice


def _by_estimated_time(s: Scenario, stage: str, ref: dict[str, str], chosen: dict[str, str]
                       ) -> list[tuple[str, float]]:
    """The stage's levels up to its reference that are consistent with the levels chosen so far
    (the stages not yet chosen at their reference), each with the estimated wall time of the
    scenario at it (:func:`chiptwin.config.cost.wall_seconds`; the stages not yet chosen at
    their cheapest level, as the estimate takes ``auto``), cheapest first; ties keep
    :data:`LEVELS`' order (the sort is stable). Under a top surface, over sites with a
    footprint, ``raytrace`` comes before ``psf``: psf integrates each part of the light over the
    footprint, raytrace reads the matrix it traced once."""
    cheapest = {st: levels[0] for st, levels in LEVELS.items()}
    out = []
    for level in LEVELS[stage][: LEVELS[stage].index(ref[stage]) + 1]:
        try:
            check_consistency(with_levels(s, {**ref, **chosen, stage: level}))
        except ScenarioError:
            continue
        out.append((level, wall_seconds(with_levels(s, {**cheapest, **chosen, stage: level}))))
    return sorted(out, key=lambda lt: lt[1])


def _add(total: dict[str, float], spent: dict[str, float]) -> None:
    for f in total:
        total[f] += spent.get(f, math.inf)


def _fmt(v: float) -> str:
    return f"{v:.3g}" if math.isfinite(v) else "unbounded"


def cache_path() -> Path:
    """``$XDG_CACHE_HOME/chiptwin/fidelity.sqlite`` (default ``~/.cache/chiptwin/...``)."""
    from chiptwin._numba import user_cache_dir

    return user_cache_dir().parent / "fidelity.sqlite"


def _scene_hash(s: Scenario, stage: str, level: str, ref: str) -> str:
    """The scene's physics, without what does not change a calibration: the fidelity levels,
    the budget, the seed (the expected level draws nothing; the chip's fixed pattern moves the
    relative errors by far less than they are), the output options."""
    raw = dataclasses.asdict(s)
    raw["run"].pop("fidelity"), raw["run"].pop("error_budget"), raw["run"].pop("save_frames")
    raw["scenario"].pop("seed"), raw.pop("source")
    raw["chip"]["dsp"].pop("mode")
    text = json.dumps([__version__, stage, level, ref, raw], sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


@contextlib.contextmanager
def _connect(path: Path | None) -> Iterator[sqlite3.Connection]:
    """The estimates database in one transaction, closed after (sqlite3's own context manager
    commits but leaves the connection open)."""
    path = cache_path() if path is None else path
    path.parent.mkdir(parents=True, exist_ok=True)
    con = sqlite3.connect(path, timeout=30)
    try:
        with con:
            con.execute("CREATE TABLE IF NOT EXISTS estimates (key TEXT PRIMARY KEY, "
                        "estimate TEXT, created REAL)")
            yield con
    finally:
        con.close()


def _cache_get(path: Path | None, key: str) -> dict[str, Any] | None:
    with _connect(path) as con:
        row = con.execute("SELECT estimate FROM estimates WHERE key = ?", (key,)).fetchone()
    if row is None:
        return None
    hit = json.loads(row[0])
    hit["errors"] = {f: (math.inf if v is None else v) for f, v in hit["errors"].items()}
    return hit


def _cache_put(path: Path | None, key: str, estimate: dict[str, Any]) -> None:
    errors = {f: (v if math.isfinite(v) else None) for f, v in estimate["errors"].items()}
    text = json.dumps({**estimate, "errors": errors})
    with _connect(path) as con:
        con.execute("INSERT OR REPLACE INTO estimates VALUES (?, ?, ?)",
                    (key, text, time.time()))


def describe(choice: AutoChoice) -> list[str]:
    """Lines for ``chiptwin validate``: each stage's level and why, the estimated errors."""
    lines = [f"  {stage:9s} {choice.reasons[stage]}" for stage in choice.levels]
    est = ", ".join(f"{f} {_fmt(choice.estimate[f])} (budget {b:g})"
                    for f, b in choice.budget.items())
    lines.append(f"  estimated error against the reference: {est}")
    over = [f for f, b in choice.budget.items() if choice.estimate[f] > b]
    if over:
        lines.append(f"  over the budget on {', '.join(over)}: the levels not left to auto "
                     "already spend it; auto kept the reference level of its stages")
    if choice.calibration_s:
        lines.append(f"  estimates computed in {choice.calibration_s:.2f} s (cached for next "
                     "time)")
    return lines


__all__ = ["LEVELS", "ORDER", "AutoChoice", "CachedEstimates", "Estimate", "describe",
           "figure_errors", "figures", "gaussian_moment_bounds", "gaussian_moment_errors",
           "gaussian_tv", "ideal_adc", "reference_levels", "resolve",
           "with_levels"]
