"""The compute pool: CPU-heavy work off the event loop, bounded, shared by identical requests.

Threads for array work: numpy and scipy release the GIL in their kernels,
arrays need no pickling, and one request's peak memory is not copied.
Processes for work that is mostly Python bytecode (arc fitting): in a thread it
would hold the GIL, serialising such requests and stalling the event loop and
the numpy threads; in a worker process it runs on its own core. The pool admits
``workers + max_pending`` computations of either kind; beyond that a request is
shed with 503 and ``Retry-After`` instead of piling up. Identical requests in
flight (same task id) wait for the one computation (single flight).
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import multiprocessing
import os
import threading
import time
from collections.abc import Callable
from concurrent.futures import Executor, ProcessPoolExecutor, ThreadPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any, TypeVar

from service import metrics
from service.problems import Problem

T = TypeVar("T")


#: How often a worker process checks that the server that started it is still there.
PARENT_POLL_SECONDS = 0.5


def _server_alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            # a zombie is gone for our purpose: it will never send work again
            return f.read().rsplit(b")", 1)[1].split()[0] != b"Z"
    except FileNotFoundError:
        return False
    except OSError:  # pragma: no cover - no /proc: ask the kernel
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        return True


def _watch_server(pid: int) -> None:
    """Worker initializer: exit when the server process is gone.

    A worker blocks on its job queue, which never reaches end-of-file (the worker
    holds both ends), so a server killed hard (SIGKILL, the OOM killer, a test
    harness's timeout) would leave its workers, and their open output pipes, behind
    for ever.
    """
    def watch() -> None:
        while _server_alive(pid):
            time.sleep(PARENT_POLL_SECONDS)
        os._exit(0)

    threading.Thread(target=watch, name="zw-watch-server", daemon=True).start()


def _process_context() -> multiprocessing.context.BaseContext:
    # forkserver, not fork: the server process has threads (forking them is unsafe);
    # its preloaded core makes each worker start in milliseconds, not seconds
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload(["zwcore", "orjson"])
    return ctx


class ComputePool:
    """Threads (``workers``) and, for Python-bound work, worker processes (``processes``;
    0 runs that work in the threads too), started on first use."""

    def __init__(self, workers: int, max_pending: int, processes: int = 0) -> None:
        self.workers = workers
        self.processes = processes
        self.capacity = workers + max_pending
        self._executor = ThreadPoolExecutor(workers, thread_name_prefix="zw-compute")
        self._process_executor: ProcessPoolExecutor | None = None
        self._busy = 0
        self._lock = threading.Lock()
        self._inflight: dict[str, asyncio.Task[Any]] = {}
        metrics.POOL_CAPACITY.set(self.capacity)

    @property
    def busy(self) -> int:
        return self._busy

    def _release(self) -> None:
        with self._lock:
            self._busy -= 1
            metrics.POOL_BUSY.set(self._busy)

    def _executor_for(self, in_process: bool) -> Executor:
        if not (in_process and self.processes):
            return self._executor
        with self._lock:
            if self._process_executor is None:
                self._process_executor = ProcessPoolExecutor(
                    self.processes, mp_context=_process_context(),
                    initializer=_watch_server, initargs=(os.getpid(),))
            return self._process_executor

    def _drop_broken(self, executor: Executor) -> None:
        with self._lock:
            if self._process_executor is executor:
                self._process_executor = None
        _stop_processes(executor)

    async def run(self, operation: str, fn: Callable[..., T], *args: Any,
                  in_process: bool = False) -> T:
        """Run ``fn(*args)`` in the pool, or shed with 503 when the pool is full.

        With ``in_process`` (and processes configured) it runs in a worker process:
        ``fn`` and ``args`` must then pickle (a module-level function, plain data).
        A slot is held until the job has really finished (or was dropped from the
        queue), not until the caller stops waiting: a thread cannot be interrupted,
        so a cancelled caller must not free the slot of a computation still running.
        A worker process that dies (killed for memory, say) costs its jobs a 503;
        the next job starts fresh workers.
        """
        with self._lock:
            if self._busy >= self.capacity:
                metrics.POOL_SHED.inc()
                raise Problem(503, "Busy", "All compute workers are busy; retry shortly.",
                              kind="busy", headers={"Retry-After": "1"})
            self._busy += 1
            metrics.POOL_BUSY.set(self._busy)
        start = time.perf_counter()

        def done(_: concurrent.futures.Future[T]) -> None:
            metrics.COMPUTE_SECONDS.labels(operation).observe(time.perf_counter() - start)
            self._release()

        executor = self._executor_for(in_process)
        try:
            job = executor.submit(fn, *args)
        except BrokenProcessPool:
            self._release()
            self._drop_broken(executor)
            raise _worker_lost() from None
        except BaseException:
            self._release()
            raise
        job.add_done_callback(done)
        try:
            # Cancelling the wait cancels a job still queued (its callback frees the slot).
            return await asyncio.wrap_future(job)
        except BrokenProcessPool:
            self._drop_broken(executor)
            raise _worker_lost() from None

    async def run_once(self, key: str, operation: str, fn: Callable[..., T], *args: Any,
                       in_process: bool = False) -> tuple[T, bool]:
        """Like :meth:`run`, but concurrent calls with the same key share one computation.

        Returns the result and whether it was shared with a call already in flight.
        The computation belongs to no single caller: one that is cancelled (its client
        went away) stops waiting, and the others still get the result.
        """
        pending = self._inflight.get(key)
        if pending is not None:
            return await asyncio.shield(pending), True
        task: asyncio.Task[Any] = asyncio.ensure_future(
            self.run(operation, fn, *args, in_process=in_process))
        self._inflight[key] = task

        def forget(t: asyncio.Task[Any]) -> None:
            if self._inflight.get(key) is t:
                del self._inflight[key]
            if not t.cancelled():
                t.exception()  # retrieved: whoever awaits it re-raises; nobody may be left

        task.add_done_callback(forget)
        return await asyncio.shield(task), False

    def shutdown(self) -> None:
        self._executor.shutdown(wait=False, cancel_futures=True)
        if self._process_executor is not None:
            _stop_processes(self._process_executor)


def _stop_processes(executor: Executor) -> None:
    """Shut a process pool down now: queued jobs are cancelled and running ones
    terminated (their callers are gone or get a 503), so a server stopping with a
    long fit in flight neither waits for it nor leaves the worker behind."""
    # ProcessPoolExecutor has no public way to stop running jobs before Python 3.14
    # (terminate_workers); its worker table is the documented-by-source way in.
    workers = dict(getattr(executor, "_processes", None) or {})
    executor.shutdown(wait=False, cancel_futures=True)
    for proc in workers.values():
        if proc.is_alive():
            proc.terminate()


def _worker_lost() -> Problem:
    return Problem(503, "Worker lost", "A compute worker process stopped; retry shortly.",
                   kind="busy", headers={"Retry-After": "1"})
