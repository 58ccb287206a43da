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

    White read noise falls as 1/√M (REFERENCE §4); the kTC noise shared by reset and signal samples
    of one frame cancels (true CDS).

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
