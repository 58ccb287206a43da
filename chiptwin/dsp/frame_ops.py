"""Bit-accurate frame operations: background subtraction, CMS, N-frame averaging, line binning.

Shapes: a frame is ``(n_pixels,)``; a stack of frames is ``(n_frames, n_pixels)``; CMS samples are
``(..., M, n_pixels)``. Inputs are int64 codes of the config's ``in_fmt``; results are
:class:`~chiptwin.dsp.registers.FixedResult`. Each config lists its registers, in data-path order,
with :meth:`registers`; the float references with the same argument conventions are in
:mod:`chiptwin.dsp.reference`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from chiptwin.dsp import _kernels as K
from chiptwin.dsp.fixed import (
    Fmt,
    _accumulate_into,
    _lincomb,
    _requantize,
    add_fmt,
    as_codes,
    sum_fmt,
)
from chiptwin.dsp.registers import (
    FixedResult,
    OverflowLog,
    check_modes,
    check_positive,
    divide,
    divide_registers,
    errors_named,
)

ADC_FMT = Fmt(False, 13, 0)
"""Codes of the reference chip's 13-bit ADC (JSSC 2006), unsigned integers."""

WORD_FMT = Fmt(True, 16, 2)
"""A signed 16-bit memory word (``[chip.memory] word_bits = 16``), 2 fractional bits (choice)."""


def _set(obj: object, name: str, value: object) -> None:
    object.__setattr__(obj, name, value)


# ---------------------------------------------------------------------------------------------
# background subtraction
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class BackgroundConfig:
    """Dark / background frame subtraction ``out = frame - dark``.

    Registers: ``input`` (ADC codes, ``in_fmt``) · ``dark`` (reference, ``dark_fmt``: the mean of K
    dark frames keeps ``log2 K`` fractional bits) · ``diff`` (full precision, signed,
    ``max(I) + 1`` integer bits, ``max(F)`` fractional bits) · ``output`` (``out_fmt``, one rounding
    ``rounding`` then ``overflow``).
    """

    in_fmt: Fmt = ADC_FMT
    dark_fmt: Fmt = Fmt(False, 17, 4)
    out_fmt: Fmt = WORD_FMT
    rounding: str = "RND_CONV"
    overflow: str = "SAT"

    def __post_init__(self) -> None:
        check_modes("BackgroundConfig", rounding=self.rounding, overflow=self.overflow)
        with errors_named("BackgroundConfig"):
            self.registers()  # refuses a diff wider than 64 bits

    def registers(self) -> dict[str, Fmt]:
        """Register formats in data-path order."""
        diff = add_fmt(self.in_fmt, self.dark_fmt, subtract=True)
        return {"input": self.in_fmt, "dark": self.dark_fmt, "diff": diff, "output": self.out_fmt}

    def dark_config(self, n_dark: int, recip_word_bits: int = 18) -> AverageConfig:
        """The averaging that builds the dark reference from ``n_dark`` dark frames."""
        return AverageConfig(
            n=n_dark,
            in_fmt=self.in_fmt,
            out_fmt=self.dark_fmt,
            recip_word_bits=recip_word_bits,
            rounding=self.rounding,
            overflow="SAT",
        )


def subtract_background_fixed(
    frames: np.ndarray, dark: np.ndarray, cfg: BackgroundConfig
) -> FixedResult:
    """Bit-accurate dark / background frame subtraction.

    Parameters
    ----------
    frames : int array (..., n_pixels)
        Codes of ``cfg.in_fmt`` (ADC codes). Unit: LSB.
    dark : int array (n_pixels,)
        Dark reference codes of ``cfg.dark_fmt`` (e.g. from :func:`average_frames_fixed`).
    cfg : BackgroundConfig

    Returns
    -------
    FixedResult
        ``codes`` (..., n_pixels) in ``cfg.out_fmt``; registers ``diff``, ``output``.
    """
    frames = as_codes(frames, cfg.in_fmt, "subtract_background: frames")
    dark = as_codes(dark, cfg.dark_fmt, "subtract_background: dark")
    if dark.shape != frames.shape[-1:]:
        raise ValueError(
            f"subtract_background: dark shape {dark.shape} must be (n_pixels,) = "
            f"{frames.shape[-1:]}"
        )
    log = OverflowLog("diff", "output")
    diff, diff_fmt = _lincomb(frames, cfg.in_fmt, dark, cfg.dark_fmt, -1)
    out = _requantize(diff, diff_fmt, cfg.out_fmt, cfg.rounding, cfg.overflow, log["output"])
    return FixedResult(out, cfg.out_fmt, log.as_dict())


