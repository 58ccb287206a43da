"""Intervals and decisions for study metrics.

- Rates: Clopper–Pearson intervals (Clopper & Pearson, Biometrika 26, 1934) at the effective
  number of trials of Korn & Graubard (Survey Methodology 24, 1998), with the runs as clusters.
  The Beta-quantile bounds hold at the stated level for every n, including k = 0 (upper bound
  ``1 − (1 − c)^(1/n) ≈ 3/n`` at c = 95 %, the "rule of three") and k = n; the effective n
  counts that trials within a run are not independent (a read's base errors clump, sites share
  a chip when it varies between runs): see :func:`rate_estimate`.
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
from functools import lru_cache

import numpy as np


def _stats():
    """``scipy.stats``, imported when an interval is first asked for: ≈ 0.6 s that every process
    importing the runner (a pool worker, the CLI) paid whether or not it made an interval."""
    from scipy import stats

    return stats


@lru_cache(maxsize=4096)
def _t(q: float, df: float) -> float:
    """Student-t quantile, remembered: a study asks for the same few (level, n) at every point
    and look, and scipy's ppf costs ≈ 0.2 ms a call."""
    return float(_stats().t.ppf(q, df))


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
    design_effect: float | None = None  # rates: Var(p̂) over its binomial value, ≥ 1 as used

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


#: Fewest runs a rate's design effect is estimated from (NCHS's data presentation standards for
#: proportions, 2017, flag a design-based estimate with fewer than 8 degrees of freedom).
MIN_CLUSTER_RUNS = 10


def rate_estimate(k: np.ndarray, n: np.ndarray, confidence: float) -> Estimate:
    """A rate pooled over runs: ``k[i]`` successes of ``n[i]`` trials in run ``i``.

    The runs are independent (own seeds); the trials within a run need not be: a pyrosequencing
    read that goes wrong at a homopolymer carries several base errors, and with
    ``vary_chip = true`` a run's sites share one chip. A plain Clopper–Pearson interval on the
    pooled ``Σk/Σn`` then covers far less than it says (Monte Carlo in ``tests/study/
    test_stats.py``: 68 % for a nominal 95 % at a design effect of 4.5). So the runs are the
    clusters (Korn & Graubard, "Confidence intervals for proportions with small expected number
    of positive counts estimated from survey data", Survey Methodology 24:193, 1998):

    - ``p̂ = Σk/Σn``, its variance from the runs' residuals ``k_i − p̂ n_i`` (the ratio
      estimator's linearisation, ``Σ(k_i − p̂ n_i)² / (N (N − 1) n̄²)`` over N runs);
    - the design effect ``d = Var(p̂) / (p̂(1 − p̂)/Σn)``, from at least
      :data:`MIN_CLUSTER_RUNS` runs (from fewer, one degree of freedom a run makes it noise:
      Korn & Graubard's factor below bounded one error in two runs of 20 at 0.9997, where
      Clopper–Pearson says 0.142);
    - above 1, the effective trials ``n* = Σn/d · (t_{Σn−1} / t_{N−1})²`` (the second factor: the
      variance is known from N runs, not Σn trials), at most Σn; at or below 1 (the trials no
      better than independent) ``n* = Σn``: the binomial variance, no estimated one, so no
      degrees-of-freedom factor;
    - the bounds: the Clopper–Pearson Beta quantiles at ``k* = p̂ n*`` of ``n*``, one-sided at
      ``1 − c``, two-sided at ``(1 − c)/2`` each.

    At ``k = 0`` or ``k = Σn`` there is no variance to measure: ``n* = Σn`` (Korn & Graubard's
    rule), the plain Clopper–Pearson bound, which assumes the errors do not clump (none was seen
    to): a study that must bound clumping errors it never sees needs more reads by the clump's
    size. Fewer than :data:`MIN_CLUSTER_RUNS` runs, or one trial a run (``results_valid``:
    the trials are the runs), likewise: plain, and the method says why.

    Coverage of the one-sided 95 % upper bound, beta-binomial runs of 36 trials (Monte Carlo,
    ``tests/study/test_stats.py``): 93 % at p = 0.02 and a design effect of 4.5 over 90 runs
    (pooled Clopper–Pearson 77 %); short of nominal where the design effect is estimated from
    few runs with errors: 83 % over 10 runs, 63 % at a design effect of 11.5 over 10 runs (a
    review's figures). A study of clumping errors wants tens of runs a point.
    """
    k, n = np.asarray(k, dtype=float), np.asarray(n, dtype=float)
    runs, kk, nn = len(k), float(k.sum()), float(n.sum())
    if runs < 1 or nn < 1 or np.any(k < 0) or np.any(k > n):
        raise ValueError(f"rate_estimate: need runs with 0 ≤ k ≤ n and Σn ≥ 1; got k = "
                         f"{k.tolist()}, n = {n.tolist()}")
    p = kk / nn
    if runs < MIN_CLUSTER_RUNS or np.all(n <= 1):
        lo, hi = clopper_pearson(int(kk), int(nn), confidence)
        lower, upper = clopper_pearson(int(kk), int(nn), confidence, sided="one")
        why = ("one trial a run" if np.all(n <= 1) else
               f"{runs} runs < {MIN_CLUSTER_RUNS}: the design effect not measured")
        return Estimate(p, lo, hi, lower, upper, runs, f"Clopper-Pearson exact ({why})",
                        int(kk), int(nn), 1.0)
    deff = 1.0
    if 0 < kk < nn:
        var = float(np.sum((k - p * n) ** 2)) / (runs * (runs - 1) * (nn / runs) ** 2)
        deff = var / (p * (1 - p) / nn)
    alpha = 1.0 - confidence
    bounds = []
    for tail in (alpha / 2, alpha):  # two-sided, then one-sided
        n_eff = nn
        if deff > 1.0:
            n_eff = min(nn / deff * (_t(1 - tail, nn - 1) / _t(1 - tail, runs - 1)) ** 2, nn)
        k_eff = p * n_eff
        lo = 0.0 if kk == 0 else float(_stats().beta.ppf(tail, k_eff, n_eff - k_eff + 1))
        hi = 1.0 if kk == nn else float(_stats().beta.ppf(1 - tail, k_eff + 1, n_eff - k_eff))
        bounds += [lo, hi]
    return Estimate(p, *bounds, runs, "Korn-Graubard (Clopper-Pearson at the effective n, runs "
                    "as clusters)", int(kk), int(nn), max(deff, 1.0))


