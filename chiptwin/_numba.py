"""The one place numba options are set, and where its on-disk cache lives.

Every ``@njit`` in chiptwin uses :data:`NJIT`; change caching or fastmath here, never per kernel.
``fastmath`` stays off: the fixed-point kernels and the noise statistics rely on IEEE semantics.
Set ``NUMBA_DISABLE_JIT=1`` to run every kernel as plain Python (for coverage and debugging).

**Where compiled kernels are cached.** In a source tree (an editable install, the tests) numba
keeps its cache beside the sources, in ``__pycache__``, as usual. An installed package's folder
is pip's, not ours: cache files written there outlive ``pip uninstall`` and leave a
``chiptwin`` folder without ``__init__.py`` that shadows a later editable install. So
an installed chiptwin caches in the user's cache folder, ``$XDG_CACHE_HOME/chiptwin/numba``
(default ``~/.cache/chiptwin/numba``). ``NUMBA_CACHE_DIR``, when set, always wins.

**When kernels compile.** A kernel's first call on a machine (or after its sources change)
compiles it: the pixel kernels of a first ``chiptwin run pyro_1fmol`` take 15–20 s, without
progress. :func:`announce_compiles` lets the command line say so when it happens.
"""

from __future__ import annotations

import contextlib
import os
import threading
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path

import numba
from numba import njit
from numba.core.errors import NumbaIRAssumptionWarning

PACKAGE_DIR = Path(__file__).resolve().parent


def in_source_tree(package_dir: Path = PACKAGE_DIR) -> bool:
    """True when the package is imported from a checkout (its parent holds pyproject.toml)."""
    return (package_dir.parent / "pyproject.toml").is_file()


def user_cache_dir() -> Path:
    """``$XDG_CACHE_HOME/chiptwin/numba``, or ``~/.cache/chiptwin/numba``."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "chiptwin" / "numba"


def place_cache() -> str:
    """Point numba's cache at the user cache folder for an installed package (see above);
    returns the folder in use ("" = beside the sources)."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return os.environ["NUMBA_CACHE_DIR"]
    if in_source_tree():
        return ""
    folder = str(user_cache_dir())
    os.environ["NUMBA_CACHE_DIR"] = folder  # for processes started from this one
    numba.config.CACHE_DIR = folder  # numba read its environment when it was imported
    return folder


#: The cache folder in force ("" = numba's default, beside the sources).
CACHE_DIR = place_cache()

#: Options shared by every kernel: compiled once, cached on disk, no GIL (threads can share work).
NJIT_OPTIONS: dict[str, bool] = {"cache": True, "nogil": True, "fastmath": False}

#: ``@NJIT`` is ``@njit(**NJIT_OPTIONS)``.
NJIT = njit(**NJIT_OPTIONS)

#: ``@NJIT_INLINE``: the same, inlined into its callers in numba's IR. For the few-instruction
#: helpers of the inner loops (a bit generator's step, the ziggurat's common path): called as
#: functions they cost 2–3× their own work (numba's calling convention and the optimisations the
#: call boundary prevents; measured in chiptwin.pixel._random).
NJIT_INLINE = njit(inline="always", **NJIT_OPTIONS)

#: ``@NJIT_NORC``: the same without numba's reference counting (its runtime, NRT, off: the
#: ``_nrt`` option of numba's CPU target). For the loops that draw random numbers, and for the
#: base caller's per-flow steps (the phasing model's flow step, the hill climb's scoring). An
#: inlined sampler whose rare path is a call (the ziggurat's edges, Ahrens & Dieter's steps
#: P–H) leaves an atomic increment and decrement of the source array's reference count around
#: *every* draw, which numba's pruning does not remove (the call may raise): 9 of a normal's
#: 11 ns, 18 of a Poisson count and a normal's 33 ns (one thread, measured side by side;
#: ``benchmarks/bench_sensor_chain.py``); the caller's steps, run millions of times a read set,
#: paid the same pair on every call. Such a function may not allocate (no ``np.empty``, no
#: ``.copy()``): its caller, an :data:`NJIT` kernel, allocates and passes the arrays in. The
#: results are the same bits.
NJIT_NORC = njit(_nrt=False, **NJIT_OPTIONS)

# Inlining the samplers' overloads (chiptwin.pixel._random) at numba's IR level trips a pedantic
# SSA check ("variable ... is not in scope") numba asks to report; the compiled draws are tested
# bit for bit against NumPy's, so the check is silenced for those overloads only.
warnings.filterwarnings(
    "ignore", message=r".*variable '_(standard_normal|next_double|next_uint64)_jit",
    category=NumbaIRAssumptionWarning)


@contextlib.contextmanager
def announce_compiles(say: Callable[[], None]) -> Iterator[None]:
    """Call ``say()`` once, at the first kernel numba compiles inside the block (a cache miss:
    loading a cached kernel says nothing). Through numba's event API (``numba:compile``, which
    numba broadcasts only when it compiles), from whichever thread compiles."""
    from numba.core import event

    lock, said = threading.Lock(), []

    class _First(event.Listener):
        def on_start(self, ev: event.Event) -> None:
            with lock:
                if said:
                    return
                said.append(True)
            say()

        def on_end(self, ev: event.Event) -> None:
            pass

    listener = _First()
    event.register("numba:compile", listener)
    try:
        yield
    finally:
        event.unregister("numba:compile", listener)
