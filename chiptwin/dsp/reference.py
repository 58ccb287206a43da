"""Float reference of the DSP routines: the level every bit-accurate routine is measured against.

Shapes: a frame is ``(n_pixels,)``; a stack of frames is ``(n_frames, n_pixels)``; the samples of
correlated multiple sampling are ``(M, n_pixels)`` per frame. Units are ADC codes (LSB) in and out.
"""

from __future__ import annotations

import numpy as np


def subtract_background(frames: np.ndarray, dark: np.ndarray) -> np.ndarray:
    """Dark/background frame subtraction.

    Parameters
    ----------
    frames : array (..., n_pixels)
        Frames of codes. Unit: LSB.
    dark : array (n_pixels,)
        The dark reference, usually the mean of K dark frames. Unit: LSB.

    Returns
    -------
    array (..., n_pixels) of float64, signed. Unit: LSB.
    """
    return np.asarray(frames, dtype=np.float64) - np.asarray(dark, dtype=np.float64)


def correlated_multiple_sampling(reset: np.ndarray, signal: np.ndarray) -> np.ndarray:
    """Correlated multiple sampling: mean of M signal samples minus mean of M reset samples.

    White read noise falls as 1/√M (correlated multiple sampling; sources.md P10); the kTC noise
    shared by reset and signal samples of one frame cancels (true CDS).

    Parameters
    ----------
    reset, signal : array (..., M, n_pixels)
        Samples taken right after reset and at the end of integration. Unit: LSB.

    Returns
    -------
    array (..., n_pixels) of float64. Unit: LSB.
    """
    return np.mean(np.asarray(signal, np.float64), axis=-2) - np.mean(
        np.asarray(reset, np.float64), axis=-2
    )