def mean_estimate(x: np.ndarray, confidence: float) -> Estimate:
    """Mean of per-run values with a Student-t interval (none for n < 2: ±inf)."""
    x = np.asarray(x, dtype=float)
    n = len(x)
    mean = float(np.mean(x))
    if n < 2:
        return Estimate(mean, -math.inf, math.inf, -math.inf, math.inf, n, "t (n < 2: none)")
    se = float(np.std(x, ddof=1)) / math.sqrt(n)
    t2 = _t(0.5 + confidence / 2, n - 1) * se
    t1 = _t(confidence, n - 1) * se
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
    t2 = _t(0.5 + confidence / 2, n - 1) * se_db
    t1 = _t(confidence, n - 1) * se_db
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


#: Share of the error rate ``α = 1 − confidence`` that a grid stopping early spends on its interim
#: looks (all but the last); the last look, at the cap, keeps the rest. See :func:`look_levels`.
INTERIM_ALPHA_SHARE = 0.1


def look_levels(confidence: float, looks: int) -> tuple[float, ...]:
    """Per-look confidence of a sequential test that may stop at any of ``looks`` looks, with
    ``confidence`` overall: Haybittle–Peto's shape (strict interim looks, the last near the
    fixed design's level), made exact by Bonferroni.

    With ``α = 1 − confidence`` and ``s =`` :data:`INTERIM_ALPHA_SHARE`, look ``k < K`` is taken at
    ``1 − sα/(K − 1)`` and the last at ``1 − (1 − s)α``; one look is taken at ``confidence``.
    The spends add to α, so whatever the stopping rule and however correlated the looks (they
    share rows): a wrong decision at the look where a point stops is a bound on the wrong side
    of the true value at that look, of probability ≤ that look's spend, and the union over the
    looks is ≤ α. At 95 % in 9 looks: 99.94 % at each of 8 interim looks (z ≈ 3.2, as
    Haybittle's and Peto's "p < 0.001 before the end": Haybittle, Br. J. Radiol. 44:793, 1971;
    Peto et al., Br. J. Cancer 34:585, 1976) and 95.5 % at the cap, where an even split
    (:func:`looks_confidence`) takes 99.44 % at every look: a grid point decided at the cap by
    the one-look design then stays decided unless its bound lies within the 95 → 95.5 %
    quantile step of its threshold (3 % of a t bound's width at 89 degrees of freedom), while
    under the even split a rate with no event in 3,240 trials bounds at 1.6e-3 instead of 9.2e-4.
    """
    if looks <= 1:
        return (confidence,)
    alpha = 1.0 - confidence
    interim = 1.0 - INTERIM_ALPHA_SHARE * alpha / (looks - 1)
    return (interim,) * (looks - 1) + (1.0 - (1.0 - INTERIM_ALPHA_SHARE) * alpha,)


def look_sizes(cap: int, batch: int) -> tuple[int, ...]:
    """Replicates at each sequential look: ``batch``, ``2·batch``, … up to ``cap`` (the last look
    at ``cap`` even when ``batch`` does not divide it)."""
    return tuple(min(n, cap) for n in range(batch, cap + batch, batch))
