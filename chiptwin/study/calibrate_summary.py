"""A finished calibration as ``study.json``: the fitted values and intervals, the objective and
how well the data fit, the correlations, the evaluations and every method statement.

The answer states each fitted key as ``value [lo, hi]`` at the study's confidence (profile
likelihood), marks an end the data do not bound within the range as open, and names every pair
of keys whose correlation at the optimum exceeds :data:`INSEPARABLE` in size: the data cannot
separate them (most of what they say is about a combination of the two).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from chiptwin import __version__
from chiptwin.study.calibrate_fit import (
    CHORD_FTOL,
    CHORD_STEPS,
    DE_ATOL_CHI2,
    FD_STEP_U,
    POLISH_FTOL,
    POLISH_STEPS,
    POLISH_XTOL,
    PROFILE_RTOL,
    SCALE_ROUNDS,
    SMOOTH_SHARE,
    SMOOTH_STEP_U,
)

#: |ρ| above which two keys are named as not separated by the data.
INSEPARABLE: float = 0.95


def _num(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def parameter_rows(ev: Any, result: Any) -> list[dict[str, Any]]:
    """Each key: value, interval, open ends, the scenario's own value, range, scale, why."""
    cov = result.covariance()
    rows = []
    for j, (p, iv) in enumerate(zip(ev.params, result.intervals, strict=True)):
        value = p.value(result.u[j])
        se_u = math.sqrt(cov[j, j]) if cov[j, j] > 0 and result.moved()[j] else math.nan
        dx = (p.hi - p.lo) if not p.log else value * math.log(p.hi / p.lo)
        rows.append({
            "key": p.key, "value": value, "interval": [p.value(iv.lo), p.value(iv.hi)],
            "open": [iv.open_lo, iv.open_hi], "at_range_end": _at_end(result.u[j]),
            "linearised_se": None if p.integer else _num(se_u * dx),
            "scenario_value": p.reference, "range": [p.lo, p.hi],
            "scale": "log" if p.log else "lin", "integer": p.integer, "why": p.why,
            "profile_steps": iv.steps})
    return rows


def _at_end(u: float) -> str | None:
    return "low" if u <= 1e-9 else "high" if u >= 1 - 1e-9 else None


def correlation_section(ev: Any, result: Any) -> dict[str, Any]:
    """The correlation matrix at the optimum and the pairs the data cannot separate."""
    rho = result.correlation()
    keys = [p.key for p in ev.params]
    pairs = []
    for a in range(len(keys)):
        for b in range(a + 1, len(keys)):
            if np.isfinite(rho[a, b]) and abs(rho[a, b]) > INSEPARABLE:
                pairs.append({"keys": [keys[a], keys[b]], "rho": float(rho[a, b]),
                              "statement": f"the data cannot separate {keys[a]} and {keys[b]} "
                                           f"(ρ = {rho[a, b]:+.3f}): most of what they say is "
                                           "about a combination of the two; each interval "
                                           "is its own profile, the others re-optimised"})
    silent = [keys[j] for j in range(len(keys)) if not np.isfinite(rho[j, j])]
    return {"keys": keys, "matrix": [[_num(x) for x in row] for row in rho],
            "inseparable": pairs, "threshold": INSEPARABLE,
            "not_moved": silent, "method": "(JᵀJ)⁻¹ of the scaled residuals' Jacobian at the "
            "optimum (forward differences); an integer key, or one the data do not move there, "
            "has none"}


def objective_section(ev: Any, result: Any) -> dict[str, Any]:
    """χ² at the optimum, its degrees of freedom and p-value, per statistic."""
    from scipy import stats

    from chiptwin.study.calibrate_data import block_chi2

    m = ev.measured
    rec = ev.record(result.u)
    raw = np.asarray(rec["residuals"])
    p = ev.k + m.nuisance
    dof = m.n - p
    chi2_raw = float(raw @ raw)
    blocks = [{"name": name, "n": int((m.block == b).sum()), "chi2": float(c),
               "scale": float(ev.scales[b])}
              for b, (name, c) in enumerate(zip(m.block_names, block_chi2(m, raw), strict=True))]
    out = {"kind": "chi2" if m.weighted else "wls", "chi2": result.chi2,
           "chi2_unscaled": chi2_raw, "points": m.n, "parameters": ev.k, "nuisance": m.nuisance,
           "dof": dof, "blocks": blocks, "threshold": result.threshold}
    if m.weighted:
        out["p_value"] = float(stats.chi2.sf(chi2_raw, dof)) if dof > 0 else None
    if m.nuisance:
        out["offset"] = ev.offset(result.u)
    return out


