"""``auto`` fidelity: per stage, the cheapest level whose error on this scene fits the budget.

A ``[run.fidelity]`` key set to ``"auto"`` is resolved before the run (SPEC "Speed against
error"). The error of a level is taken against the stage's most faithful level the scene accepts
(the ladder's reference, :func:`reference_levels`), figure by figure (the ones
``[run] error_budget`` names, :data:`chiptwin.config.schema.BUDGET_FIGURES`):

* **kinetics** (closed_form vs cascade) and **optics** (na2 vs psf): a calibration, the scene
  run at the ``expected`` photon level (no draws, so the difference is the level's systematic
  error, exact on this scene) at both levels. Cached per scene hash in SQLite
  (``$XDG_CACHE_HOME/chiptwin/fidelity.sqlite``), so it is paid once. The optics reason also
  states the psf coupling's off-diagonal share at the site pixels: the cross-talk na2 misses.
* **photons**: ``events`` and ``binned`` give the collected charge the same law (Poisson counts
  of the same means, clipped at the same full well; ``events`` adds only arrival times), so
  ``binned`` costs 0 against ``events``. ``expected`` draws nothing: it reports each figure's
  mean, where the reference's figure is spread around it; its error is how far the reference's
  figure strays, :data:`EXPECTED_SDS` standard deviations (the site signal's ``signal_sd_e``, a
  flow value's spread, a DSP output's noise).
* **shot** (gaussian vs poisson): the total-variation distance between the Poisson law and the
  rounded normal of the same mean and variance (:func:`gaussian_tv`) at the smallest mean charge
  a site pixel holds in a frame, taken as the bound on each relative figure (the moments agree
  to the 1/12 e⁻² of rounding; the TV distance bounds any probability computed from a count).
* **dsp**: ``rtl`` equals ``fixed`` bit for bit (co-simulated, ``tests/rtl``); ``fixed`` differs
  from ``float`` by the chain's rounding (half an output LSB per rounding step, 0 when M, K and N
  are powers of two) unless the N-frame accumulator is narrower than its exact width
  (``[chip.dsp] acc_bits``), where it can wrap: unbounded.

An error is a distance between the laws of a figure at the two levels, not between two draws:
a level that samples the reference's law (binned for events) costs nothing even though its draws
differ; one that replaces the law by its mean (expected) costs the spread it leaves out.

This module runs scenes for its calibrations (:mod:`chiptwin.run`, imported when called) and
``run()`` resolves ``auto`` through it: the one import loop between the two, by design.

Errors of different stages add (the triangle inequality, an upper estimate); stages are chosen
in :data:`ORDER` (largest savings first on the ladder), each taking the cheapest level that keeps
every budgeted figure's total within the budget. Non-``auto`` stages' errors count against the
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
from scipy import stats

from chiptwin import __version__, stages
from chiptwin.chip import Recorder
from chiptwin.config import Scenario, ScenarioError
from chiptwin.config.consistency import check_consistency
from chiptwin.config.schema import BUDGET_FIGURES
from chiptwin.results import detect

#: The levels of each stage, cheapest first (raytrace is not built: the ladder skips it).
LEVELS: dict[str, tuple[str, ...]] = {
    "kinetics": ("closed_form", "cascade"),
    "photons": ("expected", "binned", "events"),
    "optics": ("na2", "psf"),
    "shot": ("gaussian", "poisson"),
    "dsp": ("float", "fixed", "rtl"),
}

#: The order stages are chosen in: the largest saving first (ladder of pyro_1fmol: cascade
#: 2.6×, rtl DSP and events photons next; optics and shot noise save least).
ORDER = ("kinetics", "dsp", "photons", "optics", "shot")

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
    return replace(s, run=replace(s.run, fidelity=fid), chip=chip)


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
    p = stats.poisson.pmf(k, lam)
    upper = stats.norm.cdf((k + 0.5 - lam) / sd)
    lower = np.where(k == 0, 0.0, stats.norm.cdf((k - 0.5 - lam) / sd))
    return float(0.5 * np.sum(np.abs(p - (upper - lower))))


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


def resolve(s: Scenario, cache: Path | None = None) -> tuple[Scenario, AutoChoice | None]:
    """``s`` with every ``auto`` stage set to a level, and the choice; ``(s, None)`` when no
    stage is ``auto``. ``cache`` is the calibration database (default in the user cache)."""
    auto = s.run.fidelity.auto_stages()
    if not auto:
        return s, None
    budget = s.run.error_budget.items()
    ref = reference_levels(s)
    estimator = _Estimator(s, ref, cache)
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
        for level in LEVELS[stage][: LEVELS[stage].index(ref[stage]) + 1]:
            trial = {**ref, **chosen, stage: level}
            try:
                check_consistency(with_levels(s, trial))
            except ScenarioError:
                continue
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
        reasons[stage] = " | ".join([f"{picked}: {est.how} → {spent}", *refused])
    chosen = {st: chosen[st] for st in LEVELS}
    resolved = with_levels(s, chosen)
    check_consistency(resolved)
    choice = AutoChoice(chosen, {st: reasons[st] for st in LEVELS}, total, budget,
                        estimator.calibration_s, estimator.cached)
    return resolved, choice


def _add(total: dict[str, float], spent: dict[str, float]) -> None:
    for f in total:
        total[f] += spent.get(f, math.inf)


def _fmt(v: float) -> str:
    return f"{v:.3g}" if math.isfinite(v) else "unbounded"


class _Estimator:
    """Each level's :class:`Estimate` on one scene (the expected-level run they share is made
    once; calibrations are read from the cache when there)."""

    def __init__(self, s: Scenario, ref: dict[str, str], cache: Path | None) -> None:
        self.s, self.ref, self.cache = s, ref, cache
        self.calibration_s = 0.0
        self.cached: list[str] = []
        self._runs: dict[tuple, _ExpectedRun] = {}

    def estimate(self, stage: str, level: str, levels: dict[str, str]) -> Estimate:
        """The error of ``level`` against the stage's reference, with the other stages at
        ``levels``; read from the cache when this scene's was computed before."""
        if stage == "shot" and levels.get("photons") == "expected":
            return Estimate.exact("the expected photon level draws no counts")
        if level == self.ref[stage]:
            return Estimate.exact("the most faithful level this scene accepts")
        key = _scene_hash(self.s, stage, level, self.ref[stage])
        hit = _cache_get(self.cache, key)
        if hit is not None:
            self.cached.append(stage)
            return Estimate(hit["errors"], hit["how"] + " (cached)")
        t0 = time.perf_counter()
        est = getattr(self, "_" + stage)(level)
        self.calibration_s += time.perf_counter() - t0
        _cache_put(self.cache, key, {"errors": est.errors, "how": est.how})
        return est

    # -- calibrated stages -------------------------------------------------------------------

    def _kinetics(self, level: str) -> Estimate:
        return self._calibrated("kinetics", level, "calibration: the expected-level run at "
                                f"{level} against {self.ref['kinetics']}")

    def _optics(self, level: str) -> Estimate:
        est = self._calibrated("optics", level, f"calibration: the expected-level run at {level} "
                               f"against {self.ref['optics']}")
        return Estimate(est.errors, est.how + f"; psf cross-talk at the site pixels "
                        f"{_cross_talk_share(self.s):.3g} of their light")

    def _calibrated(self, stage: str, level: str, how: str) -> Estimate:
        base = self._expected_levels()  # its stage is at the reference: that side is the base
        cheap, ref = (self._expected({**base, stage: lv}) for lv in (level, self.ref[stage]))
        measured = figure_errors(cheap.figures, ref.figures)
        return Estimate({f: float(measured.get(f, 0.0)) for f in FIGURES}, how)  # no flows: 0

    # -- analytic stages ---------------------------------------------------------------------

    def _photons(self, level: str) -> Estimate:
        if level == "binned":  # against events
            return Estimate.exact("binned counts have the events level's law (Poisson counts "
                                  "of the same means, the same full-well clip)")
        base = self._expected(self._expected_levels())
        summary, out, e_per_lsb = base.summary, base.out, base.e_per_lsb
        sites = summary["sites"]
        k = EXPECTED_SDS
        signal_rel = max((st["signal_sd_e"] / abs(st["signal_e"]) for st in sites
                          if st["signal_e"]), default=math.inf)
        errors = {"signal_rel": k * signal_rel, "noise_rel": 0.0,
                  "dsp_lsb": k * float(np.sqrt(np.max(out.var_e2, initial=0.0))) / e_per_lsb}
        flows = summary.get("flows")
        if flows:  # a flow value v = F / K: its spread from the flow's and the key's
            key_e, key_sd = sites[0]["signal_e"], sites[0]["signal_sd_e"]
            errors["flow_value_abs"] = k * max(
                math.hypot(f["noise_e"], f["value"] * key_sd) / key_e for f in flows)
        else:
            errors["flow_value_abs"] = 0.0
        return Estimate(_with_snr(errors), f"expected reports each figure's mean, the "
                        f"reference's figure strays {k:g} σ from it (σ_signal/signal "
                        f"{signal_rel:.3g})")

    def _shot(self, level: str) -> Estimate:
        lam = self._min_site_mean_e()
        tv = gaussian_tv(lam)
        base = self._expected(self._expected_levels())
        summary, out, e_per_lsb = base.summary, base.out, base.e_per_lsb
        flows = summary.get("flows") or []
        top = max((abs(f["value"]) for f in flows), default=0.0)
        errors = {"signal_rel": tv, "noise_rel": tv, "flow_value_abs": 2 * tv * top,
                  "dsp_lsb": 2 * tv * float(np.sqrt(np.max(out.var_e2, initial=0.0)))
                  / e_per_lsb}
        return Estimate(_with_snr(errors), f"TV distance to Poisson {tv:.3g} at the smallest "
                        f"mean charge of a site pixel in a frame, {lam:.4g} e⁻")

    def _dsp(self, level: str) -> Estimate:
        if level == "fixed":  # against rtl
            return Estimate.exact("fixed equals the RTL bit for bit (co-simulated)")
        from chiptwin.dsp.fixed import accumulator_bits_needed
        from chiptwin.dsp.pipeline import chain_for
        from chiptwin.dsp.program import DEFAULT_PROGRAM, is_default

        d = self.s.chip.dsp
        chain = chain_for(self.s.chip)
        if d.acc_bits and d.acc_bits < accumulator_bits_needed(chain.average.in_fmt,
                                                               d.average_frames):
            return Estimate(dict.fromkeys(FIGURES, math.inf),
                            f"the {d.acc_bits}-bit N-frame accumulator can wrap: fixed differs "
                            "from float without bound")
        lsb = _rounding_bound_lsb(chain, d.cms_samples, d.n_dark_frames, d.average_frames)
        how = ("M, K, N powers of two: the fixed chain is exact" if lsb == 0 else
               f"the chain's rounding, at most {lsb:.3g} LSB per output")
        if not is_default(d.program):
            later = self._program_bound_lsb()
            lsb += later
            further = [st for st in d.program if st not in DEFAULT_PROGRAM]
            how += (f"; the program's further stages ({', '.join(further)}) at most "
                    f"{later:.3g} LSB (their analytic bounds on this scene's data, calibrated)")
        base = self._expected(self._expected_levels())
        e_per_lsb = base.e_per_lsb
        signal = min(abs(st["signal_e"]) for st in base.summary["sites"]) or math.inf
        errors = {"dsp_lsb": lsb, "signal_rel": lsb * e_per_lsb / signal, "noise_rel": 0.0,
                  "flow_value_abs": 2 * lsb * e_per_lsb / signal}
        return Estimate(_with_snr(errors), how)

    def _program_bound_lsb(self) -> float:
        """The sum of the analytic bounds of the program's stages after the chain (kinetics,
        bin_rows, fir8, wiener: coefficient quantisation and rounding, which depend on the
        data), from one fixed-point run of the scene with ``report_error``. The chain's
        own bound is not in it (that is :func:`_rounding_bound_lsb`)."""
        from chiptwin.run import run

        sv = with_levels(self.s, {**self.ref, "photons": "binned", "dsp": "fixed"})
        sv = replace(sv, chip=replace(sv.chip, dsp=replace(sv.chip.dsp, report_error=True)))
        bounds = run(sv).summary["dsp_program"].get("stage_error_bounds", {})
        return float(sum(b["bound_lsb"] for b in bounds.values()))

    # -- the scene at the expected level -----------------------------------------------------

    def _expected_levels(self) -> dict[str, str]:
        return {**self.ref, "photons": "expected", "dsp": "float", "shot": "poisson"}

    def _expected(self, levels: dict[str, str]) -> _ExpectedRun:
        """The scene at ``levels`` and the expected photon level, made once per levels."""
        key = tuple(sorted(levels.items()))
        if key not in self._runs:
            self._runs[key] = _ExpectedRun.of(self.s, levels)
        return self._runs[key]

    def _min_site_mean_e(self) -> float:
        base = self._expected(self._expected_levels())
        scene, s = base.scene, base.scenario
        idx = stages.site_pixel_indices(s)
        t_int, gain = s.chip.timing.t_int_s, s.chip.adc.gain_error
        lam, b = math.inf, scene.block_frames
        for start in range(0, scene.sch.n_frames, b):
            block = scene.pixel_block(t_int, gain, start, min(start + b, scene.sch.n_frames))
            lam = min(lam, float(np.min(block.mean_e[:, idx])))
        return lam


