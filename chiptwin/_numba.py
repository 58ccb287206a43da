"""The one place numba options are set.

Every ``@njit`` in chiptwin uses :data:`NJIT`; change caching or fastmath here, never per kernel.
``fastmath`` stays off: the fixed-point kernels and the noise statistics rely on IEEE semantics.
Set ``NUMBA_DISABLE_JIT=1`` to run every kernel as plain Python (for coverage and debugging).
"""

from __future__ import annotations

from numba import njit

#: Options shared by every kernel: compiled once, cached on disk, no GIL (threads can share work).
NJIT_OPTIONS: dict[str, bool] = {"cache": True, "nogil": True, "fastmath": False}

#: ``@NJIT`` is ``@njit(**NJIT_OPTIONS)``.
NJIT = njit(**NJIT_OPTIONS)
