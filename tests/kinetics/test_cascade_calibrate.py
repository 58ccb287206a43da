"""Calibration: recovering known constants from synthetic targets; the measured yield."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from chiptwin.kinetics import RONAGHI_PHOTONS_PER_INCORPORATION
from chiptwin.kinetics.calibrate import (
    fit_light_curve,
    fit_photon_yield,
    photon_yield,
    single_flow_rate,
)
from chiptwin.kinetics.cascade_params import CascadeParams


def test_yield_in_the_linear_regime_is_eq19_integrated():
    """sources.md Kinetics: α k_t / k_a = 17.6 photons per base (1 amol in 1 nL: 1 nM ≪ every K_m,
    dispensed nucleotide not occupying apyrase)."""
    p = replace(CascadeParams(), apyrase_km_dntp_M=1.0, apyrase_kcat_dntp_per_s=5e5)
    assert photon_yield(p, dna_mol=1e-18) == pytest.approx(17.6, rel=2e-3)


def test_light_curve_fit_recovers_known_constants():
    """Synthetic curve from luciferase × 0.3 and apyrase × 2 of the defaults; the fit starts
    at the defaults and must land within 1e-6 (relative) with a residual below 1e-9."""
    start = CascadeParams()
    truth = replace(start, luciferase_M=0.3 * start.luciferase_M, apyrase_M=2 * start.apyrase_M)
    t = np.linspace(0.2, 60.0, 30)
    result = fit_light_curve(t, single_flow_rate(truth, t), start)
    assert result.success
    assert result.values["luciferase_M"] == pytest.approx(truth.luciferase_M, rel=1e-6)
    assert result.values["apyrase_M"] == pytest.approx(truth.apyrase_M, rel=1e-6)
    assert result.residual < 1e-9
    assert result.params.luciferase_M == result.values["luciferase_M"]


def test_yield_fit_reaches_the_measured_yield():
    """Ronaghi's ≈ 0.01 photon per base (sources.md Kinetics) at 1 fmol in 1 nL: luciferase is the
    free constant; the linear regime predicts [L] = 0.01 k_a K_m / (α k_cat sat) ≈ 6.3e-8 M."""
    p = CascadeParams()
    result = fit_photon_yield(RONAGHI_PHOTONS_PER_INCORPORATION, p)
    assert result.success and result.residual < 1e-9
    assert photon_yield(result.params) == pytest.approx(0.01, rel=1e-9)
    linear = p.luciferase_M * 0.01 / p.linear_photons_per_incorporation()
    assert result.values["luciferase_M"] == pytest.approx(linear, rel=0.02)


def test_yield_can_be_fitted_through_apyrase_too():
    result = fit_photon_yield(1.0, CascadeParams(), free="apyrase_M")
    assert photon_yield(result.params) == pytest.approx(1.0, rel=1e-9)
    assert result.values["apyrase_M"] > CascadeParams().apyrase_M  # more apyrase, less light


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: fit_photon_yield(0.01, CascadeParams(), free="colour"),
         "free = 'colour' is not a numeric CascadeParams field"),
        (lambda: fit_photon_yield(0.01, CascadeParams(), free="product_inhibition"),
         "free = 'product_inhibition' is not a numeric"),
        (lambda: fit_photon_yield(0.0, CascadeParams()),
         r"target_photons_per_incorporation = 0.0 is out of range"),
        (lambda: fit_light_curve([0.0, 1.0], [0.0, 0.0], CascadeParams()), "with some light"),
        (lambda: photon_yield(replace(CascadeParams(), apyrase_M=0.0)), "needs apyrase"),
    ],
)
def test_bad_calibration_input(call, match):
    with pytest.raises(ValueError, match=match):
        call()