@dataclass
class _ExpectedRun:
    """A scene run at the expected photon level (no draws): its scene, chain output, summary
    and the ladder's figures."""

    scenario: Scenario
    scene: Any
    out: Any
    summary: dict[str, Any]
    figures: dict[str, np.ndarray]

    @property
    def e_per_lsb(self) -> float:
        return self.scene.sensor.e_per_lsb

    @classmethod
    def of(cls, s: Scenario, levels: dict[str, str]) -> _ExpectedRun:
        from chiptwin.run import prepare, simulate, stage_rng

        sv = with_levels(s, levels)
        scene = prepare(sv)
        out = simulate(sv, scene, "expected", stage_rng(sv.scenario.seed, "pixel"), Recorder(),
                       sites=stages.site_pixel_indices(sv))
        summary, arrays = detect(sv, scene, out)
        return cls(sv, scene, out, summary, figures(summary, arrays, scene.sensor.e_per_lsb))


def _with_snr(spent: dict[str, float]) -> dict[str, float]:
    """Add ``snr_rel`` (power SNR S²/N²) and ``snr_db`` from the signal and noise errors."""
    s, n = spent["signal_rel"], spent["noise_rel"]
    snr_rel = (1 + s) ** 2 / (1 - n) ** 2 - 1 if n < 1 else math.inf
    return {**spent, "snr_rel": snr_rel, "snr_db": 10 * math.log10(1 + snr_rel)}


