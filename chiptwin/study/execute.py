"""Where rows run: in this process, a local process pool (default), or a Dask cluster.

Every executor takes tasks, each a list of :class:`~chiptwin.study.rows.RowTask` (consecutive
rows, a point's replicates together: :func:`batches`), and yields each task's finished rows as the
task completes, in any order (a calibration sends its candidates the same way, with its own task
function: ``run(tasks, fn)``); a row's numbers depend only on its row task, so the three give the
same table, however rows are batched. At most ``in_flight`` tasks are out at once (default
:data:`IN_FLIGHT_PER_WORKER` per worker), so the client's memory does not grow with the study's
rows and an interrupted study loses at most those tasks. The pool uses ``spawn`` (numba and
forked threads do not mix) and stays up across the batches of a bisect search; Dask runs on an
existing cluster (``--scheduler tcp://host:8786``, or ``--scheduler-file PATH`` as written by a
scheduler on an HPC cluster) or a ``distributed.LocalCluster`` it starts (``--scheduler local``).

Workers never outlive the study: a pool worker asks Linux to send it SIGKILL when its
parent dies (``prctl(PR_SET_PDEATHSIG)``) and, as a fallback on any platform, watches its parent's
pid from a thread; an interrupted study (Ctrl-C, SIGTERM) terminates its workers at once rather
than waiting for the rows in flight. A Dask client cancels its futures when interrupted; a client
killed outright is dropped by the scheduler, which then forgets the futures only it wanted.
"""

from __future__ import annotations

import ctypes
import multiprocessing
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from typing import Any

from chiptwin.config import ScenarioError
from chiptwin.config.cost import (
    IN_FLIGHT_PER_WORKER,
    MAX_ROWS_PER_TASK,
    MAX_WORKER_TIMEOUT_S,
    TASK_TARGET_S,
    WORKER_TIMEOUT_S,
)
from chiptwin.study.rows import RowTask, run_rows

#: What a task runs: a module-level function (picklable) of the task's items, returning one
#: record per item: :func:`~chiptwin.study.rows.run_rows` (a budget study's rows, the default) or
#: :func:`~chiptwin.study.calibrate_eval.run_evaluations` (a calibration's candidates).
TaskFunction = Callable[[list[Any]], list[dict[str, Any]]]
#: Seconds between two looks of a worker's watchdog at its parent's pid.
WATCHDOG_PERIOD_S = 0.5
_PR_SET_PDEATHSIG = 1  # <linux/prctl.h>


def die_with_parent(parent_pid: int) -> None:
    """Make this process exit when ``parent_pid`` (its parent) dies, however it dies.

    Linux: the kernel sends SIGKILL at the parent's death (``prctl(PR_SET_PDEATHSIG)``).
    Everywhere: a daemon thread checks every :data:`WATCHDOG_PERIOD_S` that the parent is still
    this process's parent (an orphan is re-parented, so its ``getppid`` changes) and exits if not.
    The pool's initializer; the parent may already be gone when it runs, which both notice.
    """
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
        except (OSError, AttributeError):
            pass  # the watchdog below still holds
    if os.getppid() != parent_pid:
        os._exit(1)

    def watch() -> None:
        while os.getppid() == parent_pid:
            time.sleep(WATCHDOG_PERIOD_S)
        os._exit(1)

    threading.Thread(target=watch, name="chiptwin-parent-watchdog", daemon=True).start()


DASK_HINT = 'needs the optional extra: pip install "chiptwin[dask]" (Dask distributed)'


def rows_per_task(row_s: float, rows: int, workers: int) -> int:
    """Rows a task holds: :data:`TASK_TARGET_S` of ``row_s``-second rows, but no fewer tasks
    than :data:`IN_FLIGHT_PER_WORKER` per worker (a small study still spreads over every
    worker), between 1 and :data:`MAX_ROWS_PER_TASK`."""
    by_time = int(TASK_TARGET_S / row_s) if row_s > 0 else MAX_ROWS_PER_TASK
    spread = -(-rows // (IN_FLIGHT_PER_WORKER * max(workers, 1)))
    return max(1, min(by_time, spread, MAX_ROWS_PER_TASK))


def batches(tasks: Iterable[RowTask], size: int) -> Iterator[list[RowTask]]:
    """Consecutive row tasks, ``size`` at a time (the last may hold fewer)."""
    batch: list[RowTask] = []
    for task in tasks:
        batch.append(task)
        if len(batch) == size:
            yield batch
            batch = []
    if batch:
        yield batch


class SerialExecutor:
    """Rows one after another in this process (``--workers 1``)."""

    name = "serial"
    workers = 1

    def run(self, tasks: Iterable[list[Any]], fn: TaskFunction = run_rows
            ) -> Iterator[list[dict[str, Any]]]:
        for task in tasks:
            yield fn(task)

    def close(self) -> None:
        pass

    def abort(self) -> None:
        pass


class PoolExecutor:
    """A local process pool of ``workers`` processes, ``in_flight`` tasks out at most (default
    :data:`IN_FLIGHT_PER_WORKER` × workers)."""

    name = "pool"

    def __init__(self, workers: int, in_flight: int | None = None) -> None:
        self.workers = workers
        self.in_flight = in_flight or IN_FLIGHT_PER_WORKER * workers
        self.pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"),
                                        initializer=die_with_parent, initargs=(os.getpid(),))

    def run(self, tasks: Iterable[list[Any]], fn: TaskFunction = run_rows
            ) -> Iterator[list[dict[str, Any]]]:
        # Tasks still in flight when this stops are cancelled by close() and abort(), through
        # shutdown(cancel_futures=True) in the pool's manager thread. Cancelled from this thread,
        # a queued task raced the manager marking it broken once abort() had terminated the
        # workers (InvalidStateError in Python 3.11's terminate_broken: a traceback after
        # "terminated (SIGTERM)", about one stop in 35).
        pending = iter(tasks)
        running = set()
        while True:
            while len(running) < self.in_flight:
                task = next(pending, None)
                if task is None:
                    break
                running.add(self.pool.submit(fn, task))
            if not running:
                return
            done, running = wait(running, return_when=FIRST_COMPLETED)
            for future in done:
                yield future.result()

    def close(self) -> None:
        self.pool.shutdown(wait=True, cancel_futures=True)

    def abort(self) -> None:
        """Stop now (the study was interrupted): the rows in flight are lost, never waited for."""
        processes = list((getattr(self.pool, "_processes", None) or {}).values())
        for proc in processes:
            proc.terminate()
        for proc in processes:
            proc.join(timeout=5)
            if proc.is_alive():
                proc.kill()
        manager = getattr(self.pool, "_executor_manager_thread", None)
        self.pool.shutdown(wait=False, cancel_futures=True)
        if manager is not None:
            # the manager thread closes its wake-up pipe as it ends; joined here, it is gone
            # before the interpreter's exit hook writes to that pipe (Python 3.11: an OSError
            # traceback after "terminated (SIGTERM)", about one stop in 70)
            manager.join(timeout=5)


