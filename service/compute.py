"""The compute pool: CPU-heavy work off the event loop, bounded, shared by identical requests.

Threads rather than processes: numpy and scipy release the GIL in their
kernels, arrays need no pickling, and one request's peak memory is not copied.
The pool admits ``workers + max_pending`` computations; beyond that a request
is shed with 503 and ``Retry-After`` instead of piling up. Identical requests
in flight (same task id) wait for the one computation (single flight).
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any, TypeVar

from service import metrics
from service.problems import Problem

T = TypeVar("T")


class ComputePool:
    def __init__(self, workers: int, max_pending: int) -> None:
        self.workers = workers
        self.capacity = workers + max_pending
        self._executor = ThreadPoolExecutor(workers, thread_name_prefix="zw-compute")
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

    async def run(self, operation: str, fn: Callable[[], T]) -> T:
        """Run ``fn`` in the pool, or shed with 503 when the pool is full.

        A slot is held until the job has really finished (or was dropped from the
        queue), not until the caller stops waiting: a thread cannot be interrupted,
        so a cancelled caller must not free the slot of a computation still running.
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

        try:
            job = self._executor.submit(fn)
        except BaseException:
            self._release()
            raise
        job.add_done_callback(done)
        # Cancelling the wait cancels a job still queued (its callback frees the slot).
        return await asyncio.wrap_future(job)

    async def run_once(self, key: str, operation: str, fn: Callable[[], T]) -> tuple[T, bool]:
        """Like :meth:`run`, but concurrent calls with the same key share one computation.

        Returns the result and whether it was shared with a call already in flight.
        The computation belongs to no single caller: one that is cancelled (its client
        went away) stops waiting, and the others still get the result.
        """
        pending = self._inflight.get(key)
        if pending is not None:
            return await asyncio.shield(pending), True
        task: asyncio.Task[Any] = asyncio.ensure_future(self.run(operation, fn))
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
