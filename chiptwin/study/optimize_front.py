"""The Pareto front of an optimize study, its hypervolume, the chosen point and the stopping rule.

Pure array functions over objective values already turned to minimisation (``sign · value``,
:attr:`~chiptwin.study.optimize_spec.Objective.sign`), one row per evaluated point:

- :func:`pareto_mask`: the non-dominated rows (Deb et al., "A fast and elitist multiobjective
  genetic algorithm: NSGA-II", IEEE Trans. Evol. Comput. 6:182, 2002, Sec. III-A);
- :func:`hypervolume`: the volume the front dominates up to a reference point (Zitzler &
  Thiele, "Multiobjective evolutionary algorithms: a comparative case study", IEEE Trans. Evol.
  Comput. 3:257, 1999), exact: a sweep in 2-D, slicing objectives away in more (While et al.,
  "A faster algorithm for calculating hypervolume", IEEE Trans. Evol. Comput. 10:29, 2006);
- :func:`reference_point`: the nadir of the feasible points pushed out by
  :data:`REFERENCE_MARGIN` of their span (Ishibuchi et al., "How to specify a reference point
  in hypervolume calculation for fair performance comparison", Evol. Comput. 26:411, 2018);
- :func:`chosen_index`: the front's point nearest the ideal point after normalising each
  objective to its span over the front (the compromise solution, Zeleny, "Compromise
  programming", 1973); with one objective the best feasible point;
- :func:`convergence` and :func:`stalled`: the hypervolume after each evaluation and the rule
  that stops the search when it no longer grows.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

#: Fraction of the feasible points' span (nadir − ideal) the reference point lies beyond the
#: nadir, so that the front's extreme points add volume (Ishibuchi et al. 2018, Sec. 5).
REFERENCE_MARGIN: float = 0.1
CHOSEN_RULE = ("the point of the feasible Pareto front nearest the ideal point (each "
               "objective's best over the front), each objective normalised to its span over "
               "the front: the compromise solution (Zeleny 1973)")
CHOSEN_RULE_ONE = "the feasible point with the best objective"


def minimised(records: list[dict], objectives: tuple) -> NDArray[np.float64]:
    """Evaluated points' objective values (``record["metrics"][name].value``) turned to
    minimisation (``sign · value``): points × objectives; NaN where a failed point has none."""
    return np.array([[o.sign * r["metrics"][o.metric].value if o.metric in r["metrics"]
                      else np.nan for o in objectives]
                     for r in records], dtype=float).reshape(-1, len(objectives))


def pareto_mask(F: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Rows of ``F`` (points × objectives, minimised) that no other row dominates (no worse in
    every objective and better in one). Equal rows are all kept."""
    F = np.asarray(F, dtype=float)
    keep = np.ones(len(F), dtype=bool)
    for i, f in enumerate(F):
        dominated = np.all(F <= f, axis=1) & np.any(F < f, axis=1)
        keep[i] = not dominated.any()
    return keep


def hypervolume(F: NDArray[np.float64], ref: NDArray[np.float64]) -> float:
    """The volume dominated by the rows of ``F`` and bounded by ``ref`` (minimisation); rows
    not strictly better than ``ref`` in every objective add nothing. Exact."""
    F = np.asarray(F, dtype=float).reshape(-1, len(ref))
    ref = np.asarray(ref, dtype=float)
    F = F[np.all(F < ref, axis=1)]
    if len(F) == 0:
        return 0.0
    F = np.unique(F[pareto_mask(F)], axis=0)
    return _hv(F, ref)


def _hv(F: NDArray[np.float64], ref: NDArray[np.float64]) -> float:
    if F.shape[1] == 1:
        return float(ref[0] - F[:, 0].min())
    if F.shape[1] == 2:
        F = F[np.argsort(F[:, 0])]
        best2, total = ref[1], 0.0
        for x, y in F:
            if y < best2:
                total += (ref[0] - x) * (best2 - y)
                best2 = y
        return float(total)
    # slice along the last objective: between consecutive values, the (d−1)-volume of the
    # points at or below the slice
    F = F[np.argsort(F[:, -1])]
    total = 0.0
    for i in range(len(F)):
        top = F[i + 1, -1] if i + 1 < len(F) else ref[-1]
        if top > F[i, -1]:
            below = F[: i + 1, :-1]
            total += (top - F[i, -1]) * _hv(below[pareto_mask(below)], ref[:-1])
    return float(total)


def reference_point(F_feasible: NDArray[np.float64], given: list[float | None]
                    ) -> NDArray[np.float64]:
    """Per objective (minimised): the given value, else the feasible points' worst pushed out
    by :data:`REFERENCE_MARGIN` of their span (of the value's magnitude, or 1, with no span)."""
    F = np.asarray(F_feasible, dtype=float).reshape(-1, len(given))
    out = np.zeros(len(given))
    for j, g in enumerate(given):
        if g is not None:
            out[j] = g
            continue
        if len(F) == 0:
            out[j] = np.inf
            continue
        worst, best = F[:, j].max(), F[:, j].min()
        span = worst - best or abs(worst) or 1.0
        out[j] = worst + REFERENCE_MARGIN * span
    return out


def convergence(F: NDArray[np.float64], feasible: NDArray[np.bool_],
                ref: NDArray[np.float64]) -> list[float]:
    """The feasible front's hypervolume after each of the evaluations, in their order."""
    F = np.asarray(F, dtype=float)
    return [hypervolume(F[: i + 1][feasible[: i + 1]], ref) for i in range(len(F))]


def stalled(curve: list[float], gain: float, last: int) -> bool:
    """True once the hypervolume grew by less than ``gain`` of itself over the last ``last``
    evaluations (never before a feasible front, nor before ``last`` evaluations more)."""
    if gain <= 0 or len(curve) <= last or curve[-1] <= 0:
        return False
    return (curve[-1] - curve[-1 - last]) < gain * curve[-1]


def chosen_index(F_front: NDArray[np.float64]) -> int:
    """Index into the front of the chosen point (:data:`CHOSEN_RULE`; one objective: its
    best)."""
    F = np.asarray(F_front, dtype=float)
    if F.shape[1] == 1:
        return int(np.argmin(F[:, 0]))
    lo, hi = F.min(axis=0), F.max(axis=0)
    span = np.where(hi > lo, hi - lo, 1.0)
    return int(np.argmin(np.linalg.norm((F - lo) / span, axis=1)))
