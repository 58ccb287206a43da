"""Bit-accurate filters: kinetics-weighted accumulation, 8-tap low-pass FIR, Wiener equalizer.

Coefficients are designed in float64 (:mod:`chiptwin.dsp.reference`) and quantized once, rounding
to nearest even with saturation, as a ROM would be filled; their saturations are reported under
the coefficient register. Products are full precision (``W_in + W_coef ≤ 64`` is checked) and
accumulate in a declared accumulator register; one rounding happens, at the output register.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from fractions import Fraction

import numpy as np

from chiptwin.dsp import _kernels as K
from chiptwin.dsp import reference
from chiptwin.dsp.fixed import (
    Fmt,
    OverflowCounter,
    _mul,
    _requantize,
    as_codes,
    fmt_for_range,
    mul_fmt,
    needs_checks,
    overflow_code,
    quantize,
    quantize_fraction,
    sum_fmt,
)
from chiptwin.dsp.frame_ops import WORD_FMT
from chiptwin.dsp.registers import (
    FixedResult,
    OverflowLog,
    check_modes,
    check_positive,
    errors_named,
    fmt_holding,
)

Q1_15 = Fmt(True, 16, 15)
"""Signed Q1.15 coefficients: [-1, 1 - 2^-15]."""


def _set(obj: object, name: str, value: object) -> None:
    object.__setattr__(obj, name, value)


def _check_acc(acc: Fmt, product: Fmt) -> None:
    if acc.frac_bits != product.frac_bits:
        raise ValueError(
            f"acc_fmt = {acc}: must keep the product's {product.frac_bits} fractional bits"
        )


def _mac_output(acc, acc_fmt, scale, scale_fmt, cfg, log: OverflowLog) -> np.ndarray:
    """Optional full-precision scale by a coefficient, then the one rounding at ``output``."""
    if scale is None:
        return _requantize(acc, acc_fmt, cfg.out_fmt, cfg.rounding, cfg.overflow, log["output"])
    scaled, scaled_fmt = _mul(acc, acc_fmt, np.array([scale], dtype=np.int64), scale_fmt)
    return _requantize(scaled, scaled_fmt, cfg.out_fmt, cfg.rounding, cfg.overflow, log["output"])


# ---------------------------------------------------------------------------------------------
# kinetics-weighted accumulation
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class KineticsConfig:
    """Matched filter for an exponential light curve: ``Â = g · Σ_j w_j y_j``, ``g = 1/Σ w_j²``.

    See :func:`chiptwin.dsp.reference.kinetics_weighted_amplitude` for the estimator. Registers:
    ``input`` (frames, ``in_fmt``) · ``weights`` (``w_j = exp(-k t_j)`` in ``coef_fmt``, RND_CONV,
    SAT) · ``product`` (``y_j · w_j``, full precision) · ``acc`` (``acc_fmt``, frames added in order
    ``j = 0, 1, …``; default full precision) · ``norm`` (``g`` from the *quantized* weights, exact
    rational rounded to nearest even, unsigned ``norm_word_bits`` bits, as many fractional bits as
    fit) · ``scaled`` (``acc · g``, full precision) · ``output`` (``out_fmt``; default: the input's
    fractional bits and enough integer bits for ``max|y| · g · Σ w``).

    Parameters
    ----------
    t_s : tuple of float
        Frame times (window starts) relative to the start of the decay. Unit: s. Default 16
        frames at the 1 s frame period.
    k_per_s : float
        Decay rate. Unit: 1/s. Default k_a = 0.05 s⁻¹ (pyrosequencing, paper eq. 19).
    """

    t_s: tuple[float, ...] = tuple(float(i) for i in range(16))
    k_per_s: float = 0.05
    in_fmt: Fmt = WORD_FMT
    coef_fmt: Fmt = Fmt(False, 16, 15)
    acc_fmt: Fmt | None = None
    norm_word_bits: int = 18
    out_fmt: Fmt | None = None
    rounding: str = "RND_CONV"
    overflow: str = "SAT"
    acc_overflow: str = "WRAP"
    weight_codes: tuple[int, ...] = field(init=False, repr=False, compare=False)
    weight_sat: int = field(init=False, repr=False, compare=False)
    norm_fmt: Fmt = field(init=False, repr=False, compare=False)
    norm_code: int = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        owner = "KineticsConfig"
        check_modes(
            owner, rounding=self.rounding, overflow=self.overflow, acc_overflow=self.acc_overflow
        )
        check_positive(owner, norm_word_bits=self.norm_word_bits)
        t = tuple(float(v) for v in self.t_s)
        if not t or not all(math.isfinite(v) for v in t):
            raise ValueError(f"{owner}.t_s = {self.t_s!r}: must be one or more finite times in s")
        if not (math.isfinite(self.k_per_s) and self.k_per_s >= 0):
            raise ValueError(f"{owner}.k_per_s = {self.k_per_s!r}: must be a finite rate ≥ 0 (1/s)")
        _set(self, "t_s", t)
        with errors_named(owner):
            self._derive_weights()
            self._derive_registers()

    def _derive_registers(self) -> None:
        product = mul_fmt(self.in_fmt, self.coef_fmt)
        if self.acc_fmt is None:
            _set(self, "acc_fmt", sum_fmt(product, len(self.t_s)))
        _check_acc(self.acc_fmt, product)
        if self.out_fmt is None:
            x_max = max(abs(self.in_fmt.min_value), self.in_fmt.max_value)
            w_sum = Fraction(sum(self.weight_codes)) * Fraction(2) ** -self.coef_fmt.frac_bits
            _set(
                self, "out_fmt", fmt_holding(x_max * self.norm_value * w_sum, self.in_fmt.frac_bits)
            )
        self.registers()

    def _derive_weights(self) -> None:
        counter = OverflowCounter()
        w = reference.kinetics_weights(np.array(self.t_s), self.k_per_s)
        codes = quantize(w, self.coef_fmt, "RND_CONV", "SAT", counter)
        energy = sum(int(c) * int(c) for c in codes)
        if energy == 0:
            raise ValueError(
                f"coef_fmt = {self.coef_fmt}: every weight exp(-k t) rounds to 0; "
                "give the weights more fractional bits"
            )
        g = Fraction(4**self.coef_fmt.frac_bits, energy)
        norm_fmt = fmt_for_range(g, self.norm_word_bits, signed=False)
        _set(self, "weight_codes", tuple(int(c) for c in codes))
        _set(self, "weight_sat", counter.sat)
        _set(self, "norm_fmt", norm_fmt)
        _set(self, "norm_code", quantize_fraction(g, norm_fmt, "RND_CONV", "SAT"))

    @property
    def norm_value(self) -> Fraction:
        """The quantized normalisation ``g``, exact."""
        return Fraction(self.norm_code) * Fraction(2) ** -self.norm_fmt.frac_bits

    def registers(self) -> dict[str, Fmt]:
        """Register formats in data-path order."""
        product = mul_fmt(self.in_fmt, self.coef_fmt)
        return {
            "input": self.in_fmt,
            "weights": self.coef_fmt,
            "product": product,
            "acc": self.acc_fmt,
            "norm": self.norm_fmt,
            "scaled": mul_fmt(self.acc_fmt, self.norm_fmt),
            "output": self.out_fmt,
        }


def kinetics_weighted_fixed(frames: np.ndarray, cfg: KineticsConfig) -> FixedResult:
    """Bit-accurate kinetics-weighted accumulation (matched-filter amplitude).

    Parameters
    ----------
    frames : int array (..., N, n_pixels)
        Background-subtracted frames, codes of ``cfg.in_fmt``; ``N = len(cfg.t_s)``.

    Returns
    -------
    FixedResult
        ``codes`` (..., n_pixels) in ``cfg.out_fmt``; registers ``weights``, ``acc``, ``output``
        (the full-precision ``product`` and ``scaled`` with zero counts).
    """
    n = len(cfg.t_s)
    x = as_codes(frames, cfg.in_fmt, "kinetics_weighted: frames")
    if x.ndim < 2 or x.shape[-2] != n:
        raise ValueError(f"kinetics_weighted: frames {x.shape} must be (..., N={n}, n_pixels)")
    log = OverflowLog("weights", "product", "acc", "norm", "scaled", "output")
    log["weights"].add(cfg.weight_sat, 0)
    w = np.array(cfg.weight_codes, dtype=np.int64)
    product = mul_fmt(cfg.in_fmt, cfg.coef_fmt)
    checked = needs_checks(product, n, cfg.acc_fmt, cfg.acc_overflow)
    acc, n_sat, n_wrap = K.mac_frames_kernel(
        x.reshape(-1, n, x.shape[-1]), w, cfg.acc_fmt.spec, overflow_code(cfg.acc_overflow), checked
    )
    log["acc"].add(n_sat, n_wrap)
    acc = acc.reshape(x.shape[:-2] + x.shape[-1:])
    out = _mac_output(acc, cfg.acc_fmt, cfg.norm_code, cfg.norm_fmt, cfg, log)
    return FixedResult(out, cfg.out_fmt, log.as_dict())


# ---------------------------------------------------------------------------------------------
# 8-tap low-pass FIR
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class FirConfig:
    """Low-pass FIR along the frame axis (per pixel), causal, zero initial state.

    Registers: ``input`` (``in_fmt``) · ``coef`` (``scipy.signal.firwin(taps, cutoff, window)``
    rounded to nearest even into ``coef_fmt``, default Q1.15, SAT) · ``product`` (``x · h``, full
    precision) · ``acc`` (``acc_fmt``, default signed 40 bits with ``F_in + F_coef`` fractional
    bits; taps added newest sample first, ``k = 0 … taps-1``, each partial sum through
    ``acc_overflow``) · ``output`` (``out_fmt``, default ``in_fmt``; RND then SAT by default).

    Parameters
    ----------
    cutoff : float
        Cut-off as a fraction of the Nyquist frequency of the frame rate (0 < cutoff < 1).
    """

    taps: int = 8
    cutoff: float = 0.25
    window: str = "hamming"
    in_fmt: Fmt = WORD_FMT
    coef_fmt: Fmt = Q1_15
    acc_fmt: Fmt | None = None
    out_fmt: Fmt | None = None
    rounding: str = "RND"
    overflow: str = "SAT"
    acc_overflow: str = "WRAP"
    coef_codes: tuple[int, ...] = field(init=False, repr=False, compare=False)
    coef_sat: int = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        owner = "FirConfig"
        check_modes(
            owner, rounding=self.rounding, overflow=self.overflow, acc_overflow=self.acc_overflow
        )
        check_positive(owner, taps=self.taps)
        if not 0.0 < self.cutoff < 1.0:
            raise ValueError(f"{owner}.cutoff = {self.cutoff!r}: must be in (0, 1) × Nyquist")
        with errors_named(owner):
            product = mul_fmt(self.in_fmt, self.coef_fmt)
            if self.acc_fmt is None:
                _set(self, "acc_fmt", Fmt(True, 40, product.frac_bits))
            if self.out_fmt is None:
                _set(self, "out_fmt", self.in_fmt)
            _check_acc(self.acc_fmt, product)
        counter = OverflowCounter()
        codes = quantize(self.coefficients(), self.coef_fmt, "RND_CONV", "SAT", counter)
        _set(self, "coef_codes", tuple(int(c) for c in codes))
        _set(self, "coef_sat", counter.sat)

    def coefficients(self) -> np.ndarray:
        """The float taps (the reference filter)."""
        return reference.fir_lowpass(self.taps, self.cutoff, self.window)

    def registers(self) -> dict[str, Fmt]:
        """Register formats in data-path order."""
        return {
            "input": self.in_fmt,
            "coef": self.coef_fmt,
            "product": mul_fmt(self.in_fmt, self.coef_fmt),
            "acc": self.acc_fmt,
            "output": self.out_fmt,
        }


def fir_fixed(frames: np.ndarray, cfg: FirConfig) -> FixedResult:
    """Bit-accurate low-pass FIR along axis 0.

    Parameters
    ----------
    frames : int array (n_frames, n_pixels)
        Codes of ``cfg.in_fmt``.

    Returns
    -------
    FixedResult
        ``codes`` (n_frames, n_pixels) in ``cfg.out_fmt``; registers ``coef``, ``acc``, ``output``.
    """
    x = as_codes(frames, cfg.in_fmt, "fir: frames")
    if x.ndim < 1:
        raise ValueError("fir: frames must be (n_frames, n_pixels)")
    log = OverflowLog("coef", "product", "acc", "output")
    log["coef"].add(cfg.coef_sat, 0)
    h = np.array(cfg.coef_codes, dtype=np.int64)
    product = mul_fmt(cfg.in_fmt, cfg.coef_fmt)
    checked = needs_checks(product, cfg.taps, cfg.acc_fmt, cfg.acc_overflow)
    acc, n_sat, n_wrap = K.fir_kernel(
        x.reshape(x.shape[0], -1), h, cfg.acc_fmt.spec, overflow_code(cfg.acc_overflow), checked
    )
    log["acc"].add(n_sat, n_wrap)
    out = _mac_output(acc.reshape(x.shape), cfg.acc_fmt, None, None, cfg, log)
    return FixedResult(out, cfg.out_fmt, log.as_dict())


# ---------------------------------------------------------------------------------------------
# Wiener equalizer of optical cross-talk
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class WienerConfig:
    """Choices for the Wiener equalizer; :func:`design_wiener` turns them into registers.

    Parameters
    ----------
    noise_to_signal : float
        λ = σ_n² / σ_s² (see :func:`chiptwin.dsp.reference.wiener_matrix`).
    coef_word_bits : int
        Width of the signed coefficient ROM; its fractional bits are the most that hold
        ``max |G|``.
    acc_word_bits : int or None
        Accumulator width; None: full precision (product + ``⌈log2 n_pixels⌉``).
    out_fmt : Fmt or None
        None: the input's fractional bits, integer bits for ``max|x| · max_s Σ_p |G_q[s, p]|``.
    """

    noise_to_signal: float = 0.01
    in_fmt: Fmt = WORD_FMT
    coef_word_bits: int = 18
    acc_word_bits: int | None = None
    out_fmt: Fmt | None = None
    rounding: str = "RND_CONV"
    overflow: str = "SAT"
    acc_overflow: str = "WRAP"

    def __post_init__(self) -> None:
        owner = "WienerConfig"
        check_modes(
            owner, rounding=self.rounding, overflow=self.overflow, acc_overflow=self.acc_overflow
        )
        check_positive(owner, coef_word_bits=self.coef_word_bits)
        if self.acc_word_bits is not None:
            check_positive(owner, acc_word_bits=self.acc_word_bits)
        if not (math.isfinite(self.noise_to_signal) and self.noise_to_signal >= 0):
            raise ValueError(f"{owner}.noise_to_signal = {self.noise_to_signal!r}: must be ≥ 0")


@dataclass(frozen=True, eq=False)
class WienerEqualizer:
    """A designed equalizer: float matrix, quantized coefficient ROM and every register format.

    Registers: ``input`` (``cfg.in_fmt``) · ``coef`` (``coef_fmt``) · ``product`` (full precision)
    · ``acc`` (``acc_fmt``, pixels added in order ``p = 0 … n_pixels-1``) · ``output``
    (``out_fmt``).
    """

    cfg: WienerConfig
    g: np.ndarray
    coef_fmt: Fmt
    coef_codes: np.ndarray
    coef_sat: int
    acc_fmt: Fmt
    out_fmt: Fmt

    @property
    def n_sites(self) -> int:
        """Rows of ``G``."""
        return int(self.g.shape[0])

    @property
    def n_pixels(self) -> int:
        """Columns of ``G``."""
        return int(self.g.shape[1])

    def registers(self) -> dict[str, Fmt]:
        """Register formats in data-path order."""
        return {
            "input": self.cfg.in_fmt,
            "coef": self.coef_fmt,
            "product": mul_fmt(self.cfg.in_fmt, self.coef_fmt),
            "acc": self.acc_fmt,
            "output": self.out_fmt,
        }


def design_wiener(coupling: np.ndarray, cfg: WienerConfig) -> WienerEqualizer:
    """Design and quantize the equalizer for a coupling matrix (n_pixels × n_sites)."""
    with errors_named("design_wiener"):
        return _design_wiener(coupling, cfg)


def _design_wiener(coupling: np.ndarray, cfg: WienerConfig) -> WienerEqualizer:
    g = reference.wiener_matrix(coupling, cfg.noise_to_signal)
    coef_fmt = fmt_for_range(float(np.max(np.abs(g))), cfg.coef_word_bits, signed=True)
    counter = OverflowCounter()
    codes = quantize(g, coef_fmt, "RND_CONV", "SAT", counter)
    g.flags.writeable = False
    codes.flags.writeable = False
    product = mul_fmt(cfg.in_fmt, coef_fmt)
    full = sum_fmt(product, g.shape[1])
    acc_bits = full.word_bits if cfg.acc_word_bits is None else cfg.acc_word_bits
    out_fmt = cfg.out_fmt
    if out_fmt is None:
        gain = Fraction(int(np.max(np.abs(codes).sum(axis=1)))) * Fraction(2) ** -coef_fmt.frac_bits
        x_max = max(abs(cfg.in_fmt.min_value), cfg.in_fmt.max_value)
        out_fmt = fmt_holding(x_max * gain, cfg.in_fmt.frac_bits)
    return WienerEqualizer(
        cfg=cfg,
        g=g,
        coef_fmt=coef_fmt,
        coef_codes=codes,
        coef_sat=counter.sat,
        acc_fmt=Fmt(True, acc_bits, product.frac_bits),
        out_fmt=out_fmt,
    )


def wiener_equalize_fixed(frames: np.ndarray, eq: WienerEqualizer) -> FixedResult:
    """Bit-accurate Wiener equalization ``ŝ = G_q @ pixel`` of each frame.

    Parameters
    ----------
    frames : int array (..., n_pixels)
        Background-subtracted frames, codes of ``eq.cfg.in_fmt``.

    Returns
    -------
    FixedResult
        ``codes`` (..., n_sites) in ``eq.out_fmt``; registers ``coef``, ``acc``, ``output``.
    """
    cfg = eq.cfg
    x = as_codes(frames, cfg.in_fmt, "wiener: frames")
    if x.shape[-1:] != (eq.n_pixels,):
        raise ValueError(f"wiener: frames {x.shape} must end in n_pixels = {eq.n_pixels}")
    log = OverflowLog("coef", "product", "acc", "output")
    log["coef"].add(eq.coef_sat, 0)
    product = mul_fmt(cfg.in_fmt, eq.coef_fmt)
    checked = needs_checks(product, eq.n_pixels, eq.acc_fmt, cfg.acc_overflow)
    acc, n_sat, n_wrap = K.matvec_kernel(
        x.reshape(-1, eq.n_pixels),
        eq.coef_codes,
        eq.acc_fmt.spec,
        overflow_code(cfg.acc_overflow),
        checked,
    )
    log["acc"].add(n_sat, n_wrap)
    acc = acc.reshape(x.shape[:-1] + (eq.n_sites,))
    out = _requantize(acc, eq.acc_fmt, eq.out_fmt, cfg.rounding, cfg.overflow, log["output"])
    return FixedResult(out, eq.out_fmt, log.as_dict())
