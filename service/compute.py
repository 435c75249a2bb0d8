"""The compute pool: CPU-heavy work off the event loop, bounded, shared by identical requests.

Threads rather than processes: numpy and scipy release the GIL in their
kernels, arrays need no pickling, and one request's peak memory is not copied.
The pool admits ``workers + max_pending`` computations; beyond that a request
is shed with 503 and ``Retry-After`` instead of piling up. Identical requests
in flight (same task id) wait for the one computation (single flight).
"""

from __future__ import annotations

import asyncio
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
        self._inflight: dict[str, asyncio.Future[Any]] = {}
        metrics.POOL_CAPACITY.set(self.capacity)

    @property
    def busy(self) -> int:
        return self._busy

    async def run(self, operation: str, fn: Callable[[], T]) -> T:
        """Run ``fn`` in the pool, or shed with 503 when the pool is full."""
        if self._busy >= self.capacity:
            metrics.POOL_SHED.inc()
            raise Problem(503, "Busy", "All compute workers are busy; retry shortly.",
                          kind="busy", headers={"Retry-After": "1"})
        self._busy += 1
        metrics.POOL_BUSY.set(self._busy)
        try:
            loop = asyncio.get_running_loop()
            start = time.perf_counter()
            result = await loop.run_in_executor(self._executor, fn)
            metrics.COMPUTE_SECONDS.labels(operation).observe(time.perf_counter() - start)
            return result
        finally:
            self._busy -= 1
            metrics.POOL_BUSY.set(self._busy)

    async def run_once(self, key: str, operation: str, fn: Callable[[], T]) -> tuple[T, bool]:
        """Like :meth:`run`, but concurrent calls with the same key share one computation.

        Returns the result and whether it was shared with a call already in flight.
        """
        pending = self._inflight.get(key)
        if pending is not None:
            return await asyncio.shield(pending), True
        future: asyncio.Future[Any] = asyncio.get_running_loop().create_future()
        self._inflight[key] = future
        try:
            result = await self.run(operation, fn)
        except BaseException as exc:
            future.set_exception(exc)
            future.exception()  # mark retrieved: the caller re-raises it below
            raise
        else:
            future.set_result(result)
            return result, False
        finally:
            del self._inflight[key]

    def shutdown(self) -> None:
        self._executor.shutdown(wait=False, cancel_futures=True)
