"""Where the batches run: ``local`` (worker processes on this machine, concurrent.futures) or ``dask``
(Dask ``distributed``: a LocalCluster, or a running cluster at a scheduler address).

Both hand each worker the Job once and then batches, and give back ``(batch, rows or exception)`` as
batches finish. Dask does the scheduling, data transfer and worker management; nothing here is a
scheduler or a protocol of its own. On a Dask cluster the ``linuxcnc`` host resource is given to one
worker per host (unless a worker there already declares it), and runs that need it ask for it, so
LinuxCNC instances never meet on a host.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import logging
import multiprocessing
import os
import signal
import threading
import uuid
from collections.abc import Iterator
from typing import Any

from flowmc.errors import FlowmcError
from flowmc.sweep.variants import Variant
from flowmc.sweep.worker import Job, run_batch, warm_up

__all__ = ["EXECUTORS", "LocalExecutor", "DaskExecutor", "open_executor"]

EXECUTORS = ("local", "dask")
Finished = tuple[list[Variant], "list[dict[str, Any]] | BaseException"]


def default_workers() -> int:
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1))


# ---------------------------------------------------------------- local processes

_process_job: Job | None = None
_START_TIMEOUT = 120.0
_MATH_THREADS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


@contextlib.contextmanager
def _one_math_thread_each() -> Iterator[None]:
    """Worker processes started meanwhile use one BLAS/OpenMP thread each, as Dask's workers do: the
    processes are the parallelism, and more threads per process only fight over the cores."""
    added = {k: "1" for k in _MATH_THREADS if k not in os.environ}
    os.environ.update(added)
    try:
        yield
    finally:
        for key in added:
            os.environ.pop(key, None)


def _init_process(job: Job, ready: Any) -> None:
    """In each worker process: keep the job, load the node types, then wait at ``ready`` until every
    worker has; Ctrl-C is left to the parent, which stops the sweep cleanly."""
    global _process_job
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _process_job = job
    warm_up(job.node_folders)
    ready.wait(_START_TIMEOUT)


def _started() -> None:
    """A task that returns once its process (and so, past the barrier, every process) has started."""
    return


def _run_local(batch: list[Variant]) -> list[dict[str, Any]]:
    assert _process_job is not None
    return run_batch(_process_job, batch)


class LocalExecutor:
    """``workers`` processes on this machine (spawned fresh: safe from a threaded editor), each with one
    long-lived runtime. A graph that needs LinuxCNC gets one process: its instances would collide."""

    kind = "local"

    def __init__(self, job: Job, workers: int | None = None, resources: tuple[str, ...] = ()):
        self.workers = 1 if "linuxcnc" in resources else (workers or default_workers())
        context = multiprocessing.get_context("spawn")
        self._pool = cf.ProcessPoolExecutor(self.workers, mp_context=context, initializer=_init_process,
                                            initargs=(job, context.Barrier(self.workers)))
        self._pending: dict[cf.Future, list[Variant]] = {}
        try:  # start every worker now (the pool starts one per waiting task): start-up is not a variant's time
            with _one_math_thread_each():
                started = [self._pool.submit(_started) for _ in range(self.workers)]
            for future in started:
                future.result(timeout=_START_TIMEOUT + 30)
        except BaseException as exc:
            self._pool.shutdown(wait=False, cancel_futures=True)
            if isinstance(exc, Exception):
                raise FlowmcError(f"the worker processes did not start: {type(exc).__name__}: {exc}") from None
            raise

    def describe(self) -> str:
        return f"local, {self.workers} process{'es' if self.workers != 1 else ''}"

    def results(self, batches: list[list[Variant]]) -> Iterator[Finished]:
        self._pending = {self._pool.submit(_run_local, b): b for b in batches}
        while self._pending:
            done, _ = cf.wait(list(self._pending), return_when=cf.FIRST_COMPLETED)
            for future in done:
                batch = self._pending.pop(future)
                exc = future.exception()
                yield batch, exc if exc is not None else future.result()

    def close(self) -> None:
        for future in self._pending:
            future.cancel()
        self._pool.shutdown(wait=True, cancel_futures=True)

    def __enter__(self) -> LocalExecutor:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


# ---------------------------------------------------------------- Dask

@contextlib.contextmanager
def _ctrl_c_ignored() -> Iterator[None]:
    """Ignore SIGINT while worker processes start (from the main thread only; elsewhere a no-op)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


