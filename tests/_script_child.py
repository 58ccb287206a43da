"""A script run as ``python SCRIPT ARGS`` would run it, inside a child of multiprocessing's fork
server (tests/test_benchmarks.py): the server imported the heavy libraries once; each child,
forked from it, runs the script as ``__main__`` with its own argv, working directory and file
descriptors 1 and 2 (what it and any process it starts print goes to the given files).

The server only ever imports: a child forked from it inherits no thread pool, lock or state of
another test (a child forked from a test worker itself once hung in APyTypes' thread pool).
"""

from __future__ import annotations

import os
import runpy
import sys
import traceback

#: What the fork server imports before its first child (the benchmarks' common imports: a fresh
#: interpreter spent 1–3 s on them per script).
PRELOAD = ["numpy", "scipy.special", "scipy.stats", "scipy.optimize", "numba", "simpy",
           "matplotlib.pyplot", "chiptwin.cli", "chiptwin.fidelity", "chiptwin.twin.runner"]


def run_script(script: str, args: list[str], cwd: str, out: str, err: str) -> None:
    """Run ``script`` as ``__main__``; exit with its exit code (1 on an exception, printed)."""
    code = 1
    with open(out, "wb") as fo, open(err, "wb") as fe:
        os.dup2(fo.fileno(), 1)
        os.dup2(fe.fileno(), 2)
    sys.stdout = open(1, "w", encoding="utf-8", closefd=False)  # noqa: SIM115
    sys.stderr = open(2, "w", encoding="utf-8", closefd=False)  # noqa: SIM115
    try:
        os.chdir(cwd)
        sys.argv = [script, *args]
        sys.path.insert(0, os.path.dirname(script))  # as ``python SCRIPT`` puts it first
        runpy.run_path(script, run_name="__main__")
        code = 0
    except SystemExit as e:
        if e.code is None or isinstance(e.code, int):
            code = e.code or 0
        else:
            print(e.code, file=sys.stderr)
    except BaseException:  # noqa: BLE001 (reported as the exit code and the traceback)
        traceback.print_exc()
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
