"""The reversible mass-action reaction (paper eqs. 2–4): analytic vs numeric vs 50 digits."""

from __future__ import annotations

import mpmath
import numpy as np
import pytest

from chiptwin.constants import N_A
from chiptwin.kinetics import closed_form as cf
from chiptwin.kinetics import reversible as rv

CASES = [  # (S0, P0, E, k_f, k_r) in M and 1/(M·s)
    (1e-6, 0.0, 1e-9, 1e6, 0.0),
    (1e-6, 2e-7, 1e-9, 1e6, 3e5),
    (5e-12, 1e-12, 2e-6, 1e4, 1e5),  # equilibrium mostly substrate
    (1e-3, 0.0, 1e-3, 1e6, 1e6),  # k = 2000 s⁻¹: stiff against t up to 100 s
]
T = np.array([0.0, 1e-6, 1e-3, 0.1, 1.0, 10.0, 100.0])


def mp_product(t, s0, p0, e, k_f, k_r, dps=50):
    """[P](t) in 50 digits, from eq. 2 solved by hand."""
    with mpmath.workdps(dps):
        s0, p0, e, k_f, k_r, t = (mpmath.mpf(float(v)) for v in (s0, p0, e, k_f, k_r, t))
        k = (k_f + k_r) * e
        p_eq = k_f * (s0 + p0) / (k_f + k_r)
        return float(p_eq + (p0 - p_eq) * mpmath.exp(-k * t))


@pytest.mark.parametrize("case", CASES)
def test_analytic_matches_the_numerical_solution_of_eq2(case):
    s0, p0, e, k_f, k_r = case
    numeric = rv.solve_reversible(T, s0, e, k_f, k_r, p0, rtol=1e-11)
    analytic = rv.reversible_product_M(T, s0, e, k_f, k_r, p0)
    np.testing.assert_allclose(numeric[1], analytic, rtol=1e-8, atol=1e-9 * (s0 + p0))
    np.testing.assert_allclose(numeric.sum(axis=0), s0 + p0, rtol=1e-9)  # [S] + [P] conserved


@pytest.mark.parametrize("case", CASES)
def test_analytic_matches_50_digits(case):
    """Relative error < 1e-14 on [P], including k t = 2e5 (e^{−kt} underflows to 0)."""
    s0, p0, e, k_f, k_r = case
    t = np.array([1e-12, 1e-6, 1.0, 100.0])
    got = rv.reversible_product_M(t, s0, e, k_f, k_r, p0)
    want = [mp_product(x, s0, p0, e, k_f, k_r) for x in t]
    np.testing.assert_allclose(got, want, rtol=1e-14)


def test_photons_are_eq3_integrated_and_keep_small_kt_exact():
    """N(T) = α V N_A ([P](T) − [P0]) (eq. 4); for k T = 1e-12 expm1 keeps full precision."""
    s0, p0, e, k_f, k_r, v = 1e-6, 1e-7, 1e-12, 1.0, 0.5, 1e-9
    for t_int in (1e-12, 1.0, 1e12):
        with mpmath.workdps(50):
            k = mpmath.mpf(k_f + k_r) * mpmath.mpf(e)
            p_eq = mpmath.mpf(k_f) * mpmath.mpf(s0 + p0) / (k_f + k_r)
            want = float(0.88 * v * N_A * (p_eq - mpmath.mpf(p0))
                         * -mpmath.expm1(-k * mpmath.mpf(t_int)))
        got = rv.reversible_photons(t_int, s0, e, k_f, k_r, v, p0)
        assert got == pytest.approx(want, rel=1e-13)


def test_without_reverse_reaction_it_is_substrate_detection_eqs_5_6():
    t = np.array([-1.0, 0.0, 0.3, 30.0])
    got = rv.reversible_rate(t, 2e-6, 1e-9, 1e6, 0.0, 1e-9)
    want = cf.substrate_detection_rate(t, 2e-6 * 1e-9, 1e6, 1e-9)
    np.testing.assert_allclose(got, want, rtol=1e-14)
    np.testing.assert_allclose(rv.reversible_photons(30.0, 2e-6, 1e-9, 1e6, 0.0, 1e-9),
                               cf.substrate_detection_photons(30.0, 2e-15, 1e6, 1e-9), rtol=1e-14)


def test_source_is_the_same_light_as_a_pulse_train():
    src = rv.reversible_source([1e-6, 2e-6], 1e-9, 1e6, [2e5, 0.0], 1e-9, product0_M=1e-8,
                               start_s=[0.0, 5.0])
    edges = np.array([0.0, 1.0, 5.0, 7.0, 60.0])
    got = src.photons(edges)
    cum0 = rv.reversible_photons(edges, 1e-6, 1e-9, 1e6, 2e5, 1e-9, 1e-8)
    cum1 = rv.reversible_photons(np.maximum(edges - 5.0, 0.0), 2e-6, 1e-9, 1e6, 0.0, 1e-9, 1e-8)
    np.testing.assert_allclose(got, np.stack([np.diff(cum0), np.diff(cum1)]), rtol=1e-12)


def test_no_reaction_and_huge_kt_stay_finite():
    assert rv.reversible_rate(5.0, 1e-6, 0.0, 1e6, 1e6, 1e-9) == 0.0
    assert rv.reversible_product_M(5.0, 1e-6, 1e-6, 0.0, 0.0, 3e-7) == pytest.approx(3e-7)
    huge = rv.reversible_rate(1e4, 1e-3, 1e-3, 1e6, 1e6, 1e-9)  # k t = 2e7
    assert huge == 0.0 and np.isfinite(huge)
    assert np.isfinite(rv.reversible_photons(1e300, 1e-3, 1e-3, 1e6, 1e6, 1e-9))


def test_backward_net_reaction_is_refused_as_a_source_but_negative_by_eq3():
    assert rv.reversible_rate(0.0, 0.0, 1e-9, 1e6, 1e6, 1e-9, product0_M=1e-6) < 0
    with pytest.raises(ValueError, match=r"product0_M = 1e-06 \(at site 0\) is above the "
                                         r"equilibrium"):
        rv.reversible_source([0.0], 1e-9, 1e6, 1e6, 1e-9, product0_M=1e-6)
    with pytest.raises(ValueError, match=r"k_r_per_M_per_s = -1.0 is out of range"):
        rv.reversible_product_M(1.0, 1e-6, 1e-9, 1e6, -1.0)
