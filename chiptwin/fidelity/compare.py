"""How far one level's figure is from the reference's, measured over seeds, honestly.

A level and the reference are run on the same seeds; figure ``x_i`` (the level) and ``y_i``
(the reference) of seed ``i``. Their relative difference is the **ratio of the means**,
``R − 1 = x̄ / ȳ − 1``, never the mean of the per-seed ratios ``mean(x_i / y_i) − 1``: when
``y`` is noisy the latter is biased upward by about the squared coefficient of variation of
``y`` (``E[1/y] ≈ (1 + CV²) / E[y]``, the second-order delta method), which for a dim scene's
reference SNR (CV 0.1–0.4) is 1–17 %, far above a 1 % budget.

The interval is the delta method on the ratio (Casella & Berger, *Statistical Inference*,
2nd ed., 2002, §5.5.4; the ratio estimator's variance, Cochran, *Sampling Techniques*, 3rd ed.,
1977, eq. 6.9): ``se(R) = sd(x_i − R·y_i) / (√n·|ȳ|)``, the pairs taken as they were drawn, so
common random numbers (``x_i`` and ``y_i`` sharing draws) shrink it and independent draws do
not, with no assumption which; the quantile is Student's t with n − 1 degrees of freedom
(Student, Biometrika 6, 1908), which at n = 2 is 12.7, not 1.96.

Where the figure is the worst of K sites, each site's interval is taken at ``1 − 0.05/K``
(Bonferroni; Dunn, JASA 56, 1961), so the family of K holds together at 95 %: with the per-site
95 % a scene of a few sites "exceeds" an estimate by chance about once in every few scenes (on
luciferase_label's 2 sites, 8 seeds said −5.1 % ± 4.1 % where 60 seeds say +1.0 % ± 1.6 %).

A difference is **resolved** when its 95 % half-width is at most the resolution asked for; an
unresolved one is reported with the number of seeds that would resolve it (the half-width falls
as 1/√n), never as a bare number.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from chiptwin.detection.stats import _stats

#: The confidence of every interval here.
CONFIDENCE = 0.95

#: The smallest relative difference the ladder and ``benchmarks/bench_auto.py`` aim to resolve:
#: 0.1 %, a tenth of the usual 1 % SNR budget.
RESOLUTION = 1e-3


@dataclass(frozen=True)
class Difference:
    """A measured difference and its two-sided 95 % half-width over ``n`` paired seeds."""

    value: float  # signed: relative (x̄/ȳ − 1) or absolute (mean of x − y)
    half: float  # inf when n < 2 or the reference mean is 0
    n: int
    method: str
    confidence: float = 0.95  # of this interval (a family's member: family_confidence)

    @property
    def upper(self) -> float:
        """The largest |difference| the interval allows."""
        return abs(self.value) + self.half

    def resolved(self, resolution: float) -> bool:
        """Whether the half-width is at most ``resolution``."""
        return self.half <= resolution

    def seeds_to_resolve(self, resolution: float) -> int | None:
        """Seeds whose half-width would be ``resolution`` (1/√n scaling, the t quantile at
        that count); None when it cannot be said (n < 2, no spread measured)."""
        if self.n < 2 or not math.isfinite(self.half) or resolution <= 0:
            return None
        if self.half <= resolution:
            return self.n
        c = self.confidence
        sd = self.half * math.sqrt(self.n) / _t(self.n, c)  # the spread of one seed
        n = max(self.n + 1, math.ceil((_t(10**6, c) * sd / resolution) ** 2))
        while _t(n, c) * sd / math.sqrt(n) > resolution:
            n = math.ceil(n * 1.1)
        return n

    def bounded_by(self, estimate: float, resolution: float = RESOLUTION) -> str:
        """``"holds"`` when the interval's largest |difference| is within ``estimate``,
        ``"exceeds"`` when its smallest is beyond it; ``"agrees"`` when the estimate lies inside
        an interval no wider than ``resolution`` each side (a calibrated estimate is the
        error itself, not a bound with room: measured on other draws, its interval straddles
        it however many seeds); else ``"unresolved"``."""
        if self.upper <= estimate:
            return "holds"
        if abs(self.value) - self.half > estimate:
            return "exceeds"
        return "agrees" if self.half <= resolution else "unresolved"

    def seeds_to_decide(self, estimate: float, resolution: float = RESOLUTION) -> int | None:
        """Seeds that would make :meth:`bounded_by` decide, at the same mean and spread: the
        interval narrowed to the gap between the estimate and the mean, or to ``resolution``,
        whichever is wider."""
        if self.bounded_by(estimate, resolution) != "unresolved":
            return self.n
        return self.seeds_to_resolve(max(abs(estimate - abs(self.value)), resolution))

    def as_dict(self, resolution: float) -> dict:
        out = {"value": abs(self.value), "signed": self.value,
               "ci": self.half if math.isfinite(self.half) else None, "n": self.n,
               "method": self.method, "confidence": self.confidence,
               "resolved": self.resolved(resolution)}
        if not out["resolved"]:
            out["seeds_to_resolve"] = self.seeds_to_resolve(resolution)
        return out


def _t(n: int, confidence: float = CONFIDENCE) -> float:
    return float(_stats().t.ppf(0.5 + confidence / 2, n - 1))


def family_confidence(k: int) -> float:
    """Each member's confidence for a family of ``k`` intervals to hold together at
    :data:`CONFIDENCE` (Bonferroni)."""
    return 1 - (1 - CONFIDENCE) / max(int(k), 1)


def ratio_of_means(x: np.ndarray, y: np.ndarray, family: bool = False) -> np.ndarray:
    """``x̄/ȳ − 1`` along axis 0 (seeds) and its delta-method Student-t half-width, for every
    trailing index (sites): an array of :class:`Difference`, shaped like ``x[0]``. ``family``:
    the sites' intervals hold together at 95 % (:func:`family_confidence`), as the worst of
    them (:func:`worst`) needs."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    c = family_confidence(int(np.prod(x.shape[1:]))) if family else CONFIDENCE
    value, half = ratio_of_means_arrays(x, y, c)
    n = x.shape[0]
    method = "ratio of means, delta method t" + (f" (Bonferroni, {c:.4g} each)" if c != CONFIDENCE
                                                  else "")
    flat = [Difference(float(v), float(h), n, method, c)
            for v, h in zip(np.ravel(value), np.ravel(half), strict=True)]
    return np.array(flat, dtype=object).reshape(np.shape(value))


