"""Profile-likelihood intervals of a calibration's keys (step 3 of :mod:`.calibrate_fit`).

For key j and each direction, its u is moved from the optimum and the other keys re-optimised
(:func:`~chiptwin.study.calibrate_fit.polish` by the chord method: each step with the optimum's
Jacobian, one evaluation a step; started from the last profile point moved along the
covariance's linear prediction ``u_i += C_ij/C_jj · Δu_j``) until
the scaled χ² has risen by the threshold T (3.84 at 95 % with measured standard errors). The
first step is the Jacobian's estimate of the end (``√(T·C_jj)``, ``C = (JᵀJ)⁻¹``); while the rise
is short of T the next step extrapolates the profile as a parabola through the optimum (at most
four times as far); once bracketed, the end is found on ``√Δχ²``, which is close to linear in u,
to :data:`~chiptwin.study.calibrate_fit.PROFILE_RTOL` of T. An integer key steps through its
integers. A profile that reaches the range's end below T is **open** there: the data do not
bound the key within the range.

A profile point below the optimum (by more than :data:`BETTER_SHARE` of the threshold) means the
polish had found a local minimum: it is reported (:attr:`Profiles.better`) so the fit can restart
from it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from chiptwin.study.calibrate_fit import (
    PROFILE_MIN_STEP_U,
    PROFILE_RTOL,
    PROFILE_STEPS,
    PROFILE_XTOL_U,
    Interval,
    Problem,
    polish,
)

#: χ² below the optimum's by more than this share of the threshold (0.38 at 95 %) marks a better
#: optimum found by a profile (less is within the simulated statistics' fine-scale steps: an
#: ADC code, a rounded count).
BETTER_SHARE: float = 0.1
#: Integers an integer key's profile steps through at most, per direction.
INTEGER_STEPS: int = 64


@dataclass
class Profiles:
    intervals: list[Interval]
    better: tuple[float, NDArray[np.float64]] | None = None
    evaluations: int = 0
    points: list[list[tuple[float, float]]] = field(default_factory=list)  # (u, Δχ²) per key


class _Profile:
    """One key's profile: the re-optimised χ² at a value of the key."""

    def __init__(self, problem: Problem, u_hat: NDArray[np.float64], f_hat: float, j: int,
                 out: Profiles, chord: NDArray[np.float64], covariance: NDArray[np.float64],
                 better: float) -> None:
        self.problem, self.u_hat, self.f_hat, self.j, self.out = problem, u_hat, f_hat, j, out
        self.better = better
        self.free = ~problem.integer.copy()
        self.free[j] = False
        self.chord = chord
        c = covariance[:, j]
        self.slope = np.where(self.free, c / c[j], 0.0) if c[j] > 0 else np.zeros_like(c)
        self.points: list[tuple[float, float]] = []

    def rise(self, v: float, warm: NDArray[np.float64]) -> tuple[float, NDArray[np.float64]]:
        """Δχ² at u_j = v, the others re-optimised from ``warm`` moved along the linear
        prediction; the re-optimised u."""
        u0 = np.clip(warm + self.slope * (v - warm[self.j]), 0.0, 1.0)
        u0[self.j] = v
        if self.free.any():
            u, r, asked = polish(self.problem, u0, self.free, "profile", chord=self.chord)
        else:
            (r,) = self.problem.residuals([u0], "profile")
            u, asked = u0, 1
        self.out.evaluations += asked
        f = math.inf if r is None else float(r @ r)
        if f < self.f_hat - self.better and (self.out.better is None or f < self.out.better[0]):
            self.out.better = (f, u.copy())
        self.points.append((float(v), f - self.f_hat))
        return f - self.f_hat, u


def profiles(problem: Problem, u_hat: NDArray[np.float64], f_hat: float, threshold: float,
             covariance: NDArray[np.float64], jacobian: NDArray[np.float64],
             neighbour) -> Profiles:
    """Every key's interval. ``jacobian``: the optimum's (the chord of every re-optimisation);
    ``neighbour(j, u_j, d)``: the u of the next integer value of integer key j in direction d
    (None past the range)."""
    out = Profiles([])
    for j in range(problem.k):
        p = _Profile(problem, u_hat, f_hat, j, out, jacobian, covariance,
                     BETTER_SHARE * threshold)
        if problem.integer[j]:
            ends = [_integer_end(p, d, threshold, neighbour) for d in (-1, 1)]
        else:
            c = covariance[j, j]
            first = math.sqrt(threshold * c) if np.isfinite(c) and c > 0 else 0.05
            ends = [_float_end(p, d, threshold, first) for d in (-1, 1)]
        (lo, open_lo, s_lo), (hi, open_hi, s_hi) = ends
        out.intervals.append(Interval(lo, hi, open_lo, open_hi, s_lo + s_hi))
        out.points.append(sorted(p.points))
    return out


def _float_end(p: _Profile, d: int, T: float, first: float) -> tuple[float, bool, int]:
    """Where the profile of a float key crosses T in direction d; (u, open, steps)."""
    u_hat = p.u_hat[p.j]
    bound = 1.0 if d > 0 else 0.0
    inside, outside = (u_hat, 0.0, p.u_hat), None
    v = float(np.clip(u_hat + d * max(first, PROFILE_MIN_STEP_U), 0.0, 1.0))
    steps = 0
    while steps < PROFILE_STEPS and v != inside[0]:
        delta, u = p.rise(v, inside[2])
        steps += 1
        if delta >= T:
            outside = (v, delta, u)
            break
        inside = (v, delta, u)
        if v == bound:
            return bound, True, steps
        dist = abs(v - u_hat)
        grow = min(math.sqrt(T / delta), 4.0) if delta > 0 else 4.0
        v = float(np.clip(u_hat + d * max(1.05 * grow * dist, dist + PROFILE_MIN_STEP_U),
                          0.0, 1.0))
    if outside is None:  # the steps ran out below T: as far as it was seen
        return inside[0], inside[0] == bound, steps
    while steps < PROFILE_STEPS and abs(outside[1] - T) > PROFILE_RTOL * T \
            and abs(outside[0] - inside[0]) > PROFILE_XTOL_U:
        v = _crossing(inside, outside, T, clip=0.1)
        delta, u = p.rise(v, inside[2])
        steps += 1
        if delta >= T:
            outside = (v, delta, u)
        else:
            inside = (v, delta, u)
    end = outside[0] if abs(outside[1] - T) <= PROFILE_RTOL * T else \
        _crossing(inside, outside, T, clip=0.0)
    return end, False, steps


def _crossing(inside: tuple, outside: tuple, T: float, clip: float) -> float:
    """Where √Δχ² reaches √T between the two points (linear in u), kept ``clip`` of the
    bracket away from its ends."""
    (a, da, _), (b, db, _) = inside, outside
    sa, sb = math.sqrt(max(da, 0.0)), math.sqrt(db)
    t = (math.sqrt(T) - sa) / (sb - sa) if sb > sa else 0.5
    return a + min(max(t, clip), 1.0 - clip) * (b - a)


def _integer_end(p: _Profile, d: int, T: float, neighbour) -> tuple[float, bool, int]:
    """The last integer of an integer key whose profile stays below T in direction d."""
    inside, warm, steps = p.u_hat[p.j], p.u_hat, 0
    while steps < INTEGER_STEPS:
        nxt = neighbour(p.j, inside, d)
        if nxt is None:
            return inside, True, steps
        delta, u = p.rise(nxt, warm)
        steps += 1
        if delta >= T:
            return inside, False, steps
        inside, warm = nxt, u
    return inside, False, steps