def method_statements(ev: Any, cal: Any, result: Any) -> dict[str, str]:
    """What was done, in words: optimiser, polish, intervals, stopping rule, the objective,
    the random numbers."""
    m = ev.measured
    k = ev.k
    scaled = [b for b, s in zip(m.block_names, ev.scales, strict=True) if s != 1.0]
    objective = ("χ²: Σ ((sim + offset − measured)/(s_b·√(se_measured² + se_sim²)))², the "
                 "simulated statistics' own standard errors in the variance" if m.weighted else
                 "least squares with equal weights (no standard errors given): the errors' "
                 "scale s estimated from the residuals, s² = RSS/(n − p)")
    return {
        "objective": objective + (f"; the errors of {', '.join(scaled)} scaled by their Birge "
                                  "ratio √(χ²_b/ν_b) > 1 (they scatter more than their standard "
                                  "errors say: the Particle Data Group's scale factor)"
                                  if scaled and m.weighted else ""),
        "optimiser": f"differential evolution (scipy.optimize.differential_evolution, "
                     f"best1bin, {cal.popsize} × {k} members from a Latin hypercube and the "
                     "scenario's own values, seeded from the study seed, deferred updating, "
                     "each generation through the study's executor) over each key's range "
                     "(log-scaled where it spans more than a decade), then "
                     "scipy.optimize.least_squares (trust region reflective) from its best "
                     f"member, the Jacobian by forward differences of {FD_STEP_U:g} of each "
                     "range",
        "stopping": f"evolution: population's objective spread ≤ "
                    f"{DE_ATOL_CHI2 if m.weighted else 0:g} + {cal.tol:g} × its mean, or "
                    f"{cal.generations} generations ({result.evolution.get('generations')} "
                    f"run, {'converged' if result.evolution.get('converged') else 'the cap'}); "
                    f"polish: relative change of χ² ≤ {POLISH_FTOL:g} or of u ≤ "
                    f"{POLISH_XTOL:g}, or {POLISH_STEPS} steps (each with a Jacobian of k "
                    f"evaluations), alternated with the errors' scales until they move < 1 % "
                    f"(≤ {SCALE_ROUNDS} rounds); a profile point: χ² ≤ {CHORD_FTOL:g} or "
                    f"{CHORD_STEPS} chord steps; a profile's end: within {PROFILE_RTOL:.0%} of "
                    "the rise",
        "interval": f"profile likelihood at {cal.confidence:.0%}: each key moved from the "
                    "optimum, the others re-optimised (least squares from the covariance's "
                    "linear prediction, with the optimum's Jacobian: the chord method), to "
                    "where the scaled χ² has risen by "
                    f"{result.threshold:.3f} ("
                    + ("the χ²₁ quantile" if m.weighted else "the F(1, n − p) quantile: the "
                       "errors' scale is estimated") + f", to {PROFILE_RTOL:.0%} of it); an end "
                    "open where the range ends first",
        "smoothness": f"χ² at {SMOOTH_STEP_U:g} of each range from the optimum: if it moves "
                      f"by more than {SMOOTH_SHARE:g} of the rise, the random numbers are not "
                      "common to the candidates and the intervals are flagged (warnings)",
        "random_numbers": "common random numbers: every candidate simulated with the same "
                          "seeds (chiptwin.study.rows.row_seed of the study seed, one chip "
                          "from chip_seed), so candidates differ by their values, not their "
                          "draws",
    }


