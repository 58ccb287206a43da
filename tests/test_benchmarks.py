"""Benchmarks that cannot rot (issue 22, item 4): every script in ``benchmarks/`` runs with
``--quick`` (a small size, the same code path) in a subprocess, exits 0 and prints its figures.

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
import shutil
import subprocess
import sys
from concurrent.futures import Future, ThreadPoolExecutor
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


def _run(script: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "MPLBACKEND": "Agg"}
    return subprocess.run([sys.executable, str(script), "--quick"], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=TIMEOUT_S)


def _needs_missing_tools(script: Path) -> bool:
    return script.name == "bench_rtl.py" and not (shutil.which("verilator")
                                                  and shutil.which("iverilog"))


class _Started:
    """Scripts started on demand: :meth:`result` starts a script (if not yet) and, in a serial
    session, the next selected one too, so that two run at a time. Under xdist a worker cannot
    know which test it gets next: it starts only its own test's script (each script runs once in
    the session, not once per worker)."""

    def __init__(self, order: list[str], prefetch: bool) -> None:
        self._pool = ThreadPoolExecutor(max_workers=2 if prefetch else 1)
        self._order, self._prefetch = order, prefetch
        self._futures: dict[str, Future] = {}

    def _start(self, name: str) -> Future:
        if name not in self._futures:
            self._futures[name] = self._pool.submit(_run, ROOT / "benchmarks" / name)
        return self._futures[name]

    def result(self, name: str) -> subprocess.CompletedProcess:
        future = self._start(name)
        if self._prefetch and name in self._order:
            later = self._order[self._order.index(name) + 1:]
            if later:
                self._start(later[0])
        return future.result()

    def close(self) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)


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
