"""Where rows run: in this process, a local process pool (default), or a Dask cluster.

Every executor takes a list of :class:`~chiptwin.study.rows.RowTask` and yields finished rows as
they complete, in any order; a row's numbers depend only on its task, so the three give the same
table. The pool uses ``spawn`` (numba and forked threads do not mix) and stays up across the
batches of a bisect search; Dask runs on an existing cluster (``--scheduler tcp://host:8786``) or
a ``distributed.LocalCluster`` it starts (``--scheduler local``).
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from typing import Any

from chiptwin.config import ScenarioError
from chiptwin.study.rows import RowTask, run_row

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


class PoolExecutor:
    """A local process pool of ``workers`` processes.

    At most ``2 × workers`` rows are in flight, so an interrupted study loses at most those, and
    rows of one point run back to back on the processes that already prepared it.
    """

    name = "pool"

    def __init__(self, workers: int) -> None:
        self.workers = workers
        self.pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"))

    def run(self, tasks: Iterable[RowTask]) -> Iterator[dict[str, Any]]:
        pending = iter(tasks)
        running = set()
        try:
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
        finally:
            for future in running:
                future.cancel()

    def close(self) -> None:
        self.pool.shutdown(wait=True, cancel_futures=True)


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

    def run(self, tasks: Iterable[RowTask]) -> Iterator[dict[str, Any]]:
        from distributed import as_completed

        futures = [self.client.submit(run_row, t, pure=False) for t in tasks]
        try:
            for future in as_completed(futures):
                yield future.result()
        finally:
            self.client.cancel([f for f in futures if not f.done()])

    def close(self) -> None:
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()


def make_executor(workers: int | None = None, scheduler: str | None = None):
    """The executor for ``--workers N`` (default: every core) and ``--scheduler ADDRESS``."""
    n = workers or os.cpu_count() or 1
    if scheduler:
        return DaskExecutor(scheduler, n)
    return SerialExecutor() if n == 1 else PoolExecutor(n)
