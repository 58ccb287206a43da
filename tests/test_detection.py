"""Window totals and their variances, checked against Monte Carlo draws of the model they assume."""

from __future__ import annotations

import numpy as np
import pytest

from chiptwin.detection import snr, window_sums


@pytest.mark.parametrize("decay", [None, 0.05])
def test_window_sum_variance_matches_monte_carlo(decay):
    """Outputs y_j = A·exp(−k t_j) + e_j − d (e_j independent, d the common dark-reference error):
    the estimator's mean and variance over 40 000 draws agree with the returned ones (1 % / 3 %).
    The draws go through one call as 40 000 pixels (columns are estimated independently: the
    first 200, one call each, are the same numbers)."""
    rng = np.random.default_rng(1)
    t = np.arange(2.0, 60.0, 4.0)  # block mid-times of one 60 s flow, N = 4
    shape = np.exp(-0.05 * t)
    var_e, var_d, n, draws = 2.0e4, 5.0e3, 4, 40_000
    y = (1.0e5 * shape[None, :] + rng.normal(0, np.sqrt(var_e), (draws, t.size))
         - rng.normal(0, np.sqrt(var_d), (draws, 1)))
    est = window_sums(t, y.T, np.zeros((t.size, draws)), np.zeros(draws), n,
                      np.array([0.0, 60.0]), decay)[0][0]
    for i in range(200):
        one = window_sums(t, y[i][:, None], np.zeros((t.size, 1)), np.zeros(1), n,
                          np.array([0.0, 60.0]), decay)[0][0, 0]
        assert one == est[i]
    _, var = window_sums(t, np.zeros((t.size, 1)), np.full((t.size, 1), var_e),
                         np.array([var_d]), n, np.array([0.0, 60.0]), decay)
    assert est.mean() == pytest.approx(n * 1.0e5 * shape.sum(), rel=0.01)
    assert est.var() == pytest.approx(var[0, 0], rel=0.03)


def test_snr_power_is_the_square_of_amplitude():
    power, amplitude = snr(np.array([300.0, 300.0]), np.array([100.0, 0.0]))
    assert power[0] == pytest.approx(9.0) and amplitude[0] == pytest.approx(3.0)
    assert np.isinf(amplitude[1])


def test_snr_without_noise():
    """No noise: a signal is infinitely above it (sign kept), no signal is SNR 0, not inf
    (a dark, noiseless site was reported "detected")."""
    power, amplitude = snr(np.array([5.0, -5.0, 0.0, 3.0]), np.array([0.0, 0.0, 0.0, 1.5]))
    assert list(amplitude) == [np.inf, -np.inf, 0.0, 2.0]
    assert list(power) == [np.inf, np.inf, 0.0, 4.0]


def test_detection_is_one_sided():
    """No light (atp_glow at 1e-9 fmol), a threshold of power SNR 1 (amplitude 1), 30 seeds ×
    3 sites: a site whose estimate is strongly negative is no detection, so the rate is
    P(Z > 1) = 0.159 ± 4 binomial σ, not the two-sided 0.317 it was (12 of 25 detections had a
    negative signal)."""
    import chiptwin

    signed, detected = [], []
    for seed in range(30):
        r = chiptwin.run("atp_glow", ["assay.atp_fmol=1e-9", "run.detection_snr_power=1"],
                         seed=seed)
        signed += [s["signal_e"] / s["noise_e"] for s in r.summary["sites"]]
        detected += [s["detected"] for s in r.summary["sites"]]
    z, det = np.array(signed), np.array(detected)
    assert z.size == 90 and not np.any(det & (z < 0))
    p = 0.1587
    assert abs(det.mean() - p) <= 4 * np.sqrt(p * (1 - p) / z.size)
