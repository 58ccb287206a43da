"""Intervals and decisions for study metrics.

- Rates: exact Clopper–Pearson intervals (Clopper & Pearson, Biometrika 26, 1934): the bounds are
  Beta quantiles, so they hold at the stated level for every n, including k = 0 (upper bound
  ``1 − (1 − c)^(1/n) ≈ 3/n`` at c = 95 %, the "rule of three") and k = n.
- Means: Student-t intervals over replicates (normal-theory; the per-run metrics are sums or
  extremes of thousands of frame values, and n ≥ 2 is required for an interval).
- SNR loss: the delta method on ``ln`` of the two means (independent samples).

Every interval carries its method and n, so an output never shows a bare number. A requirement
is decided with the ONE-sided bound at the study's confidence: met when the bound is on the
allowed side, failed when the opposite bound is already beyond the threshold, undecided between.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np


def _stats():
    """``scipy.stats``, imported when an interval is first asked for: ≈ 0.6 s that every process
    importing the runner (a pool worker, the CLI) paid whether or not it made an interval."""
    from scipy import stats

    return stats


@dataclass(frozen=True)
class Estimate:
    """A metric at a point: estimate, two-sided interval and one-sided bounds at ``confidence``."""

    value: float
    lo: float  # two-sided interval at ``confidence``
    hi: float
    lower: float  # one-sided lower bound at ``confidence``
    upper: float  # one-sided upper bound at ``confidence``
    n: int  # replicates behind it (trials for rates: ``trials``)
    method: str
    k: int | None = None  # rates: successes and trials
    trials: int | None = None

    def as_dict(self) -> dict:
        return {k: _json_float(v) for k, v in asdict(self).items() if v is not None}


def _json_float(v):
    if isinstance(v, float) and not math.isfinite(v):
        return None if math.isnan(v) else ("inf" if v > 0 else "-inf")
    return v


def clopper_pearson(k: int, n: int, confidence: float, sided: str = "two") -> tuple[float, float]:
    """Exact binomial interval for k successes in n trials.

    ``sided = "two"``: the central interval, each tail ``(1 − c)/2``; ``"one"``: the pair of
    one-sided bounds, each at level ``c`` (the lower from one test, the upper from another).
    """
    if not 0 <= k <= n or n < 1:
        raise ValueError(f"clopper_pearson: need 0 ≤ k ≤ n, n ≥ 1; got k = {k}, n = {n}")
    alpha = 1.0 - confidence
    tail = alpha / 2 if sided == "two" else alpha
    lo = 0.0 if k == 0 else float(_stats().beta.ppf(tail, k, n - k + 1))
    hi = 1.0 if k == n else float(_stats().beta.ppf(1.0 - tail, k + 1, n - k))
    return lo, hi


def rate_estimate(k: int, n: int, runs: int, confidence: float) -> Estimate:
    """A pooled rate: ``k`` of ``n`` trials over ``runs`` replicates."""
    lo, hi = clopper_pearson(k, n, confidence)
    lower, upper = clopper_pearson(k, n, confidence, sided="one")
    return Estimate(k / n, lo, hi, lower, upper, runs, "Clopper-Pearson exact", k, n)


def mean_estimate(x: np.ndarray, confidence: float) -> Estimate:
    """Mean of per-run values with a Student-t interval (none for n < 2: ±inf)."""
    x = np.asarray(x, dtype=float)
    n = len(x)
    mean = float(np.mean(x))
    if n < 2:
        return Estimate(mean, -math.inf, math.inf, -math.inf, math.inf, n, "t (n < 2: none)")
    se = float(np.std(x, ddof=1)) / math.sqrt(n)
    t2 = float(_stats().t.ppf(0.5 + confidence / 2, n - 1)) * se
    t1 = float(_stats().t.ppf(confidence, n - 1)) * se
    return Estimate(mean, mean - t2, mean + t2, mean - t1, mean + t1, n, "Student t")


def loss_db_interval(x: np.ndarray, ref: np.ndarray, confidence: float) -> Estimate:
    """``10·log10(mean(ref)/mean(x))`` with a delta-method t interval.

    Var(ln x̄) ≈ s²/(n x̄²); the two samples are independent (different seeds), so the variances
    add; the t quantile takes the smaller sample's degrees of freedom (conservative).
    """
    x, ref = np.asarray(x, float), np.asarray(ref, float)
    n = min(len(x), len(ref))
    mx, mr = float(np.mean(x)), float(np.mean(ref))
    if mx <= 0 or mr <= 0:
        return Estimate(math.inf, -math.inf, math.inf, -math.inf, math.inf, n,
                        "delta method (SNR ≤ 0: undefined)")
    if math.isinf(mx) or math.isinf(mr):  # a noiseless side: no interval (log10(0) raised)
        value = 0.0 if mx == mr else (math.inf if math.isinf(mr) else -math.inf)
        return Estimate(value, -math.inf, math.inf, -math.inf, math.inf, n,
                        "delta method (an infinite SNR: no interval)")
    value = 10 * math.log10(mr / mx)
    if n < 2:
        return Estimate(value, -math.inf, math.inf, -math.inf, math.inf, n, "delta method t")
    var = np.var(x, ddof=1) / (len(x) * mx**2) + np.var(ref, ddof=1) / (len(ref) * mr**2)
    se_db = 10 / math.log(10) * math.sqrt(var)
    t2 = float(_stats().t.ppf(0.5 + confidence / 2, n - 1)) * se_db
    t1 = float(_stats().t.ppf(confidence, n - 1)) * se_db
    return Estimate(value, value - t2, value + t2, value - t1, value + t1, n, "delta method t")


def decide(est: Estimate, op: str, threshold: float) -> str:
    """``"pass"``, ``"fail"`` or ``"undecided"`` for ``metric op threshold`` at the bound's
    level: pass when the bound on the allowed side meets it, fail when the other bound already
    breaks it."""
    if op == "<=":
        return "pass" if est.upper <= threshold else ("fail" if est.lower > threshold
                                                       else "undecided")
    return "pass" if est.lower >= threshold else ("fail" if est.upper < threshold
                                                   else "undecided")


def looks_confidence(confidence: float, looks: int) -> float:
    """Per-look level that keeps ``looks`` sequential looks at ``confidence`` overall
    (Bonferroni: conservative, valid whatever the stopping rule)."""
    return 1.0 - (1.0 - confidence) / max(looks, 1)