def average_frames(frames: np.ndarray, n: int) -> np.ndarray:
    """N-frame averaging: the mean of each run of ``n`` consecutive frames.

    Parameters
    ----------
    frames : array (n_frames, n_pixels)
        ``n_frames`` must be a multiple of ``n``. Unit: LSB.
    n : int
        Frames per average, ≥ 1.

    Returns
    -------
    array (n_frames // n, n_pixels) of float64. Unit: LSB.
    """
    frames = np.asarray(frames, dtype=np.float64)
    if n < 1 or frames.shape[0] % n:
        raise ValueError(f"average_frames: n={n} must be ≥ 1 and divide n_frames={frames.shape[0]}")
    return frames.reshape(frames.shape[0] // n, n, *frames.shape[1:]).mean(axis=1)


# ---------------------------------------------------------------------------------------------
# Float references of the routines added with the bit-accurate DSP. Same conventions:
# frames (n_frames, n_pixels), values in LSB, float64 out.
# ---------------------------------------------------------------------------------------------


def accumulate_frames(frames: np.ndarray, n: int) -> np.ndarray:
    """N-frame accumulation: the sum of each run of ``n`` consecutive frames.

    Parameters
    ----------
    frames : array (n_frames, n_pixels)
        ``n_frames`` must be a multiple of ``n``. Unit: LSB.
    n : int
        Frames per sum, ≥ 1.

    Returns
    -------
    array (n_frames // n, n_pixels) of float64. Unit: LSB.
    """
    frames = np.asarray(frames, dtype=np.float64)
    if n < 1 or frames.shape[0] % n:
        raise ValueError(f"accumulate_frames: n={n} must be ≥ 1 and divide {frames.shape[0]}")
    return frames.reshape(frames.shape[0] // n, n, *frames.shape[1:]).sum(axis=1)


def kinetics_weights(t_s: np.ndarray, k_per_s: float) -> np.ndarray:
    """Matched-filter weights ``w_j = exp(-k t_j)`` of an exponential light curve.

    Parameters
    ----------
    t_s : array (N,)
        Frame times relative to the start of the decay. Unit: s.
    k_per_s : float
        Decay rate: k_a ≈ 0.05 s⁻¹ for pyrosequencing (eq. 19), k_t = 0.1 s⁻¹ for the ATP glow
        assay (eq. 12). Unit: 1/s.

    Returns
    -------
    array (N,) of float64, in (0, 1] for ``t ≥ 0``.
    """
    return np.exp(-float(k_per_s) * np.asarray(t_s, dtype=np.float64))


def kinetics_weighted_amplitude(frames: np.ndarray, t_s: np.ndarray, k_per_s: float) -> np.ndarray:
    """Amplitude of an exponential decay by its matched filter (least squares).

    Model: frame ``j`` of a pixel is ``y_j = A·w_j + n_j`` with ``w_j = exp(-k t_j)`` and white
    noise of equal variance σ². The estimator ``Â = Σ w_j y_j / Σ w_j²`` is the least-squares (and,
    for Gaussian noise, maximum-likelihood) estimate of ``A``: unbiased, variance ``σ²/Σ w_j²``.
    Among all linear unbiased estimators it has the least variance, so it raises the power SNR by
    ``Σ w_j²`` over a single frame at ``t = 0``. ``A`` is the value a frame would have at ``t = 0``.
    Frames integrated over windows ``[t_j, t_j + T]`` follow the same model (the window integral is
    ``w_j · (1 - e^{-kT})/k``), so ``t_j`` are the window starts and ``A`` is a frame's value.

    Parameters
    ----------
    frames : array (..., N, n_pixels)
        Background-subtracted frames. Unit: LSB.
    t_s : array (N,)
        Frame times. Unit: s.
    k_per_s : float
        Decay rate. Unit: 1/s.

    Returns
    -------
    array (..., n_pixels) of float64. Unit: LSB.
    """
    w = kinetics_weights(t_s, k_per_s)
    y = np.asarray(frames, dtype=np.float64)
    return np.einsum("j,...jp->...p", w, y) / np.dot(w, w)


def bin_lines(frames: np.ndarray, rows: int, cols: int, factor: int) -> np.ndarray:
    """Line binning: the sum of ``factor`` adjacent rows, column by column.

    Parameters
    ----------
    frames : array (..., rows · cols)
        Pixels row-major (pixel ``p`` is row ``p // cols``, column ``p % cols``). Unit: LSB.
    rows, cols, factor : int
        Array geometry; ``factor`` divides ``rows``.

    Returns
    -------
    array (..., rows // factor · cols) of float64. Unit: LSB.
    """
    x = np.asarray(frames, dtype=np.float64)
    if rows % factor or x.shape[-1] != rows * cols:
        raise ValueError(f"bin_lines: {rows}×{cols} pixels, factor {factor}: shape {x.shape}")
    lead = x.shape[:-1]
    return x.reshape(*lead, rows // factor, factor, cols).sum(axis=-2).reshape(*lead, -1)


def fir_lowpass(taps: int, cutoff: float, window: str = "hamming") -> np.ndarray:
    """Low-pass FIR taps by the window method (``scipy.signal.firwin``), DC gain exactly 1.

    Parameters
    ----------
    taps : int
        Number of taps (8 on the chip).
    cutoff : float
        Cut-off as a fraction of the Nyquist frequency (0 < cutoff < 1); with frames at 1 Hz,
        0.25 means 0.125 Hz.
    window : str
        Window name understood by ``scipy.signal.get_window``.

    Returns
    -------
    array (taps,) of float64.
    """
    from scipy.signal import firwin

    return firwin(taps, cutoff, window=window)


def fir_filter(frames: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Causal FIR along the frame axis with zero initial state: ``y[t] = Σ_k h[k] x[t-k]``.

    Parameters
    ----------
    frames : array (n_frames, n_pixels)
        Unit: LSB.
    h : array (taps,)
        Filter taps.

    Returns
    -------
    array (n_frames, n_pixels) of float64. Unit: LSB.
    """
    from scipy.signal import lfilter

    return lfilter(np.asarray(h, np.float64), [1.0], np.asarray(frames, np.float64), axis=0)


def wiener_matrix(coupling: np.ndarray, noise_to_signal: float) -> np.ndarray:
    """Wiener (linear MMSE) equalizer of optical cross-talk (Salama et al. 2004, Sec. 3.3).

    Model: ``pixel = C @ site + noise`` with ``C`` the coupling matrix (n_pixels × n_sites), site
    signals uncorrelated with prior variance σ_s², pixel noise white with variance σ_n². The
    linear MMSE estimate is ``ŝ = G @ pixel`` with ``G = (Cᵀ C + λ I)⁻¹ Cᵀ``, ``λ = σ_n² / σ_s²``.
    ``λ → 0`` gives the least-squares (zero-forcing) inverse.

    Parameters
    ----------
    coupling : array (n_pixels, n_sites)
        Fraction of a site's signal that reaches each pixel (optics stage).
    noise_to_signal : float
        λ = σ_n² / σ_s², ≥ 0 (both in LSB²).

    Returns
    -------
    array (n_sites, n_pixels) of float64.
    """
    c = np.asarray(coupling, dtype=np.float64)
    if c.ndim != 2 or noise_to_signal < 0:
        raise ValueError(f"wiener_matrix: coupling {c.shape} must be 2-D, λ={noise_to_signal} ≥ 0")
    gram = c.T @ c + float(noise_to_signal) * np.eye(c.shape[1])
    return np.linalg.solve(gram, c.T)


def wiener_equalize(frames: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Apply the equalizer: ``ŝ = G @ pixel`` for each frame.

    Parameters
    ----------
    frames : array (..., n_pixels)
        Background-subtracted frames. Unit: LSB.
    g : array (n_sites, n_pixels)
        From :func:`wiener_matrix`.

    Returns
    -------
    array (..., n_sites) of float64: site signals in pixel LSB (pixel = C @ site).
    """
    return np.asarray(frames, dtype=np.float64) @ np.asarray(g, dtype=np.float64).T