def _rounding_bound_lsb(chain, m: int, k: int, n: int) -> float:
    """Largest |fixed − float| of an N-frame average, in ADC LSB: half an output LSB per step
    that rounds (a division by M, K or N that is not a power of two), carried through the
    subtraction (CMS frame minus dark reference) and the averages (means of bounded errors)."""
    def half_ulp(fmt, divisor: int) -> float:
        return 0.0 if divisor & (divisor - 1) == 0 else 0.5 * 2.0 ** -fmt.frac_bits

    cms = half_ulp(chain.cms.out_fmt, m)
    dark = cms + half_ulp(chain.dark.out_fmt, k)
    exact_diff = chain.background.out_fmt.frac_bits >= max(chain.cms.out_fmt.frac_bits,
                                                           chain.dark.out_fmt.frac_bits)
    background = cms + dark + (0.0 if exact_diff else 0.5 * 2.0 ** -chain.background.out_fmt
                               .frac_bits)
    return background + half_ulp(chain.average.out_fmt, n)


def _cross_talk_share(s: Scenario) -> float:
    """The largest share of a site pixel's light that comes from other sites (psf coupling)."""
    from chiptwin import stages
    c = stages.coupling(with_levels(s, {"optics": "psf"}))
    idx = stages.site_pixel_indices(s)
    rows = c[idx]
    rows = rows.toarray() if hasattr(rows, "toarray") else np.asarray(rows)
    total = rows.sum(axis=1)
    own = rows[np.arange(len(idx)), np.arange(len(idx))]
    with np.errstate(invalid="ignore", divide="ignore"):
        share = np.where(total > 0, 1 - own / total, 0.0)
    return float(np.max(share, initial=0.0))


# -- the calibration cache -------------------------------------------------------------------

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


__all__ = ["AutoChoice", "Estimate", "describe", "gaussian_tv", "resolve"]