# ---------------------------------------------------------------------------------------------
# N-frame accumulation and averaging
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class AverageConfig:
    """N-frame accumulation into a W-bit accumulator, then division by N.

    Registers: ``input`` (``in_fmt``) · ``acc`` (``acc_fmt``, reset to 0 for each run of ``n``
    frames, frames added in order, each partial sum through ``acc_overflow``; default: full
    precision ``W + ⌈log2 n⌉``) · then the divide step: ``scaled`` (n a power of two: the acc
    codes read with ``log2 n`` more fractional bits, a free shift) or ``recip`` (``1/n`` rounded
    to nearest even in ``UQ(-⌊log2 n⌋).(recip_word_bits + ⌊log2 n⌋)``) and ``product`` (acc ×
    recip, full precision) · ``output`` (``out_fmt``, default ``in_fmt``; one rounding).
    """

    n: int = 4
    in_fmt: Fmt = WORD_FMT
    acc_fmt: Fmt | None = None
    out_fmt: Fmt | None = None
    recip_word_bits: int = 18
    rounding: str = "RND_CONV"
    overflow: str = "SAT"
    acc_overflow: str = "WRAP"

    def __post_init__(self) -> None:
        check_positive("AverageConfig", n=self.n, recip_word_bits=self.recip_word_bits)
        check_modes(
            "AverageConfig",
            rounding=self.rounding,
            overflow=self.overflow,
            acc_overflow=self.acc_overflow,
        )
        if self.acc_fmt is None:
            with errors_named("AverageConfig"):
                _set(self, "acc_fmt", sum_fmt(self.in_fmt, self.n))
        if self.out_fmt is None:
            _set(self, "out_fmt", self.in_fmt)
        if self.acc_fmt.frac_bits != self.in_fmt.frac_bits:
            raise ValueError(
                f"AverageConfig.acc_fmt = {self.acc_fmt}: must keep the input's "
                f"{self.in_fmt.frac_bits} fractional bits"
            )
        with errors_named("AverageConfig"):
            self.registers()  # refuses a product wider than 64 bits

    def registers(self) -> dict[str, Fmt]:
        """Register formats in data-path order."""
        regs = {"input": self.in_fmt, "acc": self.acc_fmt}
        regs.update(divide_registers(self.acc_fmt, self.n, self.recip_word_bits))
        regs["output"] = self.out_fmt
        return regs


