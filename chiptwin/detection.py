"""Detection: from DSP outputs to per-site signal, noise, SNR, decisions and base calls.

SNR follows the paper: SNR = Q²/σ² (Salama et al. 2004, eq. 22) is a POWER ratio; its square root,
the amplitude ratio, is reported beside it and always labelled (REFERENCE §4).
"""

from __future__ import annotations

import math

import numpy as np

SNR_DEFINITION = (
    "snr_power = signal² / noise² (Salama et al. 2004, eq. 22, a power ratio); "
    "snr_amplitude = signal / noise = √snr_power"
)


def snr(signal_e: np.ndarray | float, noise_e: np.ndarray | float) -> tuple:
    """Power and amplitude SNR of a signal with the given noise standard deviation.

    Returns
    -------
    (snr_power, snr_amplitude) : power ratio Q²/σ² (eq. 22) and amplitude ratio Q/σ.
    """
    signal_e, noise_e = np.asarray(signal_e, float), np.asarray(noise_e, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        amplitude = np.where(noise_e > 0, signal_e / noise_e, np.inf)
    return amplitude**2, amplitude


def window_sums(
    block_t_s: np.ndarray,
    values: np.ndarray,
    var: np.ndarray,
    dark_var: np.ndarray,
    frames_per_block: int,
    edges_s: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Sum DSP outputs over time windows, in frame units, with the variance of each sum.

    Each output is the average of ``frames_per_block`` dark-subtracted frames, so its contribution
    to a window total is ``value · frames_per_block``. Independent variances add; the dark
    reference is common to every output, so its variance adds coherently (× count²).

    Parameters
    ----------
    block_t_s : array (n_blocks,)
        Time of each output (the middle of its frames). Unit: s.
    values, var : array (n_blocks, n_pixels)
        Outputs and their independent variances. Unit: any (LSB or e⁻), and its square.
    dark_var : array (n_pixels,)
        Variance of the dark reference, same unit squared.
    frames_per_block : int
        N of the N-frame average.
    edges_s : array (n_windows + 1,)
        Window edges; an output belongs to the window its time falls in. Unit: s.

    Returns
    -------
    (sums, variances) : arrays (n_windows, n_pixels).
    """
    which = np.searchsorted(edges_s, block_t_s, side="right") - 1
    n_win = len(edges_s) - 1
    keep = (which >= 0) & (which < n_win)
    sums = np.zeros((n_win, values.shape[1]))
    variances = np.zeros_like(sums)
    np.add.at(sums, which[keep], values[keep] * frames_per_block)
    np.add.at(variances, which[keep], var[keep] * frames_per_block**2)
    frames = np.bincount(which[keep], minlength=n_win) * frames_per_block
    variances += frames[:, None] ** 2 * dark_var[None, :]
    return sums, variances


def required_signal_e(snr_power: float, var0_e2: float, var_per_signal_e: float = 1.0) -> float:
    """Signal that reaches a power SNR when the noise variance is ``var0 + k·S``.

    Solves S² = t·(var0 + k·S) for the positive root: S = (t·k + √(t²k² + 4·t·var0)) / 2.

    Parameters
    ----------
    snr_power : float
        Target power SNR t (eq. 22).
    var0_e2 : float
        Signal-independent noise variance (dark shot, read, reset, quantization). Unit: e⁻².
    var_per_signal_e : float
        Variance added per signal electron (1 for shot noise alone). Unit: e⁻.
    """
    t, k = snr_power, var_per_signal_e
    return (t * k + math.sqrt((t * k) ** 2 + 4.0 * t * var0_e2)) / 2.0

