"""Fixed-point array operations: exact quantization, requantization, full-precision arithmetic.

Formats, modes and word growth are in :mod:`chiptwin.dsp.fmt` (re-exported here). Codes are
``int64`` arrays; each public function validates dtype and range once and calls a numba kernel
(:mod:`chiptwin.dsp._kernels`); the ``_private`` twins skip the validation for codes the routines
produced themselves. Every operation that can overflow adds its saturation and wrap events to an
optional :class:`OverflowCounter`; ``uint64`` input is refused (mixed with int64 it
turns into float64 in numba).
"""

from __future__ import annotations

import numpy as np

from chiptwin.dsp import _kernels as K
from chiptwin.dsp.fmt import (
    MAX_FRAC_BITS,
    NEAREST_MODES,
    OVERFLOW_MODES,
    ROUNDING_MODES,
    Fmt,
    Overflow,
    OverflowCounter,
    Rounding,
    accumulator_bits_needed,
    add_fmt,
    fit_int,
    fmt_for_range,
    mul_fmt,
    overflow_code,
    quantize_fraction,
    round_fraction,
    rounding_code,
    sum_fmt,
)

__all__ = [
    "MAX_FRAC_BITS",
    "NEAREST_MODES",
    "OVERFLOW_MODES",
    "ROUNDING_MODES",
    "Fmt",
    "Overflow",
    "OverflowCounter",
    "Rounding",
    "accumulate",
    "accumulate_into",
    "accumulator_bits_needed",
    "add",
    "add_fmt",
    "as_codes",
    "fit_int",
    "fmt_for_range",
    "mul",
    "mul_fmt",
    "needs_checks",
    "overflow_code",
    "quantize",
    "quantize_fraction",
    "requantize",
    "round_fraction",
    "rounding_code",
    "sub",
    "sum_fmt",
]

# ---------------------------------------------------------------------------------------------
# validation
# ---------------------------------------------------------------------------------------------


def as_codes(codes: np.ndarray | int, fmt: Fmt, name: str = "codes") -> np.ndarray:
    """Validate integer codes of ``fmt`` once (dtype, range); return them as C-contiguous int64.

    Raises
    ------
    TypeError
        Non-integer dtype, or ``uint64`` (refused: it turns into float64 when mixed with int64).
    ValueError
        A code outside ``[fmt.min_code, fmt.max_code]``.
    """
    arr = np.asarray(codes)
    if arr.dtype == np.uint64:
        raise TypeError(f"{name}: uint64 codes are refused; pass int64 (numba turns "
                        "uint64 mixed with int64 into float64)")
    if arr.dtype.kind not in "iub":
        raise TypeError(f"{name}: codes must be integers, got dtype {arr.dtype}")
    arr = _contiguous(arr, np.int64)
    if arr.size == 0:
        return arr
    lo, hi = K.range_kernel(arr.reshape(-1))
    if lo < fmt.min_code or hi > fmt.max_code:
        bad = arr[(arr < fmt.min_code) | (arr > fmt.max_code)].flat[0]
        raise ValueError(
            f"{name}: code {bad} outside {fmt.describe()} range [{fmt.min_code}, {fmt.max_code}]"
        )
    return arr


def _contiguous(x: np.ndarray | float, dtype: type) -> np.ndarray:
    """``x`` as a C-contiguous array of ``dtype``, keeping 0-d shapes (kernels see one layout)."""
    arr = np.asarray(x, dtype=dtype)
    return arr if arr.flags.c_contiguous else np.ascontiguousarray(arr)


def _as_float(x: np.ndarray | float, name: str) -> np.ndarray:
    arr = _contiguous(x, np.float64)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: NaN or infinite values cannot be quantized")
    return arr


# ---------------------------------------------------------------------------------------------
# quantize / requantize
# ---------------------------------------------------------------------------------------------


