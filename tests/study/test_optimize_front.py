"""The front's pure functions against slow obvious references: the non-dominated rows by
brute force, the hypervolume exactly (rectangles by hand in 2-D) and by Monte Carlo in 3-D,
the stopping rule and the chosen point on fronts whose answer is known."""

from __future__ import annotations

import numpy as np
import pytest

from chiptwin.study.optimize_front import (
    chosen_index,
    convergence,
    hypervolume,
    pareto_mask,
    reference_point,
    stalled,
)


def _dominated_naive(F: np.ndarray) -> np.ndarray:
    """Row i is dominated when some row j is ≤ in every objective and < in one."""
    n = len(F)
    return np.array([any(all(F[j] <= F[i]) and any(F[j] < F[i]) for j in range(n) if j != i)
                     for i in range(n)])


@pytest.mark.parametrize("d", [2, 3, 4])
def test_pareto_mask_is_the_brute_force_one(d):
    rng = np.random.default_rng(d)
    F = rng.integers(0, 6, size=(60, d)).astype(float)  # integers: ties and duplicates
    assert np.array_equal(pareto_mask(F), ~_dominated_naive(F))


def test_hypervolume_of_a_staircase_in_2d_by_hand():
    # three points under reference (4, 4): rectangles 3×1 + 2×1 + 1×1 stacked = 1·3+1·2+... by
    # hand: [1,3]→(4−1)(4−3)=3; [2,2]→(4−2)(3−2)=2; [3,1]→(4−3)(2−1)=1; total 6
    F = np.array([[1.0, 3.0], [2.0, 2.0], [3.0, 1.0], [3.5, 3.5]])  # the last dominated
    assert hypervolume(F, np.array([4.0, 4.0])) == pytest.approx(6.0)
    assert hypervolume(F[:0], np.array([4.0, 4.0])) == 0.0
    assert hypervolume(np.array([[5.0, 1.0]]), np.array([4.0, 4.0])) == 0.0  # beyond ref


def test_hypervolume_in_1d_is_the_distance_to_the_reference():
    assert hypervolume(np.array([[2.0], [3.0]]), np.array([10.0])) == 8.0


def test_hypervolume_in_3d_matches_monte_carlo():
    """2·10⁵ uniform draws in the box [0, ref]: the dominated fraction's standard error is
    ≤ 0.0011 of the box; the exact value must lie within 5 of them."""
    rng = np.random.default_rng(1)
    F = rng.uniform(0.1, 1.0, size=(12, 3))
    ref = np.ones(3)
    exact = hypervolume(F, ref)
    u = rng.uniform(0.0, 1.0, size=(200_000, 3))
    dominated = np.zeros(len(u), dtype=bool)
    for f in F:
        dominated |= np.all(u >= f, axis=1)
    p = dominated.mean()
    se = np.sqrt(p * (1 - p) / len(u))
    assert abs(exact - p) < 5 * se


def test_reference_point_is_the_nadir_pushed_out_or_the_given_value():
    F = np.array([[1.0, -10.0], [3.0, -20.0]])
    ref = reference_point(F, [None, 0.0])
    assert ref[0] == pytest.approx(3.0 + 0.1 * 2.0) and ref[1] == 0.0
    assert reference_point(np.array([[2.0]]), [None])[0] == pytest.approx(2.2)  # no span
    assert np.isinf(reference_point(np.zeros((0, 1)), [None])[0])  # no feasible point


def test_convergence_counts_feasible_points_only_and_never_falls():
    F = np.array([[3.0, 3.0], [1.0, 1.0], [2.0, 2.0], [0.5, 2.5]])
    feasible = np.array([True, False, True, True])
    curve = convergence(F, feasible, np.array([4.0, 4.0]))
    assert curve[0] == curve[1] == 1.0  # the infeasible (1, 1) adds nothing
    assert curve[2] == 4.0 and curve[3] == pytest.approx(4.0 + 1.5 * 1.5)
    assert all(b >= a for a, b in zip(curve, curve[1:], strict=False))


def test_stalled_needs_a_front_and_k_more_evaluations():
    assert not stalled([0.0] * 30, 0.01, 5)  # no feasible front yet: go on
    assert not stalled([1.0, 1.0], 0.01, 5)  # fewer than k + 1 evaluations
    assert stalled([1.0] * 6, 0.01, 5)
    assert not stalled([1.0] * 5 + [1.02], 0.01, 5)  # 2 % gained over the last 5
    assert not stalled([1.0] * 6, 0.0, 5)  # gain 0: the budget alone


def test_chosen_point_is_the_knee_of_a_convex_front():
    x = np.linspace(0.0, 1.0, 11)
    F = np.column_stack([x, (1 - np.sqrt(x)) ** 2])  # a convex front bowing towards (0, 0)
    i = chosen_index(F)
    assert F[i, 0] == pytest.approx(0.3, abs=0.051)  # nearest the ideal (0, 0): x = 1/4
    assert chosen_index(np.array([[3.0], [1.0], [2.0]])) == 1  # one objective: its best


def test_a_constraint_is_judged_by_its_bound_or_its_estimate():
    """Optuna's convention: ≤ 0 is met. ``<=`` reads the one-sided upper bound, ``>=`` the
    lower; ``judged = "estimate"`` the estimate; an infinite bound (a mean of one run) is not
    met."""
    from chiptwin.detection.stats import Estimate
    from chiptwin.study.optimize import judged
    from chiptwin.study.optimize_spec import Constraint

    e = Estimate(1.0e-4, 0.0, 3.0e-4, 0.0, 2.5e-4, 4, "test")
    assert judged(Constraint("base_error_rate", "<=", 1e-3), e) == pytest.approx(2.5e-4 - 1e-3)
    assert judged(Constraint("base_error_rate", "<=", 2e-4), e) > 0  # the bound is above
    assert judged(Constraint("base_error_rate", "<=", 2e-4, "estimate"), e) < 0
    assert judged(Constraint("snr_power", ">=", -1.0), e) == pytest.approx(-1.0)
    one = Estimate(5.0, -np.inf, np.inf, -np.inf, np.inf, 1, "t (n < 2: none)")
    assert judged(Constraint("snr_power", ">=", 1.0), one) == np.inf


def test_an_objective_without_a_finite_estimate_fails_the_trial():
    from chiptwin.detection.stats import Estimate
    from chiptwin.study.optimize import unusable
    from chiptwin.study.optimize_spec import Objective

    objs = (Objective("energy_per_base_nj", "minimize"),)
    finite = Estimate(2.0, 1.0, 3.0, 1.5, 2.5, 3, "test")
    assert unusable({"energy_per_base_nj": finite}, objs) == ""
    assert "no run of the point finished" in unusable({}, objs)
    inf = Estimate(np.inf, np.nan, np.nan, np.nan, np.nan, 3, "test")
    assert "not a finite objective" in unusable({"energy_per_base_nj": inf}, objs)