def ratio_of_means_arrays(x: np.ndarray, y: np.ndarray, confidence: float = CONFIDENCE
                          ) -> tuple[np.ndarray, np.ndarray]:
    """The arrays behind :func:`ratio_of_means`: ``(x̄/ȳ − 1, 95 % half-width)``, vectorised
    over the trailing axes (the Monte Carlo coverage test draws thousands of cases at once)."""
    n = x.shape[0]
    xm, ym = x.mean(axis=0), y.mean(axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = xm / ym
        if n < 2:
            return r - 1, np.full(np.shape(r), math.inf)
        resid = x - r * y
        se = resid.std(axis=0, ddof=1) / (math.sqrt(n) * np.abs(ym))
    half = np.where(np.isfinite(se), _t(n, confidence) * se, math.inf)
    return r - 1, half


def mean_difference(d: np.ndarray) -> Difference:
    """The mean of paired differences ``d_i = x_i − y_i`` (or of per-seed errors that are not
    ratios) with its Student-t half-width."""
    d = np.asarray(d, dtype=float)
    n = len(d)
    half = math.inf if n < 2 else _t(n) * float(np.std(d, ddof=1)) / math.sqrt(n)
    return Difference(float(np.mean(d)), half, n, "mean, Student t")


def worst(diffs: np.ndarray) -> Difference | None:
    """The site difference whose interval reaches furthest from 0 (largest ``upper``); ties
    and infinite half-widths go to the largest |value|."""
    flat = [d for d in np.ravel(diffs) if math.isfinite(d.value)]
    if not flat:
        return None
    return max(flat, key=lambda d: (d.upper, abs(d.value)))


__all__ = ["CONFIDENCE", "RESOLUTION", "Difference", "family_confidence", "mean_difference",
           "ratio_of_means", "ratio_of_means_arrays", "worst"]
