"""Argument checks shared by the pixel and ADC functions.

Every message names the argument, the value it got and what is allowed, so a caller (or the
scenario adapter above it) can pass it on unchanged.
"""

from __future__ import annotations

import math
import numbers

import numpy as np
from numpy.typing import ArrayLike, NDArray


def _interval(lo: float | None, hi: float | None, lo_open: bool, hi_open: bool) -> str:
    left = "(" if lo_open or lo is None else "["
    right = ")" if hi_open or hi is None else "]"
    lo_s = "-inf" if lo is None else f"{lo:g}"
    hi_s = "inf" if hi is None else f"{hi:g}"
    return f"{left}{lo_s}, {hi_s}{right}"


def check_scalar(
    name: str,
    value: float,
    lo: float | None = None,
    hi: float | None = None,
    *,
    lo_open: bool = False,
    hi_open: bool = False,
) -> float:
    """Return ``value`` as a float after checking it is a finite real number in the interval.

    Raises
    ------
    ValueError
        Naming ``name``, the value and the allowed interval.
    """
    allowed = "a finite real number in " + _interval(lo, hi, lo_open, hi_open)
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name} = {value!r}: must be {allowed}")
    v = float(value)
    bad = not math.isfinite(v)
    bad = bad or (lo is not None and (v <= lo if lo_open else v < lo))
    bad = bad or (hi is not None and (v >= hi if hi_open else v > hi))
    if bad:
        raise ValueError(f"{name} = {value!r}: must be {allowed}")
    return v


def check_int(name: str, value: int, lo: int, hi: int | None = None) -> int:
    """Return ``value`` as an int after checking it is an integer in ``[lo, hi]``.

    Raises
    ------
    ValueError
        Naming ``name``, the value and the allowed range.
    """
    allowed = f"an integer in [{lo}, {'inf' if hi is None else hi}]"
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ValueError(f"{name} = {value!r}: must be {allowed}")
    if value < lo or (hi is not None and value > hi):
        raise ValueError(f"{name} = {value!r}: must be {allowed}")
    return int(value)


def check_array(
    name: str, values: ArrayLike, lo: float | None = None, hi: float | None = None
) -> NDArray[np.float64]:
    """Return ``values`` as a float64 array after checking every element is finite and in range.

    Raises
    ------
    ValueError
        Naming ``name``, the offending extreme value and the allowed interval.
    """
    arr = np.asarray(values, dtype=np.float64)
    if arr.size == 0:
        return arr
    allowed = "finite values in " + _interval(lo, hi, False, False)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} contains NaN or infinite values: must be {allowed}")
    if lo is not None and arr.min() < lo:
        raise ValueError(f"{name} has a value {arr.min()!r}: must be {allowed}")
    if hi is not None and arr.max() > hi:
        raise ValueError(f"{name} has a value {arr.max()!r}: must be {allowed}")
    return arr


def readonly(a: np.ndarray) -> np.ndarray:
    """A read-only view of ``a``: one array type for a kernel whichever write flag ``a`` has
    (numba compiles a kernel again for each)."""
    view = a.view()
    view.flags.writeable = False
    return view
