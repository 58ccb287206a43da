"""Benchmarks that cannot rot: every script in ``benchmarks/`` runs with
``--quick`` (a small size, the same code path) in a process of its own, exits 0 and prints its
figures. The process is forked from a server that has imported the scripts' libraries
(:class:`_Forked`): the script runs as ``__main__`` as ``python SCRIPT --quick`` runs it,
without paying those imports again.

Nothing here times anything: a figure is "printed" when the output holds a number with a unit
(``0.12 s``, ``848 ns``, ``1.9x``, a JSON key ending in ``_s``) or the script's own table header
(:data:`HEADERS`). The scripts are found by glob, so a new benchmark is covered the day it lands.
Each script is started when its test (or, in a serial session, the test before it) asks for it,
so in a serial session two run at a time (the machine's two cores) and under xdist each worker
runs only the scripts of the tests it was given, one at a time (the other core is the other
worker's).
"""

from __future__ import annotations

import multiprocessing
import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from tests import _script_child
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
    """``python SCRIPT --quick``, forked from multiprocessing's fork server
    (:mod:`tests._script_child`): the server imports the libraries the scripts share once per
    test process; each script runs in a child forked from it, as ``__main__`` with its own argv,
    working directory and file descriptors 1 and 2. A fresh interpreter per script paid 1–3 s of
    imports (py-spy over the suite: 24 CPU-s of the module's 45 s). Not forked from the test
    worker itself: a child of a worker that had used APyTypes' thread pool hung in it. Processes
    a script starts itself (a pool, a cold run) are fresh interpreters as before."""

    def __init__(self, script: Path, folder: Path) -> None:
        self.script = script
        self._out, self._err = folder / f"{script.stem}.out", folder / f"{script.stem}.err"
        self._proc = _server().Process(target=_script_child.run_script, args=(
            str(script), ["--quick"], str(ROOT), str(self._out), str(self._err)))
        self._proc.start()

    def result(self) -> subprocess.CompletedProcess:
        """Wait for the script (killed after :data:`TIMEOUT_S`) and return what it printed."""
        self._proc.join(TIMEOUT_S)
        if self._proc.is_alive():
            self._proc.kill()
            self._proc.join()
        out = [p.read_text("utf-8", "replace") if p.exists() else "" for p in (self._out,
                                                                               self._err)]
        return subprocess.CompletedProcess([self.script.name, "--quick"], self._proc.exitcode,
                                           *out)


def _server():
    """multiprocessing's fork-server context, its server preloading the scripts' imports (started
    with this process's environment: the scripts' children see ``PYTHONPATH`` and ``MPLBACKEND``
    as before)."""
    os.environ.update(PYTHONPATH=str(ROOT), MPLBACKEND="Agg")
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload(["tests._script_child", *_script_child.PRELOAD])
    return ctx


class _Started:
    """Scripts started on demand: :meth:`result` starts a script (if not yet) and, in a serial
    session, the next selected one too, so that two run at a time. Under xdist a worker cannot
    know which test it gets next: it starts only its own test's script (each script runs once in
    the session, not once per worker)."""

    def __init__(self, order: list[str], prefetch: bool, folder: Path) -> None:
        self._order, self._prefetch, self._folder = order, prefetch, folder
        self._children: dict[str, _Forked] = {}
        self._done: dict[str, subprocess.CompletedProcess] = {}

    def _start(self, name: str) -> None:
        if name not in self._children:
            self._children[name] = _Forked(ROOT / "benchmarks" / name, self._folder)

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
def started(request, tmp_path_factory):
    """The scripts, started as the tests ask for them (:class:`_Started`)."""
    order = [item.callspec.params["script"].name for item in request.session.items
             if item.module is request.module and hasattr(item, "callspec")
             and not _needs_missing_tools(item.callspec.params["script"])]
    runner = _Started(order, prefetch="PYTEST_XDIST_WORKER" not in os.environ,
                      folder=tmp_path_factory.mktemp("benchmarks"))
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


def test_a_forked_script_reports_what_python_script_would(tmp_path):
    """The runner itself: a script's argv, output (its own and its children's), exit code, a
    ``sys.exit`` message and an uncaught exception's traceback come back as from a subprocess."""
    script = tmp_path / "s.py"
    script.write_text(
        "import subprocess, sys\n"
        "print('argv', sys.argv[1:], flush=True)\n"
        "subprocess.run([sys.executable, '-c', 'print(\"child\")'])\n"
        "if sys.argv[1] == '--quick':\n"
        "    raise RuntimeError('boom')\n")
    done = _Forked(script, tmp_path).result()
    assert done.returncode == 1 and done.stdout == "argv ['--quick']\nchild\n"
    assert "RuntimeError: boom" in done.stderr
    script.write_text("import sys\nsys.exit('bad usage')\n")
    done = _Forked(script, tmp_path).result()
    assert done.returncode == 1 and done.stderr == "bad usage\n"
    script.write_text("import sys\nsys.exit(3)\n")
    assert _Forked(script, tmp_path).result().returncode == 3