def _runs(frames: np.ndarray, n: int, what: str) -> np.ndarray:
    """``(n_frames, ...)`` → ``(n_frames // n, n, n_rest)``, refusing a ragged last run."""
    if frames.ndim < 1 or frames.shape[0] % n or frames.shape[0] == 0:
        raise ValueError(
            f"{what}: n_frames = {frames.shape[:1]} must be a positive multiple of {n}"
        )
    return frames.reshape(frames.shape[0] // n, n, -1)


def _accumulate(frames: np.ndarray, cfg: AverageConfig, log: OverflowLog) -> np.ndarray:
    frames = as_codes(frames, cfg.in_fmt, "frames")
    runs = _runs(frames, cfg.n, "average_frames")
    acc = _accumulate_into(runs, cfg.in_fmt, cfg.acc_fmt, cfg.acc_overflow, log["acc"], 1)
    return acc.reshape((runs.shape[0],) + frames.shape[1:])


def accumulate_frames_fixed(frames: np.ndarray, cfg: AverageConfig) -> FixedResult:
    """Sum of each run of ``cfg.n`` consecutive frames in the accumulator register.

    Parameters
    ----------
    frames : int array (n_frames, n_pixels)
        Codes of ``cfg.in_fmt``; ``n_frames`` a multiple of ``cfg.n``.

    Returns
    -------
    FixedResult
        ``codes`` (n_frames // n, n_pixels) in ``cfg.acc_fmt``; register ``acc``.
    """
    log = OverflowLog("acc")
    acc = _accumulate(frames, cfg, log)
    return FixedResult(acc, cfg.acc_fmt, log.as_dict())


def average_frames_fixed(frames: np.ndarray, cfg: AverageConfig) -> FixedResult:
    """Mean of each run of ``cfg.n`` consecutive frames: accumulate, divide, one rounding.

    Parameters
    ----------
    frames : int array (n_frames, n_pixels)
        Codes of ``cfg.in_fmt``; ``n_frames`` a multiple of ``cfg.n``.

    Returns
    -------
    FixedResult
        ``codes`` (n_frames // n, n_pixels) in ``cfg.out_fmt``; registers ``acc``, ``output``.
    """
    log = OverflowLog("acc", "output")
    acc = _accumulate(frames, cfg, log)
    out = divide(
        acc,
        cfg.acc_fmt,
        cfg.n,
        cfg.recip_word_bits,
        cfg.out_fmt,
        cfg.rounding,
        cfg.overflow,
        log["output"],
    )
    return FixedResult(out, cfg.out_fmt, log.as_dict())


# ---------------------------------------------------------------------------------------------
# correlated multiple sampling
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class CmsConfig:
    """Correlated multiple sampling: ``(Σ signal - Σ reset) / M`` over M samples each.

    Registers: ``input`` (``in_fmt``) · ``sum_reset`` and ``sum_signal`` (``acc_fmt``, the M samples
    added in order, each partial sum through ``acc_overflow``; default full precision
    ``W + ⌈log2 M⌉``) · ``diff`` (``sum_signal - sum_reset``, full precision, signed) · divide step
    (``scaled`` or ``recip`` + ``product``, as in :class:`AverageConfig`) · ``output``.
    """

    m: int = 4
    in_fmt: Fmt = ADC_FMT
    acc_fmt: Fmt | None = None
    out_fmt: Fmt = WORD_FMT
    recip_word_bits: int = 18
    rounding: str = "RND_CONV"
    overflow: str = "SAT"
    acc_overflow: str = "WRAP"

    def __post_init__(self) -> None:
        check_positive("CmsConfig", m=self.m, recip_word_bits=self.recip_word_bits)
        check_modes(
            "CmsConfig",
            rounding=self.rounding,
            overflow=self.overflow,
            acc_overflow=self.acc_overflow,
        )
        if self.acc_fmt is None:
            with errors_named("CmsConfig"):
                _set(self, "acc_fmt", sum_fmt(self.in_fmt, self.m))
        if self.acc_fmt.frac_bits != self.in_fmt.frac_bits:
            raise ValueError(
                f"CmsConfig.acc_fmt = {self.acc_fmt}: must keep the input's "
                f"{self.in_fmt.frac_bits} fractional bits"
            )
        with errors_named("CmsConfig"):
            self.registers()

    @property
    def diff_fmt(self) -> Fmt:
        """Full-precision format of ``sum_signal - sum_reset``."""
        return add_fmt(self.acc_fmt, self.acc_fmt, subtract=True)

    def registers(self) -> dict[str, Fmt]:
        """Register formats in data-path order."""
        regs = {
            "input": self.in_fmt,
            "sum_reset": self.acc_fmt,
            "sum_signal": self.acc_fmt,
            "diff": self.diff_fmt,
        }
        regs.update(divide_registers(self.diff_fmt, self.m, self.recip_word_bits))
        regs["output"] = self.out_fmt
        return regs


def cms_fixed(reset: np.ndarray, signal: np.ndarray, cfg: CmsConfig) -> FixedResult:
    """Bit-accurate correlated multiple sampling.

    Parameters
    ----------
    reset, signal : int array (..., M, n_pixels)
        Samples right after reset and at the end of integration, codes of ``cfg.in_fmt``.

    Returns
    -------
    FixedResult
        ``codes`` (..., n_pixels) in ``cfg.out_fmt``; registers ``sum_reset``, ``sum_signal``,
        ``diff``, ``output``.
    """
    reset = as_codes(reset, cfg.in_fmt, "cms: reset")
    signal = as_codes(signal, cfg.in_fmt, "cms: signal")
    if reset.shape != signal.shape or reset.ndim < 2 or reset.shape[-2] != cfg.m:
        raise ValueError(
            f"cms: reset {reset.shape} and signal {signal.shape} must both be (..., M={cfg.m}, "
            "n_pixels)"
        )
    log = OverflowLog("sum_reset", "sum_signal", "diff", "output")
    acc = {
        name: _accumulate_into(x, cfg.in_fmt, cfg.acc_fmt, cfg.acc_overflow, log[name], -2)
        for name, x in (("sum_reset", reset), ("sum_signal", signal))
    }
    diff, diff_fmt = _lincomb(acc["sum_signal"], cfg.acc_fmt, acc["sum_reset"], cfg.acc_fmt, -1)
    out = divide(
        diff,
        diff_fmt,
        cfg.m,
        cfg.recip_word_bits,
        cfg.out_fmt,
        cfg.rounding,
        cfg.overflow,
        log["output"],
    )
    return FixedResult(out, cfg.out_fmt, log.as_dict())


# ---------------------------------------------------------------------------------------------
# line binning
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class BinningConfig:
    """Line binning: the sum of ``factor`` adjacent rows (lines), column by column.

    Pixel ``p`` of a frame is row ``p // cols``, column ``p % cols`` (row-major). Registers:
    ``input`` · ``sum`` (full precision, ``+⌈log2 factor⌉`` integer bits) · ``output``
    (``out_fmt``, default = ``sum``, i.e. exact).
    """

    rows: int = 8
    cols: int = 16
    factor: int = 2
    in_fmt: Fmt = WORD_FMT
    out_fmt: Fmt | None = None
    rounding: str = "RND_CONV"
    overflow: str = "SAT"

    def __post_init__(self) -> None:
        check_positive("BinningConfig", rows=self.rows, cols=self.cols, factor=self.factor)
        check_modes("BinningConfig", rounding=self.rounding, overflow=self.overflow)
        if self.rows % self.factor:
            raise ValueError(
                f"BinningConfig.factor = {self.factor}: must divide rows = {self.rows}"
            )
        with errors_named("BinningConfig"):
            if self.out_fmt is None:
                _set(self, "out_fmt", sum_fmt(self.in_fmt, self.factor))
            self.registers()

    def registers(self) -> dict[str, Fmt]:
        """Register formats in data-path order."""
        return {
            "input": self.in_fmt,
            "sum": sum_fmt(self.in_fmt, self.factor),
            "output": self.out_fmt,
        }


def bin_lines_fixed(frames: np.ndarray, cfg: BinningConfig) -> FixedResult:
    """Bit-accurate line binning.

    Parameters
    ----------
    frames : int array (..., rows · cols)
        Codes of ``cfg.in_fmt``, pixels row-major.

    Returns
    -------
    FixedResult
        ``codes`` (..., rows // factor · cols) in ``cfg.out_fmt``; registers ``sum``, ``output``.
    """
    frames = as_codes(frames, cfg.in_fmt, "bin_lines: frames")
    if frames.shape[-1:] != (cfg.rows * cfg.cols,):
        raise ValueError(
            f"bin_lines: frames {frames.shape} must end in rows·cols = {cfg.rows * cfg.cols}"
        )
    lead = frames.shape[:-1]
    grid = frames.reshape(-1, cfg.rows, cfg.cols)
    sums = K.bin_rows_kernel(grid, cfg.factor).reshape(*lead, -1)  # exact: sum_fmt ≤ 64 bits
    log = OverflowLog("sum", "output")
    sum_f = sum_fmt(cfg.in_fmt, cfg.factor)
    out = _requantize(sums, sum_f, cfg.out_fmt, cfg.rounding, cfg.overflow, log["output"])
    return FixedResult(out, cfg.out_fmt, log.as_dict())