class DaskExecutor:
    """Rows on a Dask distributed cluster: an existing scheduler's address, ``"local"``, or
    the scheduler a ``scheduler_file`` names (Dask's convention on HPC clusters)."""

    name = "dask"

    def __init__(self, address: str | None, workers: int, in_flight: int | None = None,
                 scheduler_file: str | None = None,
                 worker_timeout_s: float = WORKER_TIMEOUT_S) -> None:
        flag, given = ("--scheduler-file", scheduler_file) if scheduler_file else \
            ("--scheduler", address)
        try:
            from distributed import Client, LocalCluster
        except ImportError:
            raise ScenarioError("chiptwin", flag, given, DASK_HINT) from None
        self.cluster = None
        if address == "local":
            self.cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                        dashboard_address=None)
            self.client = Client(self.cluster)
        else:
            target = scheduler_address(scheduler_file) if scheduler_file else address
            try:
                self.client = Client(target, timeout="10s")
            except OSError as exc:
                raise ScenarioError("chiptwin", flag, given,
                                    f"no Dask scheduler answers at {target} ({exc})") from None
        try:
            self.client.wait_for_workers(1, timeout=worker_timeout_s)
        except TimeoutError:
            self.close()
            raise ScenarioError("chiptwin", "--worker-timeout", worker_timeout_s,
                                f"no Dask worker joined the scheduler at {given} within "
                                f"{worker_timeout_s:g} s; start workers, or allow longer: in "
                                f"(0, {MAX_WORKER_TIMEOUT_S:g}] s") from None
        self.workers = len(self.client.scheduler_info()["workers"]) or workers
        self.in_flight = in_flight or IN_FLIGHT_PER_WORKER * self.workers
        self.futures: set = set()

    def run(self, tasks: Iterable[list[Any]], fn: TaskFunction = run_rows
            ) -> Iterator[list[dict[str, Any]]]:
        from distributed import as_completed

        pending = iter(tasks)
        running = as_completed()
        try:
            while True:
                while len(self.futures) < self.in_flight:
                    task = next(pending, None)
                    if task is None:
                        break
                    future = self.client.submit(fn, task, pure=False)
                    self.futures.add(future)
                    running.add(future)
                if not self.futures:
                    return
                future = next(running)
                self.futures.discard(future)
                yield future.result()
        finally:
            self.client.cancel([f for f in self.futures if not f.done()])
            self.futures = set()

    def close(self) -> None:
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()

    def abort(self) -> None:
        """Interrupted: cancel every future of this client, then close (the LocalCluster's
        workers with it)."""
        try:
            self.client.cancel([f for f in self.futures if not f.done()], force=True)
        finally:
            self.close()


def scheduler_address(path: str) -> str:
    """The address a Dask scheduler file names (the JSON ``dask scheduler --scheduler-file``
    and ``Client.write_scheduler_file`` write); a missing or unreadable file is refused naming
    ``--scheduler-file``."""
    import json
    from pathlib import Path

    try:
        info = json.loads(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ScenarioError("chiptwin", "--scheduler-file", path,
                            "no such file: a scheduler file is written by `dask scheduler "
                            "--scheduler-file PATH` (or Client.write_scheduler_file) once the "
                            "scheduler is up") from None
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise ScenarioError("chiptwin", "--scheduler-file", path,
                            f'not a Dask scheduler file (JSON with an "address"): {exc}'
                            ) from None
    address = info.get("address") if isinstance(info, dict) else None
    if not isinstance(address, str) or not address:
        raise ScenarioError("chiptwin", "--scheduler-file", path,
                            'names no scheduler: a Dask scheduler file is JSON with an "address" '
                            '(e.g. "tcp://10.0.0.5:8786")')
    return address


def make_executor(workers: int | None = None, scheduler: str | None = None,
                  in_flight: int | None = None, scheduler_file: str | None = None,
                  worker_timeout_s: float = WORKER_TIMEOUT_S):
    """The executor for ``--workers N`` (default: every core), ``--scheduler ADDRESS`` or
    ``--scheduler-file PATH``, ``--in-flight N`` and ``--worker-timeout S``."""
    n = workers or os.cpu_count() or 1
    if scheduler or scheduler_file:
        return DaskExecutor(scheduler, n, in_flight, scheduler_file, worker_timeout_s)
    return SerialExecutor() if n == 1 else PoolExecutor(n, in_flight)