def quantize(
    x: np.ndarray | float,
    fmt: Fmt,
    rounding: Rounding = "RND_CONV",
    overflow: Overflow = "SAT",
    counter: OverflowCounter | None = None,
) -> np.ndarray:
    """Float64 values to codes of ``fmt``, exactly: one rounding of the exact value, no double one.

    Parameters
    ----------
    x : array_like of float64, any shape
        Finite values (NaN/inf are refused).
    fmt : Fmt
        Destination format.
    rounding, overflow : str
        See the module docstring. Rounding first, then overflow.
    counter : OverflowCounter, optional
        Receives the saturation and wrap events.

    Returns
    -------
    ndarray of int64, shape of ``x``.

    Notes
    -----
    ``x · 2^F`` is exact in float64 whenever it is a normal number below ``2^62``; the kernel
    rounds that float exactly (``floor`` and ``y - floor(y)`` are exact). Otherwise it splits
    ``x = m · 2^e`` (``math.frexp``, ``|m| < 2^53``) and rounds the integer ``m · 2^(e+F)`` with
    integer shifts, so subnormals, huge values and huge ``|F|`` are exact too.
    """
    arr = _as_float(x, "quantize: x")
    codes, n_sat, n_wrap = K.quantize_kernel(
        arr.ravel(), fmt.frac_bits, fmt.spec, rounding_code(rounding), overflow_code(overflow)
    )
    if counter is not None:
        counter.add(n_sat, n_wrap)
    return codes.reshape(arr.shape)


def requantize(
    codes: np.ndarray,
    src: Fmt,
    dst: Fmt,
    rounding: Rounding = "RND_CONV",
    overflow: Overflow = "SAT",
    counter: OverflowCounter | None = None,
) -> np.ndarray:
    """Codes of ``src`` to codes of ``dst``: round away ``src.F - dst.F`` bits, then overflow.

    Exact for every pair of formats (shifts of any length, 64-bit words included).

    Returns
    -------
    ndarray of int64, shape of ``codes``.
    """
    return _requantize(
        as_codes(codes, src, "requantize: codes"), src, dst, rounding, overflow, counter
    )


def _requantize(
    arr: np.ndarray,
    src: Fmt,
    dst: Fmt,
    rounding: str,
    overflow: str,
    counter: OverflowCounter | None,
) -> np.ndarray:
    """:func:`requantize` of codes already validated (C-contiguous int64 inside ``src``)."""
    out, n_sat, n_wrap = K.requantize_kernel(
        arr.ravel(),
        dst.frac_bits - src.frac_bits,
        dst.spec,
        rounding_code(rounding),
        overflow_code(overflow),
    )
    if counter is not None:
        counter.add(n_sat, n_wrap)
    return out.reshape(arr.shape)


# ---------------------------------------------------------------------------------------------
# full-precision arithmetic
# ---------------------------------------------------------------------------------------------


def _broadcast(ca: np.ndarray, cb: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool, tuple]:
    """Arrange two code arrays for the 2-D kernels: ``(big2d, small1d, swapped, shape)``.

    Equal shapes, a trailing-axes operand (e.g. a dark frame under a stack of frames) and a
    scalar need no copy; other broadcasts are materialized.
    """
    shape = np.broadcast_shapes(ca.shape, cb.shape)
    for big, small, swapped in ((ca, cb, False), (cb, ca, True)):
        if big.shape != shape:
            continue
        if small.size == 1 or small.shape == shape:
            return big.reshape(1, -1), small.reshape(-1), swapped, shape
        if small.size and small.shape == shape[len(shape) - small.ndim :]:
            return big.reshape(-1, small.size), small.reshape(-1), swapped, shape
    ca, cb = (np.ascontiguousarray(v) for v in np.broadcast_arrays(ca, cb))
    return ca.reshape(1, -1), cb.reshape(-1), False, shape


def _lincomb(ca: np.ndarray, fa: Fmt, cb: np.ndarray, fb: Fmt, sign: int) -> tuple[np.ndarray, Fmt]:
    """Full-precision ``a + sign·b`` of validated codes."""
    out_fmt = add_fmt(fa, fb, subtract=sign < 0)
    sa, sb = out_fmt.frac_bits - fa.frac_bits, out_fmt.frac_bits - fb.frac_bits
    big, small, swapped, shape = _broadcast(ca, cb)
    if swapped:
        out = K.lincomb_kernel(big, sb, sign, small, sa, 1)
    else:
        out = K.lincomb_kernel(big, sa, 1, small, sb, sign)
    return out.reshape(shape), out_fmt


def _mul(ca: np.ndarray, fa: Fmt, cb: np.ndarray, fb: Fmt) -> tuple[np.ndarray, Fmt]:
    """Full-precision ``a · b`` of validated codes."""
    out_fmt = mul_fmt(fa, fb)
    big, small, _, shape = _broadcast(ca, cb)
    return K.mul_kernel(big, small).reshape(shape), out_fmt


def add(a: np.ndarray, fa: Fmt, b: np.ndarray, fb: Fmt) -> tuple[np.ndarray, Fmt]:
    """Full-precision ``a + b`` (broadcasting). Never overflows. Returns ``(codes, Fmt)``."""
    return _lincomb(as_codes(a, fa, "add: a"), fa, as_codes(b, fb, "add: b"), fb, 1)


