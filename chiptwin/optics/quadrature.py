"""Gauss–Legendre nodes and weights on [−1, 1], computed once per order.

``numpy.polynomial.legendre.leggauss(n)`` solves an eigenvalue problem each call (≈ 4 ms at
n = 64); the optics summary's stack quadratures asked for the same few orders ~2,000 times per
contact scene with a layer stack (7 of 14 s of a crosstalk_microarray ``auto`` run, measured).
The arrays are read-only: callers share them.
"""

from __future__ import annotations

import functools

import numpy as np
from numpy.typing import NDArray


@functools.lru_cache(maxsize=64)
def gauss_legendre(n: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``leggauss(n)``: nodes ``x`` and weights ``w``, read-only, cached by ``n``."""
    x, w = np.polynomial.legendre.leggauss(n)
    x.setflags(write=False)
    w.setflags(write=False)
    return x, w
