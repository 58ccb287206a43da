"""Detection: from DSP outputs to per-site signal, noise, SNR, decisions and base calls.

SNR follows the paper: SNR = Q²/σ² (Salama et al. 2004, eq. 22) is a POWER ratio; its square root,
the amplitude ratio, is reported beside it and always labelled (Salama et al. 2004, eq. 22).
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
    (snr_power, snr_amplitude) : power ratio Q²/σ² (eq. 22) and amplitude ratio Q/σ. Without
        noise, a signal is infinitely far above it (±inf amplitude), and no signal is not above
        it at all (0: nothing to detect, not an infinite SNR).
    """
    signal_e, noise_e = np.asarray(signal_e, float), np.asarray(noise_e, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        noiseless = np.where(signal_e == 0, 0.0, np.copysign(np.inf, signal_e))
        amplitude = np.where(noise_e > 0, signal_e / noise_e, noiseless)
    return amplitude**2, amplitude


def window_sums(
    block_t_s: np.ndarray,
    values: np.ndarray,
    var: np.ndarray,
    dark_var: np.ndarray,
    frames_per_block: int,
    edges_s: np.ndarray,
    decay_per_s: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The light of each time window from the DSP outputs in it, with its variance.

    Each output is the average of N = ``frames_per_block`` dark-subtracted frames. The window's
    total is estimated as ``N · c · Σ_j w_j y_j``:

    * plain sum (``decay_per_s`` None): ``w_j = 1``, ``c = 1``;
    * matched filter for light decaying as exp(−k t) from the window's start (pyrosequencing,
      eq. 19): ``w_j = exp(−k (t_j − t_0))``, ``c = Σw / Σw²``. It is the least-squares amplitude
      ``Σ w y / Σ w²`` scaled back to a window total, unbiased for that decay, and weights the
      bright outputs where the sum weights the dim tail equally (Salama et al. 2004, eq. 19: 61 % of
      a flow's light comes after its first 10 s).

    Independent variances add with weights ``(N c w_j)²``; the dark reference is common to every
    output, so its variance adds coherently, ``(N c Σ w_j)²``.

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
    decay_per_s : float, optional
        k of the matched filter. Unit: 1/s.

    Returns
    -------
    (sums, variances) : arrays (n_windows, n_pixels).
    """
    which = np.searchsorted(edges_s, block_t_s, side="right") - 1
    n_win = len(edges_s) - 1
    keep = (which >= 0) & (which < n_win)
    which, t = which[keep], block_t_s[keep]
    w = np.ones_like(t) if decay_per_s is None else np.exp(-decay_per_s * (t - edges_s[which]))
    sum_w = np.bincount(which, weights=w, minlength=n_win)
    sum_w2 = np.bincount(which, weights=w**2, minlength=n_win)
    c = np.ones(n_win) if decay_per_s is None else np.divide(
        sum_w, sum_w2, out=np.zeros(n_win), where=sum_w2 > 0)
    scale = frames_per_block * c[which] * w  # each output's weight in its window's total
    sums = np.zeros((n_win, values.shape[1]))
    variances = np.zeros_like(sums)
    np.add.at(sums, which, values[keep] * scale[:, None])
    np.add.at(variances, which, var[keep] * scale[:, None] ** 2)
    variances += (frames_per_block * c * sum_w)[:, None] ** 2 * dark_var[None, :]
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

