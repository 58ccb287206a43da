"""The calibration's pieces against obvious references: the residual and its offset, the
errors' scales, profile intervals of a linear model (where the profile likelihood is exactly
û ± √(T·C_jj)), the smoothness check, a key's scale, and the calibrated scenario's TOML."""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest

from chiptwin.study.calibrate_data import Measured, block_scales, residuals
from chiptwin.study.calibrate_fit import PROFILE_RTOL, FitResult, Problem, smoothness
from chiptwin.study.calibrate_outputs import toml_value
from chiptwin.study.calibrate_profile import profiles
from chiptwin.study.calibrate_spec import FitParameter


def measured(values, se, block, names, offset=None, weighted=True) -> Measured:
    n = len(values)
    return Measured(np.array(values, float), np.array(se, float), np.array(block),
                    tuple(names), np.zeros(n, bool) if offset is None else np.array(offset),
                    np.arange(n, dtype=float), "x", weighted)


def test_the_residual_carries_both_standard_errors_and_the_profiled_offset():
    m = measured([10.0, 20.0, 3.0], [1.0, 2.0, 0.5], [0, 0, 1], ("mean", "var"),
                 offset=[True, True, False])
    sim, sim_se = np.array([8.0, 19.0, 3.5]), np.array([1.0, 1.0, 0.5])
    r, delta = residuals(m, sim, sim_se)
    w = 1 / np.array([2.0, 5.0])  # 1/(se² + se_sim²) of the two means
    assert delta == pytest.approx((w @ np.array([2.0, 1.0])) / w.sum())  # weighted mean gap
    sigma = np.sqrt([2.0, 5.0, 0.5])
    assert r == pytest.approx((sim + delta * np.array([1, 1, 0]) - m.values) / sigma)
    scaled, _ = residuals(m, sim, sim_se, np.array([1.0, 2.0]))
    assert scaled[2] == pytest.approx(r[2] / 2.0) and scaled[0] == pytest.approx(r[0])


def test_least_squares_ignores_the_simulated_errors_and_its_scale_is_estimated():
    m = measured([1.0, 2.0, 3.0, 4.0], np.ones(4), [0] * 4, ("y",), weighted=False)
    r, _ = residuals(m, np.array([1.5, 2.5, 2.5, 4.5]), np.full(4, 9.0))
    assert r == pytest.approx([0.5, 0.5, -0.5, 0.5])
    (s,) = block_scales(m, r, 1)
    assert s == pytest.approx(math.sqrt((r @ r) / 3))  # √(RSS/(n − p)), below 1 too


@pytest.mark.parametrize(("chi2_b", "expected"), [(0.5, 1.0), (4.0, 2.0)])
def test_measured_errors_are_scaled_by_the_birge_ratio_only_upwards(chi2_b, expected):
    m = measured([0.0] * 4, np.ones(4), [0, 0, 1, 1], ("a", "b"))
    # 4 values, 2 parameters: each block's share of the 2 degrees of freedom is 1
    r = np.array([math.sqrt(chi2_b), 0.0, 1.0, 0.0])
    assert block_scales(m, r, 2) == pytest.approx([expected, 1.0])


class Linear(Problem):
    """r(u) = A u − b: the profile likelihood's interval is û ± √(T·C_jj), C = (AᵀA)⁻¹."""

    def __init__(self, a: np.ndarray, b: np.ndarray) -> None:
        self.a, self.b = a, b
        self.k = a.shape[1]
        self.integer = np.zeros(self.k, bool)
        self.n = a.shape[0]

    def residuals(self, us, stage):
        return [self.a @ u - self.b for u in us]


def test_profiles_of_a_linear_model_are_its_exact_intervals():
    rng = np.random.default_rng(3)
    a = rng.normal(size=(12, 3)) * [40.0, 25.0, 60.0]
    a[:, 1] += 0.8 * a[:, 0]  # two correlated keys: the others must be re-optimised
    u_true = np.array([0.4, 0.5, 0.6])
    problem = Linear(a, a @ u_true + rng.normal(size=12))
    u_hat = np.linalg.lstsq(a, problem.b, rcond=None)[0]
    r = a @ u_hat - problem.b
    fit = FitResult(u_hat, float(r @ r), r, a, 3.84)
    c = fit.covariance()
    out = profiles(problem, u_hat, float(r @ r), 3.84, c, a, None)
    for j, iv in enumerate(out.intervals):
        half = math.sqrt(3.84 * c[j, j])
        assert not (iv.open_lo or iv.open_hi)
        # the end is within PROFILE_RTOL of T in Δχ²: within ≈ RTOL/2 of the half-width
        assert iv.lo == pytest.approx(u_hat[j] - half, abs=PROFILE_RTOL * half)
        assert iv.hi == pytest.approx(u_hat[j] + half, abs=PROFILE_RTOL * half)
    assert out.better is None


def test_a_key_the_data_do_not_bound_is_open_at_its_range_end():
    a = np.array([[10.0, 0.0], [0.0, 1e-3], [5.0, 0.0]])  # key 1 barely moves anything
    problem = Linear(a, np.array([4.0, 0.0, 2.0]))
    u_hat = np.array([0.4, 0.5])
    r = a @ u_hat - problem.b
    fit = FitResult(u_hat, float(r @ r), r, a, 3.84)
    iv = profiles(problem, u_hat, float(r @ r), 3.84, fit.covariance(), a, None).intervals[1]
    assert (iv.lo, iv.hi, iv.open_lo, iv.open_hi) == (0.0, 1.0, True, True)


class Jittery(Linear):
    """A linear model plus a draw that changes whenever u changes at all (broken common random
    numbers): the smoothness check must flag it."""

    def residuals(self, us, stage):
        return [self.a @ u - self.b + (0.0 if np.array_equal(u, U0) else 2.0) for u in us]


U0 = np.array([0.5, 0.5])


def test_the_smoothness_check_flags_draws_that_are_not_common():
    a = np.eye(2) * 10.0
    for cls, smooth in ((Linear, True), (Jittery, False)):
        problem = cls(a, a @ U0)
        s = smoothness(problem, U0, 0.0, 3.84)
        assert s["smooth"] is smooth, s


@pytest.mark.parametrize(("lo", "hi", "log", "integer", "u", "value"), [
    (0.2, 0.8, False, False, 0.5, 0.5), (1.0, 100.0, True, False, 0.5, 10.0),
    (6.0, 16.0, False, True, 0.26, 9), (1.0, 100.0, True, False, 1.5, 100.0),
])
def test_a_keys_value_in_u(lo, hi, log, integer, u, value):
    p = FitParameter("k", lo, hi, log, integer, "why", lo)
    assert p.value(u) == pytest.approx(value)
    if not integer and 0 <= u <= 1:
        assert p.unit(p.value(u)) == pytest.approx(u)


def test_toml_values_read_back():
    table = {"a": 1, "b": 0.1, "c": "x \"q\" µ", "d": [[1, 2], [3, 4]], "e": True,
             "f": [{"name": "SiO2", "n": 1.46}], "g": 1e-300}
    text = "\n".join(f"{k} = {toml_value(v)}" for k, v in table.items())
    assert tomllib.loads(text) == table
