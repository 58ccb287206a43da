"""The DSP stage the chip model calls: CMS → dark-reference subtraction → N-frame averaging.

Each frame carries the ADC's samples (``codes``, at the ``binned`` photon level) and, always, the
analytic mean and variance of its CMS difference (the ``expected`` level). The pipeline runs the
DSP level on the codes and propagates mean and variance beside it, so every result comes with its
noise. The dark reference's own noise is common to every output and kept apart
(:attr:`Pipeline.dark_var`): sums over outputs must add it coherently, not in quadrature.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from chiptwin.dsp import reference


@dataclass(frozen=True)
class Frame:
    """One frame from the ADCs.

    Attributes
    ----------
    codes : array (2M, n_pixels) of int64, or None
        M reset samples, then M signal samples. None at the ``expected`` photon level.
    mean, var : array (n_pixels,)
        Expected CMS difference and its variance. Unit: LSB, LSB².
    """

    codes: np.ndarray | None
    mean: np.ndarray
    var: np.ndarray


@dataclass(frozen=True)
class BlockOut:
    """One DSP output: the average of N dark-subtracted frames.

    Attributes
    ----------
    value : array (n_pixels,)
        What the DSP level computed (equals ``mean`` at the ``expected`` photon level). Unit: LSB.
    mean, var : array (n_pixels,)
        Its expectation and its variance excluding the dark reference's. Unit: LSB, LSB².
    """

    value: np.ndarray
    mean: np.ndarray
    var: np.ndarray


class Pipeline:
    """Background subtraction, correlated multiple sampling and N-frame averaging.

    Parameters
    ----------
    level : str
        ``"float"``: the float reference (:mod:`chiptwin.dsp.reference`).
    """

    LEVELS = ("float",)

    def __init__(self, level: str = "float") -> None:
        if level not in self.LEVELS:
            raise ValueError(f"DSP level {level!r} is not built; built: {self.LEVELS}")
        self.level = level
        self.dark_value: np.ndarray | None = None
        self.dark_mean: np.ndarray | None = None
        self.dark_var: np.ndarray | None = None

    def dark(self, frames: list[Frame]) -> None:
        """Average K dark frames into the dark reference."""
        k = len(frames)
        self.dark_mean = np.mean([f.mean for f in frames], axis=0)
        self.dark_var = np.sum([f.var for f in frames], axis=0) / k**2
        if frames[0].codes is None:
            self.dark_value = self.dark_mean
        else:
            self.dark_value = reference.average_frames(self._cms(frames), k)[0]

    def block(self, frames: list[Frame]) -> BlockOut:
        """Subtract the dark reference from N frames and average them."""
        if self.dark_value is None:
            raise RuntimeError("Pipeline.block called before the dark reference was taken")
        n = len(frames)
        mean = np.mean([f.mean for f in frames], axis=0) - self.dark_mean
        var = np.sum([f.var for f in frames], axis=0) / n**2
        if frames[0].codes is None:
            return BlockOut(value=mean, mean=mean, var=var)
        diff = reference.subtract_background(self._cms(frames), self.dark_value)
        return BlockOut(value=reference.average_frames(diff, n)[0], mean=mean, var=var)

    @staticmethod
    def _cms(frames: list[Frame]) -> np.ndarray:
        """CMS of each frame: ``(n_frames, n_pixels)``."""
        codes = np.stack([f.codes for f in frames])
        m = codes.shape[1] // 2
        return reference.correlated_multiple_sampling(codes[:, :m], codes[:, m:])