def summarise(study: Any, ev: Any, result: Any, prof: Any) -> dict[str, Any]:
    """``study.json`` of a calibration."""
    cal = study.calibration
    params = parameter_rows(ev, result)
    corr = correlation_section(ev, result)
    log = ev.log
    best, curve = math.inf, []
    for i, e in enumerate(log, 1):
        if e["objective"] is not None and e["objective"] < best:
            best = e["objective"]
            curve.append([i, best])
    counts = {s: sum(e["status"] == s for e in log) for s in ("ok", "invalid", "error")}
    stages = {s: sum(e["stage"] == s for e in log) for s in dict.fromkeys(e["stage"]
                                                                        for e in log)}
    runs: list[list[Any]] = []  # [stage, first evaluation, evaluations] in the order asked
    for i, e in enumerate(log, 1):
        if runs and runs[-1][0] == e["stage"]:
            runs[-1][2] += 1
        else:
            runs.append([e["stage"], i, 1])
    return {
        "study": study.name, "kind": "calibrate", "description": study.description,
        "source": study.source, "scenario": study.scenario_path, "seed": study.seed,
        "confidence": cal.confidence,
        "target": {"kind": cal.target.kind, "path": cal.target.path, "hash": cal.target.hash,
                   "description": cal.target.describe(), "points": ev.measured.n},
        "parameters": params,
        "calibrated": {r["key"]: r["value"] for r in params},
        "objective": objective_section(ev, result),
        "correlation": corr,
        "methods": method_statements(ev, cal, result),
        "fit": {"evolution": result.evolution, "polish": result.polish,
                "profile_evaluations": prof.evaluations, "notes": result.notes,
                "smoothness": result.smoothness},
        "evaluations": {"total": len(log), "computed": ev.computed, "resumed": ev.resumed,
                        **counts, "by_stage": stages, "stages": runs,
                        "wall_s_mean": _num(float(np.mean([e["wall_s"] for e in log])))
                        if log else None},
        "convergence": curve,
        "residuals": residual_table(ev, result),
        "profiles": [[[u, d] for u, d in pts] for pts in prof.points],
        "answer": [{"statement": answer_statement(params, cal.confidence, corr),
                    "trustworthy": bool(result.smoothness.get("smooth", True))}],
        "warnings": fit_warnings(result),
        "runs": {"total": len(log), "computed": ev.computed, "resumed": ev.resumed, **counts},
        "chiptwin_version": __version__,
    }


def residual_table(ev: Any, result: Any) -> dict[str, Any]:
    """Measured, fitted (with the offset) and the scaled residual of every measured value."""
    m = ev.measured
    rec = ev.record(result.u)
    sim = np.asarray(rec["sim"])
    delta = ev.offset(result.u)
    return {"x_label": m.x_label, "blocks": list(m.block_names), "x": m.x.tolist(),
            "block": m.block.tolist(), "measured": m.values.tolist(), "se": m.se.tolist(),
            "fitted": (sim + delta * m.offset).tolist(), "sim_se": rec["sim_se"],
            "normalised": result.residuals.tolist(), "weighted": m.weighted}


def answer_statement(params: list[dict[str, Any]], confidence: float,
                     corr: dict[str, Any]) -> str:
    """The fitted values in one sentence."""
    parts = []
    for p in params:
        lo, hi = p["interval"]
        lo_s = f"≤ {lo:.4g} (open: the range's end)" if p["open"][0] else f"{lo:.4g}"
        hi_s = f"≥ {hi:.4g} (open: the range's end)" if p["open"][1] else f"{hi:.4g}"
        parts.append(f"{p['key']} = {p['value']:.4g} [{lo_s}, {hi_s}]")
    text = f"fitted at {confidence:.0%} (profile likelihood): " + "; ".join(parts)
    for pair in corr["inseparable"]:
        text += f". {pair['statement'][0].upper()}{pair['statement'][1:]}"
    return text


def fit_warnings(result: Any) -> list[str]:
    """What makes the intervals untrustworthy, in words (study.json ``warnings``)."""
    s = result.smoothness
    if not s or s["smooth"]:
        return []
    return [f"χ² moves by {s['max_chi2_change']:.3g} when a key moves by {s['step_u']:g} of its "
            f"range (more than {s['limit']:.3g}): the twin's random numbers are not common to "
            "the candidates (a sampler that re-aligns its stream when a mean moves), so the "
            "intervals are set by the simulated statistics' noise, not by the data; the values "
            "are a search's best, the intervals not to be used"]
