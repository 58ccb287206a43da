"""The paper's CMOS claim (Salama et al. 2004, Sec. 4; checked in docs/background/sources.md
P11–P13).

Salama et al. 2004 claim SNR = 10 for 0.5 photons/s/µm² over 10 s on a 100 × 100 µm diode.
Noise per eq. 21 in electrons: σ² = S + D + σ_read²; SNR = S²/σ² (eq. 22, a power ratio).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from chiptwin.config import load_scenario
from chiptwin.detection import required_signal_e, snr
from chiptwin.fidelity import run
from chiptwin.pixel import dark_current_e_per_s
from tests.conftest import SCENARIOS

AREA_UM2 = 100.0 * 100.0
FLUX, T_S, READ_E = 0.5, 10.0, 100.0


def paper_snr_power(qe: float, j_nA_per_cm2: float) -> float:
    s = FLUX * AREA_UM2 * T_S * qe
    d = dark_current_e_per_s(j_nA_per_cm2, AREA_UM2, 25.0) * T_S
    return float(snr(s, (s + d + READ_E**2) ** 0.5)[0])


def test_forward_check():
    """sources.md P13: QE 0.3, J = 0.36 nA/cm², σ_read = 100 e⁻ → SNR_power ≈ 99,
    SNR_amp ≈ 9.95.

    Tolerance 1 % (the reference rounds to two digits).
    """
    p = paper_snr_power(0.3, 0.36)
    assert p == pytest.approx(99.0, rel=0.01)
    assert p**0.5 == pytest.approx(9.95, rel=0.01)


@pytest.mark.parametrize(
    ("qe", "reading", "j_expected"),
    [(0.3, "power", 3.6), (0.5, "power", 10.0), (0.3, "amplitude", 0.36), (0.5, "amplitude", 1.0)],
)
def test_inverse_dark_current_for_snr10(qe, reading, j_expected):
    """sources.md P12: the dark current density that gives exactly SNR = 10.

    Power reading (10 dB): 3.6 / 10 nA/cm² at QE 0.3 / 0.5; amplitude reading (20 dB):
    0.36 / 1.0 nA/cm². Tolerance 3 % (the table is rounded to two significant digits).
    """
    target = 10.0 if reading == "power" else 100.0
    j = brentq(lambda j: paper_snr_power(qe, j) - target, 1e-4, 1e3, xtol=1e-12)
    assert j == pytest.approx(j_expected, rel=0.03)


def test_required_signal_solves_the_quadratic():
    s = required_signal_e(10.0, 2.26e6, 1.0)
    assert s**2 / (2.26e6 + s) == pytest.approx(10.0, rel=1e-12)


def test_snr10_scenario_matches_the_composed_noise_budget():
    """The scenario's chain equals eq. 21 plus the two terms a real chip adds, composed by hand.

    σ² = S + D + σ_read² + σ_q² + (D + σ_read² + σ_q²)/K, with σ_read the CMS difference's read
    noise (100 e⁻ with M = 2), σ_q² the rounding of the two M-sample means (measured here by
    Monte Carlo: M codes of one level that differ by read noise only), and the last term the dark
    reference averaged over K = 64 frames. Tolerance 0.5 %.
    """
    s = load_scenario(SCENARIOS / "snr10_requirement.toml")
    result = run(s)
    px, adc = s.chip.pixel, s.chip.adc
    signal = FLUX * AREA_UM2 * s.chip.timing.t_int_s * px.qe
    dark = dark_current_e_per_s(px.dark_current_nA_per_cm2, AREA_UM2, 25.0) * s.chip.timing.t_int_s
    e_per_lsb = (adc.v_max_V - adc.v_min_V) / 2**adc.bits / (1.602176634e-19 / 1e-12)
    m, k = s.chip.dsp.cms_samples, s.chip.dsp.n_dark_frames
    fixed = READ_E**2 + 2 * e_per_lsb**2 * _rounding_var_of_mean(m, READ_E / e_per_lsb)
    var = signal + dark + fixed + (dark + fixed) / k
    site = result.summary["sites"][0]
    assert site["signal_e"] == pytest.approx(signal, rel=1e-9)
    assert site["snr_power"] == pytest.approx(signal**2 / var, rel=0.005)
    assert site["snr_amplitude"] == pytest.approx((signal**2 / var) ** 0.5, rel=0.005)
    # The flux that reaches power SNR 10 solves S² = 10·(var0 + S), S = flux·A·T·QE.
    var0 = dark + fixed + (dark + fixed) / k
    flux = required_signal_e(10.0, var0, 1.0) / (AREA_UM2 * s.chip.timing.t_int_s * px.qe)
    assert result.summary["required_flux_photons_per_s_per_um2"] == pytest.approx(flux, rel=0.005)


def _rounding_var_of_mean(m: int, sigma_lsb: float, n: int = 2_000_000) -> float:
    """Monte Carlo: variance of mean(round(x + noise_j)) − mean(x + noise_j), x uniform."""
    rng = np.random.default_rng(5)
    x = rng.random(n)[:, None] + sigma_lsb * rng.standard_normal((n, m))
    return float(np.var(np.mean(np.rint(x) - x, axis=1)))
