"""The fit of a calibration: a global search, a local polish, profile-likelihood intervals.

Every fitted key is searched in ``u ∈ [0, 1]`` over its range (over the logarithm of a range
wider than a decade: :class:`~chiptwin.study.calibrate_spec.FitParameter`), so one step size and
one tolerance serve keys of any unit.

1. **Global search**: :func:`scipy.optimize.differential_evolution` (``best1bin``, a Latin
   hypercube of ``popsize × k`` members plus the scenario's own values, ``updating="deferred"``,
   ``polish=False``, seeded). It stops when the population's objectives spread less than
   :data:`DE_ATOL_CHI2` + ``tol`` × their mean, or after ``generations``. Its ``workers`` is
   a map-like that sends a whole generation's candidates through the study's executor (serial,
   local pool, Dask) at once, then reads them back.
2. **Local polish**: :func:`scipy.optimize.least_squares` (trust region reflective, bounds
   [0, 1]) on the residual vector from the best member; its Jacobian by forward differences of
   :data:`FD_STEP_U` of each range, the k shifted candidates evaluated together through the
   executor; it stops at :data:`POLISH_FTOL`, :data:`POLISH_XTOL` or :data:`POLISH_STEPS`.
   Integer keys keep the evolution's value. Then each statistic's errors are scaled by its
   Birge ratio (:func:`chiptwin.study.calibrate_data.block_scales`) and the polish repeated.
3. **Intervals**: the profile likelihood. For each key, its value is moved away from the optimum
   and the others re-optimised (least squares from the covariance's linear prediction, each
   step with the optimum's Jacobian: the chord method, one evaluation a step), until the scaled
   χ² has risen by the threshold: the χ²₁ quantile at ``confidence`` (3.84 at 95 %) with
   measured standard errors; with least squares, whose error scale is estimated from the
   residuals, the F(1, n − p) quantile. An end that reaches the range before the rise is
   reported open ("the data do not bound it within the range"). The simulated statistics' own
   noise is in every residual's variance, so the intervals include it. Correlations come from
   the Jacobian at the optimum, ``(JᵀJ)⁻¹``.

Why SciPy: already a core dependency; differential evolution takes a map-like ``workers``, so a
generation goes to the pool or to Dask through the executors every study uses; least squares
gives the Jacobian the correlations need; both are deterministic with a seed, so a rerun asks for
the same candidates and every stored evaluation is taken instead of simulated (resumption).
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

#: The evolution's absolute tolerance on the population's χ² spread (with measured errors): half a
#: unit, well inside the interval's rise of 3.84; least squares (no χ² units) uses ``tol`` alone.
DE_ATOL_CHI2: float = 0.5
#: The smoothness check's step, in u, and the share of the threshold χ² may move by on it.
SMOOTH_STEP_U: float = 1e-6
SMOOTH_SHARE: float = 0.1
#: Eigenvalues of JᵀJ below this share of the largest count as unmeasured combinations.
CONDITION: float = 1e-12
#: Forward-difference step of the Jacobian, in u (a share of each key's range): wide enough that
#: a candidate's change is the model's, not the draws' (common random numbers keep the draws,
#: but an ADC code or a rejection sampler can still step), narrow enough for the curvature.
FD_STEP_U: float = 1e-3
#: Residual of an invalid candidate (an inconsistent scenario) in the polish: far outside.
INVALID_RESIDUAL: float = 1e6
#: Most steps of the polish (least_squares' function evaluations; each with its Jacobian's k).
POLISH_STEPS: int = 40
#: Most steps of a profile point's re-optimisation (the chord method: one evaluation each).
CHORD_STEPS: int = 8
#: The polish stops when χ² changes by less than this share of it (least_squares ftol: of a χ²
#: of 170, 0.017, far inside the intervals' rise of 3.84) …
POLISH_FTOL: float = 1e-4
#: … a profile point's, by less than this share (0.17 of 170) …
CHORD_FTOL: float = 1e-3
#: … or u by less than this (least_squares xtol, relative).
POLISH_XTOL: float = 1e-5
#: Rounds of (errors' scales from the residuals, polish) until the scales settle to 1 %.
SCALE_ROUNDS: int = 4
#: A profile's end is found when the rise is within this share of the threshold …
PROFILE_RTOL: float = 0.1
#: … or the bracket is narrower than this (in u); at most this many steps per end.
PROFILE_XTOL_U: float = 1e-4
PROFILE_STEPS: int = 12
#: The smallest first step of a profile, in u.
PROFILE_MIN_STEP_U: float = 2e-3


class Problem(Protocol):
    """What the fit needs of a calibration (:class:`chiptwin.study.calibrate.Evaluator`)."""

    k: int
    integer: NDArray[np.bool_]

    def residuals(self, us: list[NDArray[np.float64]], stage: str
                  ) -> list[NDArray[np.float64] | None]:
        """The scaled residual vector of each candidate (None: invalid), evaluated together."""
        ...


@dataclass
class Interval:
    """A key's profile-likelihood interval, in u; ``open_lo``/``open_hi``: the rise was not
    reached within the range."""

    lo: float
    hi: float
    open_lo: bool = False
    open_hi: bool = False
    steps: int = 0


@dataclass
class FitResult:
    u: NDArray[np.float64]
    chi2: float  # scaled
    residuals: NDArray[np.float64]  # scaled
    jacobian: NDArray[np.float64]
    threshold: float
    intervals: list[Interval] = field(default_factory=list)
    evolution: dict[str, Any] = field(default_factory=dict)
    polish: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    smoothness: dict[str, Any] = field(default_factory=dict)

    def covariance(self) -> NDArray[np.float64]:
        """``(JᵀJ)⁻¹`` in u. A combination the data do not measure (an eigenvalue below
        :data:`CONDITION` of the largest) keeps a huge variance along it, not none: its keys'
        correlation then says how they trade off (a pseudo-inverse would drop the direction
        and give the opposite sign)."""
        w, v = np.linalg.eigh(self.jacobian.T @ self.jacobian)
        floor = max(float(w.max(initial=0.0)), 1e-300) * CONDITION
        return (v / np.maximum(w, floor)) @ v.T

    def moved(self) -> NDArray[np.bool_]:
        """Keys the residuals depend on at the optimum (a Jacobian column not all zero)."""
        return np.any(self.jacobian != 0.0, axis=0)

    def correlation(self) -> NDArray[np.float64]:
        """Correlations of the keys at the optimum; NaN for a key the data do not move (an
        integer key: no derivative)."""
        c = self.covariance()
        d = np.sqrt(np.clip(np.diag(c), 0.0, None))
        with np.errstate(invalid="ignore", divide="ignore"):
            out = c / np.outer(d, d)
        still = ~self.moved()
        out[still, :] = np.nan
        out[:, still] = np.nan
        out[~np.isfinite(out)] = np.nan
        np.fill_diagonal(out, np.where(still, np.nan, 1.0))
        return out


def _sumsq(r: NDArray[np.float64] | None) -> float:
    return math.inf if r is None else float(r @ r)


def evolve(problem: Problem, rng: np.random.Generator, popsize: int, generations: int,
           tol: float, x0: NDArray[np.float64], atol: float = 0.0
           ) -> tuple[NDArray[np.float64], float, dict]:
    """Step 1: differential evolution over ``[0, 1]^k``; returns the best u, its χ², facts."""
    from scipy.optimize import differential_evolution

    def objective(u: NDArray[np.float64]) -> float:
        return _sumsq(problem.residuals([np.asarray(u)], "evolution")[0])

    def generation(func: Callable, candidates) -> list[float]:
        us = [np.asarray(u, dtype=float) for u in candidates]
        problem.residuals(us, "evolution")  # all of them at once through the executor
        return [func(u) for u in us]  # each now a look-up

    seeded = {"rng" if "rng" in inspect.signature(differential_evolution).parameters
              else "seed": rng}
    res = differential_evolution(objective, [(0.0, 1.0)] * problem.k, popsize=popsize,
                                 maxiter=generations, tol=tol, atol=atol, polish=False,
                                 updating="deferred", workers=generation, init="latinhypercube",
                                 x0=np.clip(x0, 0.0, 1.0), **seeded)
    return np.asarray(res.x), float(res.fun), {
        "generations": int(res.nit), "converged": bool(res.success), "message": str(res.message),
        "members": popsize * problem.k}


def polish(problem: Problem, u0: NDArray[np.float64], free: NDArray[np.bool_], stage: str,
           chord: NDArray[np.float64] | None = None
           ) -> tuple[NDArray[np.float64], NDArray[np.float64], int]:
    """Least squares over the ``free`` keys of u (the others held at ``u0``); returns u, its
    residuals and the candidates asked for.

    With ``chord`` (a Jacobian over every key, the optimum's), every step uses it instead of
    new differences (the chord method: one evaluation a step, at most :data:`CHORD_STEPS`, to
    :data:`CHORD_FTOL`): a profile's re-optimisation near the optimum."""
    from scipy.optimize import least_squares

    batch, asked = _batcher(problem, stage)

    def full(v: NDArray[np.float64]) -> NDArray[np.float64]:
        u = u0.copy()
        u[free] = v
        return u

    def fun(v):
        return batch([full(v)])[0]

    def jac(v):
        if chord is not None:
            return chord[:, free]
        return jacobian(batch, full(v), free, fun(v))

    u = u0.copy()
    if free.any():
        res = least_squares(fun, np.clip(u0[free], 0.0, 1.0), jac=jac, bounds=(0.0, 1.0),
                            method="trf", x_scale="jac", gtol=None,
                            ftol=CHORD_FTOL if chord is not None else POLISH_FTOL,
                            xtol=POLISH_XTOL,
                            max_nfev=CHORD_STEPS if chord is not None else POLISH_STEPS)
        u = full(res.x)
    return u, batch([u])[0], asked[0]


def jacobian_at(problem: Problem, u: NDArray[np.float64], stage: str
                ) -> tuple[NDArray[np.float64], int]:
    """The Jacobian of the scaled residuals at u over every key (an integer key's column is
    zero: no derivative), and the candidates asked for."""
    batch, asked = _batcher(problem, stage)
    r = batch([u])[0]
    out = np.zeros((r.size, problem.k))
    out[:, ~problem.integer] = jacobian(batch, u, ~problem.integer, r)
    return out, asked[0]


def _batcher(problem: Problem, stage: str) -> tuple[Callable, list[int]]:
    """Residuals of candidates evaluated together (an invalid one far outside), and a count."""
    asked = [0]

    def batch(us: list[NDArray[np.float64]]) -> list[NDArray[np.float64]]:
        asked[0] += len(us)
        rs = problem.residuals(us, stage)
        m = next((r.size for r in rs if r is not None), None) or problem_size(problem)
        return [r if r is not None else np.full(m, INVALID_RESIDUAL) for r in rs]

    return batch, asked


def smoothness(problem: Problem, u: NDArray[np.float64], chi2: float, threshold: float
               ) -> dict[str, Any]:
    """How much χ² moves when each key moves by :data:`SMOOTH_STEP_U` of its range, far below
    any effect the data can see: with common random numbers that hold, hardly at all; with a
    sampler that re-aligns its stream when a mean moves (a Poisson rejection loop), by as much
    as the simulated statistics' noise. Above :data:`SMOOTH_SHARE` of the threshold the profile
    intervals are set by that noise, not by the data (``smooth`` False)."""
    batch, _ = _batcher(problem, "smoothness")
    shifted = []
    for j in range(problem.k):
        s = u.copy()
        s[j] += SMOOTH_STEP_U if s[j] + SMOOTH_STEP_U <= 1.0 else -SMOOTH_STEP_U
        shifted.append(s)
    change = max((abs(float(r @ r) - chi2) for r in batch(shifted)), default=0.0)
    return {"step_u": SMOOTH_STEP_U, "max_chi2_change": change,
            "limit": SMOOTH_SHARE * threshold, "smooth": change <= SMOOTH_SHARE * threshold}


def problem_size(problem: Problem) -> int:
    return int(getattr(problem, "n", 1))


def jacobian(batch: Callable, u: NDArray[np.float64], keys: NDArray[np.bool_],
             r0: NDArray[np.float64]) -> NDArray[np.float64]:
    """Forward differences of :data:`FD_STEP_U` (backward at the top of a range) over the
    ``keys`` of u, the shifted candidates evaluated together; ``(n, keys.sum())``."""
    idx = np.flatnonzero(keys)
    steps = np.where(u[idx] + FD_STEP_U <= 1.0, FD_STEP_U, -FD_STEP_U)
    shifted = []
    for i, h in zip(idx, steps, strict=True):
        s = u.copy()
        s[i] += h
        shifted.append(s)
    rs = batch(shifted) if shifted else []
    cols = [(r - r0) / h for r, h in zip(rs, steps, strict=True)]
    return np.column_stack(cols) if cols else np.zeros((r0.size, 0))
