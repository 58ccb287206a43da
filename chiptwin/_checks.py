"""Argument checks shared by the stage packages (kinetics, optics).

Every failure is a :class:`ValueError` whose message names the argument, the offending value and the
allowed range, e.g. ``"apyrase_per_s = -0.1 is out of range: must be >= 0"``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray


def _first_bad(values: NDArray[np.float64], ok: NDArray[np.bool_]) -> str:
    """Render the first value that fails ``ok``, with its index for arrays."""
    if values.ndim == 0:
        return repr(float(values))
    index = tuple(int(i) for i in np.argwhere(~ok)[0])
    where = index[0] if len(index) == 1 else index
    return f"{float(values[index])!r} (at index {where})"


def as_float_array(name: str, value: ArrayLike) -> NDArray[np.float64]:
    """Convert to a float64 array; reject NaN and infinities."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} = {value!r} is not a number or an array of numbers") from exc
    finite = np.isfinite(arr)
    if not finite.all():
        raise ValueError(f"{name} = {_first_bad(arr, finite)} is out of range: must be finite")
    return arr


def nonnegative(name: str, value: ArrayLike) -> NDArray[np.float64]:
    """Finite and >= 0."""
    arr = as_float_array(name, value)
    ok = arr >= 0.0
    if not ok.all():
        raise ValueError(f"{name} = {_first_bad(arr, ok)} is out of range: must be >= 0")
    return arr


def positive(name: str, value: ArrayLike) -> NDArray[np.float64]:
    """Finite and > 0."""
    arr = as_float_array(name, value)
    ok = arr > 0.0
    if not ok.all():
        raise ValueError(f"{name} = {_first_bad(arr, ok)} is out of range: must be > 0")
    return arr


def quantum_yield(name: str, value: float) -> float:
    """A quantum yield: a finite scalar in [0, 1]."""
    arr = as_float_array(name, value)
    if arr.ndim != 0 or not 0.0 <= float(arr) <= 1.0:
        raise ValueError(f"{name} = {value!r} is out of range: must be a scalar in [0, 1]")
    return float(arr)


def scalar_or_matching(name: str, value: ArrayLike, n: int) -> NDArray[np.float64]:
    """A finite scalar broadcast to ``(n,)``, or an array of shape ``(n,)``."""
    arr = as_float_array(name, value)
    if arr.ndim == 0:
        return np.full(n, float(arr))
    if arr.shape != (n,):
        raise ValueError(f"{name} has shape {arr.shape}: must be a scalar or have shape ({n},)")
    return arr


def scalar(name: str, value: ArrayLike, *, minimum: float, strict: bool) -> float:
    """A finite scalar ``> minimum`` (``strict``) or ``>= minimum``."""
    arr = as_float_array(name, value)
    if arr.ndim != 0:
        raise ValueError(f"{name} has shape {arr.shape}: must be a scalar")
    x = float(arr)
    if (x <= minimum) if strict else (x < minimum):
        bound = f"> {minimum:g}" if strict else f">= {minimum:g}"
        raise ValueError(f"{name} = {x!r} is out of range: must be {bound}")
    return x
