"""The DSP stage the chip model calls: CMS → dark reference → background subtraction → averaging.

Each frame carries the ADC's samples (``codes``, at the ``binned`` photon level) and, always, the
analytic mean and variance of its CMS difference (the ``expected`` level). The pipeline runs the
DSP level on the codes and propagates mean and variance beside it, so every result comes with its
noise. The dark reference's own noise is common to every output and kept apart
(:attr:`Pipeline.dark_var`): sums over outputs must add it coherently, not in quadrature.

The chip model hands the DSP one job at a time (:meth:`Pipeline.block`, a list of
:class:`Frame`); when its run is known ahead (:mod:`chiptwin.chip.steady`) it hands many jobs at
once (:meth:`Pipeline.blocks`, a :class:`FrameStack`). Both are one computation: ``block`` is
``blocks`` of a single job, and a batch gives every job the bits it gets alone.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from chiptwin.dsp import reference
from chiptwin.dsp._kernels import cms_float_kernel
from chiptwin.dsp.chain import ChainConfig, chain_configs, with_accumulator
from chiptwin.dsp.frame_ops import average_frames_fixed, cms_fixed, subtract_background_fixed
from chiptwin.dsp.registers import FixedResult

#: A ``[chip]`` section (:class:`chiptwin.config.schema.Chip`). The stage
#: packages sit below the scenario files (``docs/architecture.md``): they read its fields by
#: name and import nothing from ``config``.
Chip = Any


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
class FrameStack:
    """Consecutive frames from the ADCs, one row each: :class:`Frame`'s fields stacked.

    Attributes
    ----------
    codes : array (n_frames, 2M, n_pixels) of int, or None
        Each frame's M reset samples, then its M signal samples. None at the ``expected`` level.
    mean, var : array (n_frames, n_pixels)
        Each frame's expected CMS difference and its variance. Unit: LSB, LSB².
    """

    codes: np.ndarray | None
    mean: np.ndarray
    var: np.ndarray

    @classmethod
    def of(cls, frames: Sequence[Frame]) -> FrameStack:
        """The frames of a list, stacked."""
        codes = None if frames[0].codes is None else np.stack([f.codes for f in frames])
        return cls(codes, np.stack([f.mean for f in frames]), np.stack([f.var for f in frames]))

    @classmethod
    def join(cls, parts: Sequence[FrameStack]) -> FrameStack:
        """Stacks one after the other, as one (a copy)."""
        codes = None if parts[0].codes is None else np.concatenate([p.codes for p in parts])
        return cls(codes, np.concatenate([p.mean for p in parts]),
                   np.concatenate([p.var for p in parts]))

    def __len__(self) -> int:
        return len(self.mean)

    def __getitem__(self, frames: slice) -> FrameStack:
        return FrameStack(None if self.codes is None else self.codes[frames], self.mean[frames],
                          self.var[frames])


@dataclass(frozen=True)
class BlockOut:
    """One DSP output: the average of N dark-subtracted frames (from :meth:`Pipeline.blocks`:
    one row per output, arrays ``(n_outputs, n_pixels)``).

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


def chain_for(chip: Chip) -> ChainConfig:
    """The fixed-point chain of a scenario's chip: formats from the ADC bits and M, K, N.

    ``[chip.dsp] acc_bits`` (if not 0) narrows the N-frame accumulator, with ``acc_overflow``.
    Raises :class:`~chiptwin.dsp.chain.FormatLimit` naming the count whose registers would pass
    64 bits.
    """
    d = chip.dsp
    chain = chain_configs(chip.adc.bits, d.cms_samples, d.n_dark_frames, d.average_frames,
                          rounding=d.rounding, overflow=d.overflow)
    if not d.acc_bits:
        return chain
    return with_accumulator(chain, d.acc_bits, d.acc_overflow)


