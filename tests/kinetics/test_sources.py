"""The closed-form builders give the light of their equations as PulseTrains."""

from __future__ import annotations

import numpy as np
import pytest

from chiptwin.constants import N_A
from chiptwin.kinetics import closed_form as cf
from chiptwin.kinetics import sources

T = np.array([0.0, 0.5, 3.0, 40.0])


def test_atp_assay_matches_eq12():
    amounts = np.array([1e-15, 0.0, 3e-16])
    train = sources.atp_assay(amounts, turnover_per_s=[0.1, 0.1, 1.0])
    want = cf.atp_assay_rate(T[None, :], amounts[:, None], np.array([[0.1], [0.1], [1.0]]))
    np.testing.assert_allclose(train.rate(T), want, rtol=1e-14)
    np.testing.assert_allclose(train.photons([0.0, 10.0])[:, 0],
                               cf.atp_assay_photons(10.0, amounts, [0.1, 0.1, 1.0]), rtol=1e-14)


def test_luciferase_label_is_a_constant_glow_eq13():
    train = sources.luciferase_label([1e-15, 2e-15], start_s=[0.0, 5.0])
    rate = 5.2994838688e22 * 1e-15
    np.testing.assert_allclose(train.rate([4.0, 100.0]), [[rate, rate], [0.0, 2 * rate]])
    np.testing.assert_allclose(train.photons([0.0, 10.0])[:, 0], [10 * rate, 10 * rate])


def test_substrate_and_catalyst_detection_match_eqs5_and_7():
    sub = sources.substrate_detection([2e-15], k_f_per_M_per_s=1e4, enzyme_M=3e-6)
    np.testing.assert_allclose(sub.rate(T)[0], cf.substrate_detection_rate(T, 2e-15, 1e4, 3e-6))
    cat = sources.catalyst_detection([2e-15], k_f_per_M_per_s=1e4, substrate_max_M=3e-6)
    np.testing.assert_allclose(cat.rate(T)[0], cf.catalyst_detection_rate(2e-15, 1e4, 3e-6))


def test_pyrosequencing_flows_are_pulses_scaled_by_homopolymer_length():
    """Flow k starts at start + k·period; amplitude n·N_DNA·α·k_t (eq. 19 generalised)."""
    n = np.array([1, 0, 3, 2])
    train = sources.pyrosequencing([1e-15, 2e-15], n, 60.0, start_s=[0.0, 10.0])
    assert train.n_pulses == 6  # the empty flow emits no pulse
    np.testing.assert_allclose(np.sort(train.onset_s), [0, 10, 120, 130, 180, 190])
    peak0 = cf.pyrosequencing_rate(0.0, 1e-15)
    np.testing.assert_allclose(train.rate([120.0])[0, 0], 3 * peak0 + peak0 * np.exp(-6.0))
    total = train.total_photons()
    np.testing.assert_allclose(total, np.array([6, 12]) * 17.6 * 1e-15 * N_A, rtol=1e-12)


def test_pyrosequencing_with_measured_yield_integrates_to_n_n_dna_y():
    """Amplitude n·N_DNA·Y·k_a, so the flow's light integrates to n·N_DNA·Y (sources.md
    Kinetics)."""
    train = sources.pyrosequencing([1e-15], [[2, 1]], 100.0, photons_per_incorporation=0.01)
    np.testing.assert_allclose(train.total_photons(), [3 * 1e-15 * N_A * 0.01], rtol=1e-12)
    np.testing.assert_allclose(train.amplitude_per_s, np.array([2, 1]) * 1e-15 * N_A * 0.01 * 0.05)


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: sources.atp_assay([[1e-15]]), r"atp_mol has shape \(1, 1\)"),
        (lambda: sources.atp_assay([1e-15], turnover_per_s=0.0), r"turnover_per_s = 0.0"),
        (lambda: sources.atp_assay([1e-15, 1e-15], start_s=[0, 1, 2]), r"start_s has shape"),
        (lambda: sources.pyrosequencing([1e-15], [1, 0], 0.0), r"flow_period_s = 0.0 .*> 0"),
        (lambda: sources.pyrosequencing([1e-15], [[1, 0]] * 2, 60.0), r"n_incorporated has shape"),
        (lambda: sources.pyrosequencing([1e-15], [1], 60.0, apyrase_per_s=[0.05]),
         r"apyrase_per_s has shape \(1,\): must be a scalar"),
    ],
)
def test_builder_errors(call, match):
    with pytest.raises(ValueError, match=match):
        call()