def sub(a: np.ndarray, fa: Fmt, b: np.ndarray, fb: Fmt) -> tuple[np.ndarray, Fmt]:
    """Full-precision ``a - b`` (broadcasting), always signed. Returns ``(codes, Fmt)``."""
    return _lincomb(as_codes(a, fa, "sub: a"), fa, as_codes(b, fb, "sub: b"), fb, -1)


def mul(a: np.ndarray, fa: Fmt, b: np.ndarray, fb: Fmt) -> tuple[np.ndarray, Fmt]:
    """Full-precision ``a · b`` (broadcasting). Never overflows. Returns ``(codes, Fmt)``."""
    return _mul(as_codes(a, fa, "mul: a"), fa, as_codes(b, fb, "mul: b"), fb)


def accumulate(codes: np.ndarray, fmt: Fmt, axis: int = 0) -> tuple[np.ndarray, Fmt]:
    """Full-precision sum along ``axis`` (``+⌈log2 n⌉`` integer bits). Returns ``(codes, Fmt)``."""
    arr = as_codes(codes, fmt)
    out_fmt = sum_fmt(fmt, arr.shape[axis])
    return arr.sum(axis=axis, dtype=np.int64), out_fmt


def accumulate_into(
    codes: np.ndarray,
    fmt: Fmt,
    acc_fmt: Fmt,
    overflow: Overflow = "WRAP",
    counter: OverflowCounter | None = None,
    axis: int = 0,
) -> np.ndarray:
    """Sum along ``axis``, in order, in a hardware accumulator register of format ``acc_fmt``.

    Parameters
    ----------
    codes : int array
        The values to add; index 0 along ``axis`` is added first.
    fmt : Fmt
        Their format; ``fmt.frac_bits`` must equal ``acc_fmt.frac_bits``.
    acc_fmt : Fmt
        The accumulator register, reset to 0. Each partial sum goes through ``overflow``.
    overflow : str
        ``WRAP`` counts every addition whose exact result left the range (the final sum is still
        right modulo ``2^W``); ``SAT`` / ``SAT_SYM`` clamp each partial sum (order matters).
    counter : OverflowCounter, optional
        Receives the events.
    axis : int
        The axis summed.

    Returns
    -------
    ndarray of int64 in ``acc_fmt``: ``codes`` without ``axis``.
    """
    return _accumulate_into(as_codes(codes, fmt), fmt, acc_fmt, overflow, counter, axis)


def _accumulate_into(
    arr: np.ndarray,
    fmt: Fmt,
    acc_fmt: Fmt,
    overflow: str,
    counter: OverflowCounter | None,
    axis: int,
) -> np.ndarray:
    """:func:`accumulate_into` of codes already validated."""
    if fmt.frac_bits != acc_fmt.frac_bits:
        raise ValueError(
            f"accumulate_into: accumulator {acc_fmt} must keep the {fmt.frac_bits} fractional "
            f"bits of its input {fmt}"
        )
    if arr.ndim == 0:
        raise ValueError("accumulate_into: codes must have at least one axis")
    axis = axis % arr.ndim
    n = arr.shape[axis]
    blocks = arr.reshape(int(np.prod(arr.shape[:axis])), n, -1)
    acc, n_sat, n_wrap = K.accumulate_kernel(
        blocks, acc_fmt.spec, overflow_code(overflow), needs_checks(fmt, n, acc_fmt, overflow)
    )
    if counter is not None:
        counter.add(n_sat, n_wrap)
    return acc.reshape(arr.shape[:axis] + arr.shape[axis + 1 :])


def needs_checks(term_fmt: Fmt, n_terms: int, acc_fmt: Fmt, overflow: str) -> bool:
    """False when no partial sum of ``n_terms`` terms of ``term_fmt`` can leave ``acc_fmt``.

    The kernels then take their fast path (plain ``int64`` adds). ``SAT_SYM`` on a signed
    register is always checked: it also rewrites a partial sum equal to the most negative code.
    """
    if n_terms == 0:
        return False
    if overflow == "SAT_SYM" and acc_fmt.signed:
        return True
    if term_fmt.signed and not acc_fmt.signed:
        return True
    need = accumulator_bits_needed(term_fmt, n_terms) + int(acc_fmt.signed != term_fmt.signed)
    return need > acc_fmt.word_bits
