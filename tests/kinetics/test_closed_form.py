"""Closed-form kinetics (Salama et al., Biosens. Bioelectron. 19, 2004, eqs. 2–19).

Validation tests reproduce the numbers of docs/background/sources.md (Kinetics); unit tests check
that each photon count is the integral of its rate and that the functions stay finite at the
extremes.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate

from chiptwin.constants import N_A
from chiptwin.kinetics import closed_form as cf

FMOL = 1e-15


# --- validation against sources.md Kinetics -------------------------------------------------------


def test_prefactor_glow_is_5p3e22():
    """Eqs. 12–13 prefactor 5.3e22 = N_A·0.88·0.1 (sources.md K7).

    Tolerance: the paper prints two significant digits, so |x − 5.3e22| ≤ 0.05e22; the exact
    product is also checked to 1e-12.
    """
    value = cf.emission_prefactor(alpha=0.88, turnover_per_s=0.1)
    assert value == pytest.approx(5.3e22, abs=0.05e22)
    assert value == pytest.approx(N_A * 0.88 * 0.1, rel=1e-12)


def test_prefactor_flash_is_5p3e23():
    """Eq. 19 prefactor 5.3e23 = N_A·0.88·1.0 (sources.md Kinetics). Tolerance: two printed
    digits."""
    value = cf.emission_prefactor(alpha=0.88, turnover_per_s=1.0)
    assert value == pytest.approx(5.3e23, abs=0.05e23)
    assert value == pytest.approx(N_A * 0.88, rel=1e-12)


def test_defaults_give_the_papers_prefactors():
    """The default α and turnover reproduce eq. 12 (glow) for 1 mol of ATP at t = 0."""
    assert cf.atp_assay_rate(0.0, 1.0) == pytest.approx(N_A * 0.88 * 0.1, rel=1e-12)
    assert cf.luciferase_label_rate(1.0) == pytest.approx(N_A * 0.88 * 0.1, rel=1e-12)
    assert cf.pyrosequencing_rate(0.0, 1.0) == pytest.approx(N_A * 0.88, rel=1e-12)


def test_photons_per_incorporation_is_17p6():
    """α·k_t/k_a = 0.88·1/0.05 = 17.6 photons per incorporated base (sources.md Kinetics, derived
    from eq. 19). Tolerance: rel 1e-12 (exact arithmetic)."""
    assert cf.incorporation_yield() == pytest.approx(17.6, rel=1e-12)
    total = cf.pyrosequencing_photons(1e6, 1.0 / N_A)  # one strand, T → ∞ (e^-5e4 = 0)
    assert total == pytest.approx(17.6, rel=1e-12)


def test_one_fmol_pyrosequencing_by_eq19():
    """1 fmol by eq. 19: peak 5.3e8 photons/s, 1.06e10 photons in total, 39 % in the first 10 s
    (sources.md K10, derived). Tolerance: the printed digits
    (±0.05e8, ±0.005e10, ±0.5 %); exact values to 1e-12."""
    peak = cf.pyrosequencing_rate(0.0, FMOL)
    total = cf.pyrosequencing_photons(1e4, FMOL)
    first_10s = cf.pyrosequencing_photons(10.0, FMOL)
    assert peak == pytest.approx(5.3e8, abs=0.05e8)
    assert total == pytest.approx(1.06e10, abs=0.005e10)
    assert first_10s / total == pytest.approx(0.39, abs=0.005)
    assert peak == pytest.approx(FMOL * N_A * 0.88, rel=1e-12)
    assert first_10s / total == pytest.approx(-math.expm1(-0.5), rel=1e-12)


def test_ronaghi_yield_gives_0p01_photon_per_incorporation():
    """With the measured yield (Ronaghi, Genome Res. 11, 2001: ≈ 0.01 photon per ATP), 1 fmol gives
    ≈ 6e6 photons in total, the figure of the open question in sources.md P17. Tolerance: rel 1e-12
    for the exact product, 5 % for the quoted 6e6."""
    total = cf.pyrosequencing_photons(1e4, FMOL, photons_per_incorporation=0.01)
    assert total == pytest.approx(FMOL * N_A * 0.01, rel=1e-12)
    assert total == pytest.approx(6e6, rel=0.05)


def test_ando_quantum_yield_scales_linearly():
    """α = 0.41 (Ando et al. 2008) scales every photon figure by 0.41/0.88."""
    ratio = cf.pyrosequencing_rate(0.0, FMOL, alpha=cf.ALPHA_ANDO) / cf.pyrosequencing_rate(
        0.0, FMOL)
    assert ratio == pytest.approx(0.41 / 0.88, rel=1e-12)


# --- eqs. 2–3 ------------------------------------------------------------------------------------


def test_mass_action_rate_eq2():
    assert cf.mass_action_rate(2.0, 3.0, 5.0) == pytest.approx(30.0)
    assert cf.mass_action_rate(2.0, 3.0, 5.0, 1.0, 4.0) == pytest.approx(30.0 - 20.0)
    out = cf.mass_action_rate(1.0, np.array([1.0, 2.0]), np.array([[1.0], [3.0]]))
    assert out.shape == (2, 2)


def test_photon_rate_eq3_links_mass_action_to_substrate_detection():
    """Eq. 5 is eq. 3 applied to eq. 2 at t = 0 with [E] constant and no back reaction."""
    k_f, s0, e, v = 1e5, 1e-6, 1e-8, 1e-9
    direct = cf.photon_rate(cf.mass_action_rate(k_f, s0, e), v)
    assert direct == pytest.approx(cf.substrate_detection_rate(0.0, v * s0, k_f, e), rel=1e-12)


# --- each count is the integral of its rate --------------------------------------------------


@pytest.mark.parametrize("t_int", [0.0, 0.3, 10.0, 200.0])
def test_counts_are_integrals_of_rates(t_int):
    """N(T) of eqs. 6, 8, 12, 13, 19 against scipy.integrate.quad of I(t) (rel 1e-9)."""
    pairs = [
        (lambda t: cf.substrate_detection_rate(t, 2e-15, 1e4, 3e-6),
         cf.substrate_detection_photons(t_int, 2e-15, 1e4, 3e-6)),
        (lambda t: cf.catalyst_detection_rate(2e-15, 1e4, 3e-6),
         cf.catalyst_detection_photons(t_int, 2e-15, 1e4, 3e-6)),
        (lambda t: cf.atp_assay_rate(t, 1e-15, 1.0), cf.atp_assay_photons(t_int, 1e-15, 1.0)),
        (lambda t: cf.luciferase_label_rate(1e-15), cf.luciferase_label_photons(t_int, 1e-15)),
        (lambda t: cf.pyrosequencing_rate(t, 1e-15, 3),
         cf.pyrosequencing_photons(t_int, 1e-15, 3)),
        (lambda t: cf.pyrosequencing_rate(t, 1e-15, 2, photons_per_incorporation=0.01),
         cf.pyrosequencing_photons(t_int, 1e-15, 2, photons_per_incorporation=0.01)),
    ]
    for rate, count in pairs:
        expected = integrate.quad(rate, 0.0, t_int, epsabs=0, epsrel=1e-12, limit=200)[0]
        assert count == pytest.approx(expected, rel=1e-9, abs=0)


def test_atp_assay_gives_alpha_photons_per_atp():
    """An ATP assay yields α photons per ATP in total (sources.md K8)."""
    for k_t in (cf.ATP_TURNOVER_GLOW_PER_S, cf.ATP_TURNOVER_FLASH_PER_S):
        assert cf.atp_assay_photons(1e5, 1.0 / N_A, k_t) == pytest.approx(0.88, rel=1e-12)


def test_rate_is_zero_before_mixing_and_vectorised():
    t = np.array([-5.0, -1e-12, 0.0, 1.0])
    out = cf.atp_assay_rate(t, np.array([[1e-15], [2e-15]]))
    assert out.shape == (2, 4)
    assert (out[:, :2] == 0).all() and (out[:, 2:] > 0).all()
    assert isinstance(cf.atp_assay_rate(1.0, 1e-15), np.floating)


# --- hard cases ----------------------------------------------------------------------------------


@pytest.mark.parametrize("k", [0.0, 1e-300, 1e-12, 1e-3, 1.0, 1e6, 1e300])
@pytest.mark.parametrize("t", [0.0, 1e-9, 1.0, 1e4, 1e12])
def test_no_nan_or_inf_for_extreme_rates_and_times(k, t):
    """Huge k·t underflows to 0 cleanly, tiny k·t keeps its digits (expm1), no 0·inf.

    The one legitimate overflow is the peak rate itself at t = 0 when k·N exceeds 1.8e308."""
    with np.errstate(over="ignore"):  # the peak rate at t = 0 may exceed the float range
        rate = cf.substrate_detection_rate(t, 1e-15, k, 1.0)
    count = cf.substrate_detection_photons(t, 1e-15, k, 1.0)
    assert np.isfinite(count) and count >= 0
    assert not np.isnan(rate) and rate >= 0
    if t > 0 or k < 1e200:
        assert np.isfinite(rate)
    exact_fraction = -math.expm1(-k * t) if k * t < 700 else 1.0
    if k > 0:
        assert count == pytest.approx(1e-15 * N_A * 0.88 * exact_fraction, rel=1e-12)
    else:
        assert count == 0.0


def test_small_kt_keeps_relative_precision():
    """(1 − e^{−kT}) for kT = 1e-14 would lose every digit without expm1."""
    count = cf.atp_assay_photons(1e-13, 1.0, 0.1)
    assert count == pytest.approx(N_A * 0.88 * 0.1 * 1e-13, rel=1e-12)


# --- errors --------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: cf.atp_assay_rate(0.0, -1e-15), r"atp_mol = -1e-15 .*>= 0"),
        (lambda: cf.atp_assay_rate(0.0, 1e-15, alpha=1.5), r"alpha = 1.5 .*\[0, 1\]"),
        (lambda: cf.pyrosequencing_rate(0.0, 1e-15, apyrase_per_s=0.0), r"apyrase_per_s = 0.0"),
        (lambda: cf.pyrosequencing_photons(-1.0, 1e-15), r"t_int_s = -1.0 .*>= 0"),
        (lambda: cf.atp_assay_rate(np.nan, 1e-15), r"t_s = nan .*finite"),
        (lambda: cf.atp_assay_rate(0.0, [1e-15, -2.0]), r"atp_mol = -2.0 \(at index 1\)"),
        (lambda: cf.atp_assay_rate(0.0, "lots"), r"atp_mol = 'lots' is not a number"),
        (lambda: cf.pyrosequencing_rate(0.0, 1e-15, photons_per_incorporation=-1),
         r"photons_per_incorporation = -1.0"),
    ],
)
def test_bad_arguments_name_argument_value_and_range(call, match):
    with pytest.raises(ValueError, match=match):
        call()