@dataclass
class ErrorStats:
    """Running fixed-vs-float error of the pipeline's outputs, in output LSB."""

    lsb: float
    n: int = 0
    max_abs_lsb: float = 0.0
    sum_lsb: float = 0.0
    sum_sq_err: float = 0.0
    sum_sq_ref: float = 0.0

    def add(self, fixed: np.ndarray, ref: np.ndarray) -> None:
        err = (fixed - ref) / self.lsb
        self.n += err.size
        self.max_abs_lsb = max(self.max_abs_lsb, float(np.max(np.abs(err), initial=0.0)))
        self.sum_lsb += float(err.sum())
        self.sum_sq_err += float(np.sum((fixed - ref) ** 2))
        self.sum_sq_ref += float(np.sum(ref**2))

    def add_each(self, fixed: np.ndarray, ref: np.ndarray) -> None:
        """:meth:`add` of each row of ``(n_outputs, n_pixels)`` arrays in turn: the same sums,
        in the same order, as one call per output."""
        diff = fixed - ref
        err = diff / self.lsb
        peaks = np.max(np.abs(err), axis=1, initial=0.0)
        sums, sq_err, sq_ref = err.sum(axis=1), np.sum(diff**2, axis=1), np.sum(ref**2, axis=1)
        for j in range(len(err)):
            self.n += err.shape[1]
            self.max_abs_lsb = max(self.max_abs_lsb, float(peaks[j]))
            self.sum_lsb += float(sums[j])
            self.sum_sq_err += float(sq_err[j])
            self.sum_sq_ref += float(sq_ref[j])

    def summary(self) -> dict[str, float | int | None]:
        """``max_abs_err_lsb``, ``bias_lsb``, ``sqnr_db`` (None when the outputs are exact)."""
        sqnr = (10 * np.log10(self.sum_sq_ref / self.sum_sq_err) if self.sum_sq_err > 0
                and self.sum_sq_ref > 0 else None)
        return {"outputs": self.n, "max_abs_err_lsb": self.max_abs_lsb,
                "bias_lsb": self.sum_lsb / max(self.n, 1),
                "sqnr_db": None if sqnr is None else float(sqnr)}


