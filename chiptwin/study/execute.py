"""Where rows run: in this process, a local process pool (default), or a Dask cluster.

Every executor takes a list of :class:`~chiptwin.study.rows.RowTask` and yields finished rows as
they complete, in any order; a row's numbers depend only on its task, so the three give the same
table. The pool uses ``spawn`` (numba and forked threads do not mix) and stays up across the
batches of a bisect search; Dask runs on an existing cluster (``--scheduler tcp://host:8786``) or
a ``distributed.LocalCluster`` it starts (``--scheduler local``).

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
from collections.abc import Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from typing import Any

from chiptwin.config import ScenarioError
from chiptwin.study.rows import RowTask, run_row

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


class SerialExecutor:
    """Rows one after another in this process (``--workers 1``)."""

    name = "serial"
    workers = 1

    def run(self, tasks: Iterable[RowTask]) -> Iterator[dict[str, Any]]:
        for task in tasks:
            yield run_row(task)

    def close(self) -> None:
        pass

    def abort(self) -> None:
        pass


class PoolExecutor:
    """A local process pool of ``workers`` processes.

    At most ``2 × workers`` rows are in flight, so an interrupted study loses at most those, and
    rows of one point run back to back on the processes that already prepared it.
    """

    name = "pool"

    def __init__(self, workers: int) -> None:
        self.workers = workers
        self.pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"),
                                        initializer=die_with_parent, initargs=(os.getpid(),))

    def run(self, tasks: Iterable[RowTask]) -> Iterator[dict[str, Any]]:
        # Rows still in flight when this stops are cancelled by close() and abort(), through
        # shutdown(cancel_futures=True) in the pool's manager thread. Cancelled from this thread,
        # a queued row raced the manager marking it broken once abort() had terminated the
        # workers (InvalidStateError in Python 3.11's terminate_broken: a traceback after
        # "terminated (SIGTERM)", about one stop in 35).
        pending = iter(tasks)
        running = set()
        while True:
            while len(running) < 2 * self.workers:
                task = next(pending, None)
                if task is None:
                    break
                running.add(self.pool.submit(run_row, task))
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
    """Rows on a Dask distributed cluster: an existing scheduler's address, or ``"local"``."""

    name = "dask"

    def __init__(self, address: str, workers: int) -> None:
        try:
            from distributed import Client, LocalCluster
        except ImportError:
            raise ScenarioError("chiptwin", "--scheduler", address, DASK_HINT) from None
        self.cluster = None
        if address == "local":
            self.cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                        dashboard_address=None)
            self.client = Client(self.cluster)
        else:
            try:
                self.client = Client(address, timeout="10s")
            except OSError as exc:
                raise ScenarioError("chiptwin", "--scheduler", address,
                                    f"no Dask scheduler answers there ({exc})") from None
        self.workers = len(self.client.scheduler_info()["workers"]) or workers
        self.futures: list = []

    def run(self, tasks: Iterable[RowTask]) -> Iterator[dict[str, Any]]:
        from distributed import as_completed

        futures = [self.client.submit(run_row, t, pure=False) for t in tasks]
        self.futures = futures
        try:
            for future in as_completed(futures):
                yield future.result()
        finally:
            self.client.cancel([f for f in futures if not f.done()])

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


def make_executor(workers: int | None = None, scheduler: str | None = None):
    """The executor for ``--workers N`` (default: every core) and ``--scheduler ADDRESS``."""
    n = workers or os.cpu_count() or 1
    if scheduler:
        return DaskExecutor(scheduler, n)
    return SerialExecutor() if n == 1 else PoolExecutor(n)
