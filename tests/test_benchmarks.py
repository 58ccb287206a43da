"""Benchmarks that cannot rot (issue 22, item 4): every script in ``benchmarks/`` runs with
``--quick`` (a small size, the same code path) in a process of its own, exits 0 and prints its
figures. The process is forked from the test worker (:class:`_Forked`): the script runs as
``__main__`` as ``python SCRIPT --quick`` runs it, without paying the imports again.

Nothing here times anything: a figure is "printed" when the output holds a number with a unit
(``0.12 s``, ``848 ns``, ``1.9x``, a JSON key ending in ``_s``) or the script's own table header
(:data:`HEADERS`). The scripts are found by glob, so a new benchmark is covered the day it lands.
Each script is started when its test (or, in a serial session, the test before it) asks for it,
so in a serial session two run at a time (the machine's two cores) and under xdist each worker
runs only the scripts of the tests it was given, one at a time (the other core is the other
worker's).
"""

from __future__ import annotations

import os
import re
import runpy
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import traceback
from pathlib import Path

import pytest

from tests.conftest import unavailable

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = sorted((ROOT / "benchmarks").glob("*.py"))

#: A table header a script prints, where its figures carry their unit in the header.
HEADERS = {
    "bench_cascade.py": "| method | rtol | wall per flow (ms) |",
    "bench_estimate.py": "measured s",
    "bench_ladder.py": "wall s",
    "bench_program.py": "held bits",
    "bench_replicate.py": "wall s",
    "bench_rtl.py": "Mbeat/s",
}
#: A number followed by a unit, or a JSON figure whose key names its unit.
FIGURE = re.compile(r"\d(?:\.\d+)?(?:e[+-]?\d+)?\s?(?:ns|µs|us|ms|s|x|×|MB|GB|%)(?![\w/])"
                    r"|_(?:s|ns|mb)\"\s*:\s*\d")
TIMEOUT_S = 600


def _needs_missing_tools(script: Path) -> bool:
    return script.name == "bench_rtl.py" and not (shutil.which("verilator")
                                                  and shutil.which("iverilog"))


class _Forked:
    """``python SCRIPT --quick`` run in a child forked from this test process: the script runs as
    ``__main__`` with its own argv, working directory and file descriptors 1 and 2 (what it and
    any process it starts print is captured), but it inherits the libraries this process has
    imported and the kernels it has loaded. A fresh interpreter paid 1–3 s of imports per script
    (py-spy over the suite: 24 CPU-s of the module's 45 s). What a script changes (modules,
    environment, threads) dies with the child. Processes the script starts itself (a pool, a
    cold run) are fresh interpreters as before."""

    def __init__(self, script: Path) -> None:
        self.script = script
        self._out, self._err = tempfile.TemporaryFile(), tempfile.TemporaryFile()
        self._deadline = time.monotonic() + TIMEOUT_S
        sys.stdout.flush()
        sys.stderr.flush()
        self._pid = os.fork()
        if self._pid == 0:
            self._child()  # never returns

    def _child(self) -> None:
        code = 1
        try:
            os.dup2(self._out.fileno(), 1)
            os.dup2(self._err.fileno(), 2)
            sys.stdout = open(1, "w", encoding="utf-8", closefd=False)  # noqa: SIM115
            sys.stderr = open(2, "w", encoding="utf-8", closefd=False)  # noqa: SIM115
            os.chdir(ROOT)
            os.environ.update(PYTHONPATH=str(ROOT), MPLBACKEND="Agg")
            sys.argv = [str(self.script), "--quick"]
            sys.path.insert(0, str(self.script.parent))  # as ``python SCRIPT`` puts it first
            runpy.run_path(str(self.script), run_name="__main__")
            code = 0
        except SystemExit as e:
            if e.code is None or isinstance(e.code, int):
                code = e.code or 0
            else:
                print(e.code, file=sys.stderr)
        except BaseException:
            traceback.print_exc()
        finally:
            try:
                sys.stdout.flush()
                sys.stderr.flush()
            finally:
                os._exit(code)

    def result(self) -> subprocess.CompletedProcess:
        """Wait for the script (killed after :data:`TIMEOUT_S`) and return what it printed."""
        while True:
            pid, status = os.waitpid(self._pid, os.WNOHANG)
            if pid:
                code = os.waitstatus_to_exitcode(status)
                break
            if time.monotonic() > self._deadline:
                os.kill(self._pid, signal.SIGKILL)
                os.waitpid(self._pid, 0)
                code = -signal.SIGKILL
                break
            time.sleep(0.02)
        out = [f.seek(0) or f.read().decode("utf-8", "replace") for f in (self._out, self._err)]
        for f in (self._out, self._err):
            f.close()
        return subprocess.CompletedProcess([self.script.name, "--quick"], code, *out)


class _Started:
    """Scripts started on demand: :meth:`result` starts a script (if not yet) and, in a serial
    session, the next selected one too, so that two run at a time. Under xdist a worker cannot
    know which test it gets next: it starts only its own test's script (each script runs once in
    the session, not once per worker)."""

    def __init__(self, order: list[str], prefetch: bool) -> None:
        self._order, self._prefetch = order, prefetch
        self._children: dict[str, _Forked] = {}
        self._done: dict[str, subprocess.CompletedProcess] = {}

    def _start(self, name: str) -> None:
        if name not in self._children:
            self._children[name] = _Forked(ROOT / "benchmarks" / name)

    def result(self, name: str) -> subprocess.CompletedProcess:
        self._start(name)
        if self._prefetch and name in self._order:
            later = self._order[self._order.index(name) + 1:]
            if later:
                self._start(later[0])
        if name not in self._done:
            self._done[name] = self._children[name].result()
        return self._done[name]

    def close(self) -> None:
        for name in self._children:  # a prefetched script no test asked for: wait, not orphan
            self.result(name)


@pytest.fixture(scope="module")
def started(request):
    """The scripts, started as the tests ask for them (:class:`_Started`)."""
    order = [item.callspec.params["script"].name for item in request.session.items
             if item.module is request.module and hasattr(item, "callspec")
             and not _needs_missing_tools(item.callspec.params["script"])]
    runner = _Started(order, prefetch="PYTEST_XDIST_WORKER" not in os.environ)
    yield runner
    runner.close()


def _params():
    for script in SCRIPTS:
        yield pytest.param(script, id=script.name)


def test_there_are_benchmarks():
    assert len(SCRIPTS) >= 10, SCRIPTS


@pytest.mark.parametrize("script", list(_params()))
def test_benchmark_runs_quick_and_prints_its_figures(script: Path,
                                                     started: _Started):
    if _needs_missing_tools(script):
        unavailable("bench_rtl.py needs verilator and iverilog: apt-get install verilator iverilog")
    done = started.result(script.name)
    out = done.stdout
    assert done.returncode == 0, (f"{script.name} --quick exited {done.returncode}\n"
                                  f"{out[-2000:]}\n{done.stderr[-3000:]}")
    header = HEADERS.get(script.name)
    assert (header and header in out) or FIGURE.search(out), (
        f"{script.name} --quick printed no figure (a number with a unit"
        f"{' or ' + repr(header) if header else ''}):\n{out[-2000:]}")