class Pipeline:
    """CMS → dark reference → background subtraction → N-frame averaging, at one DSP level.

    Parameters
    ----------
    level : str
        ``"float"``: the float reference (:mod:`chiptwin.dsp.reference`). ``"fixed"``: the
        bit-accurate chain (:mod:`chiptwin.dsp.chain`), overflow counted per register.
    chain : ChainConfig, optional
        Register formats; required for ``"fixed"``.
    report_error : bool
        With ``"fixed"``, run the float reference beside it and keep :class:`ErrorStats`.
    """

    LEVELS = ("float", "fixed")

    def __init__(self, level: str = "float", chain: ChainConfig | None = None,
                 report_error: bool = False, keep_codes: bool = False) -> None:
        if level not in self.LEVELS:
            raise ValueError(f"DSP level {level!r} is not built; built: {self.LEVELS}")
        if level == "fixed" and chain is None:
            raise ValueError("the fixed DSP level needs its register formats (chain)")
        self.level, self.chain = level, chain
        self.dark_mean: np.ndarray | None = None
        self.dark_var: np.ndarray | None = None
        self.overflow: dict[str, dict[str, int]] = {}
        self.error = ErrorStats(chain.average.out_fmt.lsb) if report_error and chain else None
        self._dark_float: np.ndarray | None = None
        self._dark_codes: np.ndarray | None = None
        #: With ``keep_codes``: every frame's ADC samples as read, ``(2M, n_pixels)`` each.
        self.kept: list[np.ndarray] | None = [] if keep_codes else None

    def dark(self, frames: list[Frame]) -> None:
        """Average K dark frames into the dark reference."""
        self.dark_stack(FrameStack.of(frames))

    def dark_stack(self, frames: FrameStack) -> None:
        """:meth:`dark` of stacked frames."""
        self._keep(frames)
        k = len(frames)
        self.dark_mean = np.mean(frames.mean, axis=0)
        self.dark_var = np.sum(frames.var, axis=0) / k**2
        if frames.codes is None:
            self._dark_float = self.dark_mean
            return
        if self.level == "float" or self.error is not None:
            self._dark_float = reference.average_frames(self._cms_float(frames), k)[0]
        if self.level == "fixed":
            cms = self._fixed("cms", cms_fixed(*self._split(frames), self.chain.cms))
            self._dark_codes = self._fixed("dark", average_frames_fixed(cms, self.chain.dark))[0]

    def block(self, frames: list[Frame]) -> BlockOut:
        """Subtract the dark reference from N frames and average them."""
        out = self.blocks(FrameStack.of(frames), len(frames))
        return BlockOut(value=out.value[0], mean=out.mean[0], var=out.var[0])

    def blocks(self, frames: FrameStack, n: int) -> BlockOut:
        """:meth:`block` of each run of ``n`` consecutive frames, at once: one output per row.

        Each output has the bits one call of :meth:`block` on its frames gives; the overflow
        counts are the sums of theirs, :attr:`error` adds the outputs one by one.
        """
        if self.dark_mean is None:
            raise RuntimeError("Pipeline.block called before the dark reference was taken")
        if n < 1 or len(frames) % n:
            raise ValueError(f"Pipeline.blocks: {len(frames)} frames are not runs of {n}")
        self._keep(frames)
        mean = _runs(frames.mean, n).mean(axis=1)
        mean -= self.dark_mean  # in place: the same numbers, one temporary less
        var = _runs(frames.var, n).sum(axis=1)
        var /= n**2
        if frames.codes is None:
            return BlockOut(value=mean, mean=mean, var=var)
        ref = None
        if self.level == "float" or self.error is not None:
            ref = reference.average_frames(self._cms_float(frames, self._dark_float), n)
        if self.level == "float":
            return BlockOut(value=ref, mean=mean, var=var)
        c = self.chain
        cms = self._fixed("cms", cms_fixed(*self._split(frames), c.cms))
        diff = self._fixed("background", subtract_background_fixed(cms, self._dark_codes,
                                                                    c.background))
        value = c.average.out_fmt.to_float(
            self._fixed("average", average_frames_fixed(diff, c.average)))
        if self.error is not None:
            self.error.add_each(value, ref)
        return BlockOut(value=value, mean=mean, var=var)

    def _fixed(self, step: str, result: FixedResult) -> np.ndarray:
        """Book a routine's overflow counts under ``step.register``; return its codes."""
        for reg, counts in result.overflow.items():
            book = self.overflow.setdefault(f"{step}.{reg}", {"sat": 0, "wrap": 0})
            for kind, n in counts.items():
                book[kind] += n
        return result.codes

    @staticmethod
    def _split(frames: FrameStack) -> tuple[np.ndarray, np.ndarray]:
        """Reset and signal samples: two ``(n_frames, M, n_pixels)`` arrays."""
        m = frames.codes.shape[1] // 2
        return frames.codes[:, :m], frames.codes[:, m:]

    @classmethod
    def _cms_float(cls, frames: FrameStack, dark: np.ndarray | None = None) -> np.ndarray:
        """CMS of each frame, ``(n_frames, n_pixels)``, minus ``dark`` if given: the float
        reference's numbers (:func:`~chiptwin.dsp.reference.correlated_multiple_sampling`,
        then :func:`~chiptwin.dsp.reference.subtract_background`).

        ADC codes are integers: while ``M · max|code| < 2^53`` their float64 sums are exact in
        any order, so the reference's means are the integer sums over M, summed by
        :func:`~chiptwin.dsp._kernels.cms_float_kernel` in one pass; other codes take the
        reference itself.
        """
        codes = frames.codes
        m = codes.shape[1] // 2
        # int64, or the ADC's narrow unsigned codes (chiptwin.pixel.frames.code_dtype)
        exact_sum = codes.dtype in (np.int64, np.uint16, np.uint32)
        if exact_sum and codes.size and codes.flags.c_contiguous:
            zero = np.zeros(codes.shape[2]) if dark is None else np.asarray(dark, np.float64)
            out, lo, hi = cms_float_kernel(codes, m, zero)
            if m * max(-int(lo), int(hi)) < 2**53:
                return out
        cms = reference.correlated_multiple_sampling(*cls._split(frames))
        return cms if dark is None else reference.subtract_background(cms, dark)

    def _keep(self, frames: FrameStack) -> None:
        if self.kept is not None and frames.codes is not None:
            self.kept.extend(frames.codes)


def _runs(x: np.ndarray, n: int) -> np.ndarray:
    """``(n_frames, ...)`` as ``(n_frames // n, n, ...)`` in C order: each job's frames (the
    layout of one job's stacked frames, so NumPy reduces each job's the same way)."""
    return np.ascontiguousarray(x).reshape(len(x) // n, n, *x.shape[1:])