async def _grant(resource: str, dask_worker: Any = None) -> None:
    await dask_worker.set_resources(**{resource: 1})


class DaskExecutor:
    """A Dask cluster: ``address`` of a running scheduler, or a LocalCluster of ``workers`` processes with
    one thread each. The Job is scattered to every worker once; batches are tasks."""

    kind = "dask"

    def __init__(self, job: Job, workers: int | None = None, address: str | None = None,
                 resources: tuple[str, ...] = ()):
        try:
            import distributed
        except ImportError as exc:  # pragma: no cover - a dependency of flowmc
            raise FlowmcError(f"the dask executor needs dask[distributed]: {exc}") from None
        self._distributed = distributed
        self.cluster = None
        try:
            if address:
                self.client = distributed.Client(address, timeout="30s")
            else:
                with _ctrl_c_ignored():  # the workers inherit it: Ctrl-C is the parent's to handle
                    self.cluster = distributed.LocalCluster(n_workers=workers or default_workers(),
                                                            threads_per_worker=1, processes=True,
                                                            dashboard_address=None, silence_logs=logging.ERROR)
                self.client = distributed.Client(self.cluster)
        except (OSError, TimeoutError) as exc:
            if self.cluster is not None:
                self.cluster.close()
            raise FlowmcError(f"cannot reach the Dask scheduler: {exc}", where=address or "LocalCluster") from None
        self.address = address
        self._resources = {r: 1 for r in resources}
        self._futures: dict[Any, list[Variant]] = {}
        try:
            info = self.client.scheduler_info(n_workers=-1)["workers"]
            if not info:
                raise FlowmcError("the Dask cluster has no workers", where=address or "LocalCluster")
            self.workers = sum(w.get("nthreads", 1) for w in info.values())
            self.client.run(warm_up, job.node_folders)
            for resource in self._resources:
                self._one_per_host(info, resource)
            self._job = self.client.scatter(job, broadcast=True, hash=False)
        except BaseException:
            self.close()
            raise

    def _one_per_host(self, info: dict[str, Any], resource: str) -> None:
        hosts: dict[str, list[str]] = {}
        holders = set()
        for addr, w in info.items():
            hosts.setdefault(w["host"], []).append(addr)
            if w.get("resources", {}).get(resource):
                holders.add(w["host"])
        chosen = [min(addrs) for host, addrs in hosts.items() if host not in holders]
        if chosen:
            self.client.run(_grant, resource, workers=chosen)

    def describe(self) -> str:
        where = f"scheduler {self.address}" if self.address else "LocalCluster"
        return f"dask, {where}, {self.workers} worker thread{'s' if self.workers != 1 else ''}"

    def results(self, batches: list[list[Variant]]) -> Iterator[Finished]:
        token = uuid.uuid4().hex[:8]
        self._futures = {
            self.client.submit(run_batch, self._job, batch, key=f"flowmc-sweep-{token}-{i}", pure=False,
                               resources=self._resources or None): batch
            for i, batch in enumerate(batches)}
        for future in self._distributed.as_completed(list(self._futures)):
            batch = self._futures.pop(future)
            try:
                yield batch, future.result()
            except Exception as exc:  # noqa: BLE001 - a lost worker (KilledWorker) or a failed task
                yield batch, exc

    def close(self) -> None:
        """Closing the client releases its tasks on the scheduler (those running finish, unseen)."""
        self._futures = {}
        if self.cluster is not None:  # our own cluster: its shutdown chatter (released tasks) is not news
            logging.getLogger("distributed").setLevel(logging.CRITICAL + 1)
        try:
            self.client.close()
        finally:
            if self.cluster is not None:
                self.cluster.close()

    def __enter__(self) -> DaskExecutor:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def open_executor(kind: str, job: Job, *, workers: int | None = None, address: str | None = None,
                  resources: tuple[str, ...] = ()) -> LocalExecutor | DaskExecutor:
    if kind == "local":
        return LocalExecutor(job, workers, resources)
    if kind == "dask":
        return DaskExecutor(job, workers, address, resources)
    raise FlowmcError(f"unknown executor {kind!r}; choose {' or '.join(EXECUTORS)}")
