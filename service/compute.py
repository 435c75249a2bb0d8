"""The compute pool: CPU-heavy work off the event loop, bounded, shared by identical requests.

Threads for array work: numpy and scipy release the GIL in their kernels,
arrays need no pickling, and one request's peak memory is not copied.
Processes for work that is mostly Python bytecode (arc fitting): in a thread it
would hold the GIL, serialising such requests and stalling the event loop and
the numpy threads; in a worker process it runs on its own core.

Each kind has its own capacity (its workers plus ``max_pending`` queued), so a
flood of slow arc fits never takes the places of grid requests, nor the reverse;
beyond it a request is shed with 503 and ``Retry-After``. Identical requests in
flight (same task id) wait for the one computation (single flight).

Every computation has a deadline (``ZW_COMPUTE_TIMEOUT_SECONDS``, counted from
when it starts running). A worker process past it is terminated and replaced
(pebble's process pool). A thread cannot be killed; a grid computation past its
deadline gets :class:`DeadlineExceeded` raised in it asynchronously
(``PyThreadState_SetAsyncExc``), which takes effect at the next Python bytecode:
the planners are Python loops over levels and row blocks around numpy calls, so
the thread stops within one such call and its slot is freed. (Process isolation
for grid work would copy every grid and model through a pipe; cooperative
checks would need hooks in every core planner.)

Admission by memory: each request states its estimated peak memory; while the
running ones' estimates and it would pass ``ZW_MEMORY_BUDGET_BYTES`` it waits
(up to ``ZW_MEMORY_WAIT_SECONDS``), then is shed with 503. Back to baseline:
glibc arenas are capped at two (mallopt, as ``MALLOC_ARENA_MAX=2``), and
``malloc_trim`` hands the freed heap back after a large computation and again
when the server is quiet.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import ctypes
import multiprocessing
import os
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any, TypeVar

import pebble

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


#: Modules whose functions run in the worker processes (``run(..., in_process=True)``).
PROCESS_JOB_MODULES = ("service.routers.arcs",)


def _process_context() -> multiprocessing.context.BaseContext:
    # forkserver, not fork: the server process has threads (forking them is unsafe);
    # its preloaded core makes each worker start in milliseconds, not seconds (with the
    # arc fit's compiled kernels ready: zwcore.arcs.warmup); the routers' job functions
    # too, or each worker's first job imports the web stack (~0.4 s of a request)
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload(["zwcore", "zwcore.arcs.warmup", "orjson",
                                *PROCESS_JOB_MODULES])
    return ctx


class DeadlineExceeded(Exception):
    """Raised inside a computation thread that ran past its deadline."""


class _ThreadJob:
    """A computation in a thread that the watchdog may stop (see the module docstring)."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.thread_id: int | None = None
        self.running = False
        self.stopped = False

    def run(self, fn: Callable[..., T], args: tuple[Any, ...]) -> T:
        with self.lock:
            if self.stopped:  # the deadline passed while it was queued
                raise DeadlineExceeded
            self.thread_id = threading.get_ident()
            self.running = True
        try:
            return fn(*args)
        finally:
            # From here on no exception may be injected; one injected but not yet
            # raised is withdrawn, so it cannot hit the executor's own code.
            with self.lock:
                self.running = False
                if self.stopped:
                    _set_async_exc(threading.get_ident(), None)

    def stop(self) -> None:
        with self.lock:
            self.stopped = True
            if self.running and self.thread_id is not None:
                _set_async_exc(self.thread_id, DeadlineExceeded)


def _set_async_exc(thread_id: int, exc: type[BaseException] | None) -> None:
    ctypes.pythonapi.PyThreadState_SetAsyncExc(
        ctypes.c_ulong(thread_id), ctypes.py_object(exc) if exc is not None else None)


_LIBC: Any = None
_M_ARENA_MAX = -8  # glibc's mallopt parameter number
#: glibc arenas for the whole process (its default is 8 per core: each thread that
#: allocates may get its own, and each keeps its freed heap).
MALLOC_ARENAS = 2


def _libc() -> Any:
    global _LIBC
    if _LIBC is None:
        _LIBC = ctypes.CDLL("libc.so.6")
    return _LIBC


def malloc_trim() -> None:
    """Return free heap memory to the system (glibc); a no-op elsewhere."""
    try:
        _libc().malloc_trim(0)
    except (OSError, AttributeError):  # pragma: no cover - not glibc
        pass


def limit_malloc_arenas(arenas: int = MALLOC_ARENAS) -> None:
    """``MALLOC_ARENA_MAX`` set from inside (mallopt): arenas created from now on are
    capped, so call it before the compute threads start. An explicit
    ``MALLOC_ARENA_MAX`` in the environment is left to glibc."""
    if "MALLOC_ARENA_MAX" in os.environ:
        return
    try:
        _libc().mallopt(_M_ARENA_MAX, arenas)
    except (OSError, AttributeError):  # pragma: no cover - not glibc
        pass


class MemoryBudget:
    """Estimated peak bytes of the running computations, bounded by ``budget``."""

    def __init__(self, budget: int, wait_seconds: float) -> None:
        self.budget = budget
        self.wait_seconds = wait_seconds
        self.in_use = 0
        self._changed: asyncio.Condition | None = None

    def _condition(self) -> asyncio.Condition:
        if self._changed is None:
            self._changed = asyncio.Condition()
        return self._changed

    async def acquire(self, nbytes: int) -> None:
        """Wait until ``nbytes`` fit in the budget, or raise a 503 problem."""
        if nbytes > self.budget:
            raise Problem(503, "Over the memory budget",
                          f"this request needs about {nbytes / 2**20:.0f} MiB, more than the "
                          f"server's memory budget of {self.budget / 2**20:.0f} MiB",
                          kind="memory", headers={"Retry-After": "60"})
        cond = self._condition()
        async with cond:
            try:
                await asyncio.wait_for(
                    cond.wait_for(lambda: self.in_use + nbytes <= self.budget),
                    self.wait_seconds)
            except TimeoutError:
                metrics.POOL_SHED.inc()
                raise Problem(503, "Busy", "The server's memory budget is taken by running "
                              "requests; retry shortly.", kind="busy",
                              headers={"Retry-After": "2"}) from None
            self.in_use += nbytes

    async def release(self, nbytes: int) -> None:
        cond = self._condition()
        async with cond:
            self.in_use -= nbytes
            cond.notify_all()


#: A computation estimated to need this much is followed by a malloc_trim.
TRIM_AFTER_BYTES = 64 << 20
#: Seconds between the idle trimmer's looks.
TRIM_PERIOD_SECONDS = 1.0
_large_work_ended = 0.0  # monotonic time the last large computation or response ended


def want_trim() -> None:
    """Note that large buffers were just freed (a computation, a streamed response)."""
    global _large_work_ended
    _large_work_ended = time.monotonic()


async def trim_when_idle(pool: ComputePool) -> None:
    """Trim the heap once the server is quiet after large work.

    The trim right after a computation runs while its result and the response
    being rendered are still alive; this one runs when nothing computes any more,
    after those are gone too (a long-running task of the app's lifespan).
    """
    trimmed = 0.0
    while True:
        await asyncio.sleep(TRIM_PERIOD_SECONDS)
        ended = _large_work_ended
        if ended > trimmed and pool.busy == 0 and time.monotonic() - ended >= 0.5:
            trimmed = ended
            await asyncio.to_thread(malloc_trim)


class ComputePool:
    """Threads (``workers``) for grid work and worker processes (``processes``; 0 runs
    that work in the threads too) for Python-bound work, each with its own capacity."""

    def __init__(self, workers: int, max_pending: int, processes: int = 0, *,
                 timeout: float = 120.0, memory_budget: int = 1 << 62,
                 memory_wait: float = 10.0) -> None:
        self.workers = workers
        self.processes = processes
        self.timeout = timeout
        self.capacities = {"thread": workers + max_pending,
                           "process": (processes or workers) + max_pending}
        self.capacity = sum(self.capacities.values())
        self.memory = MemoryBudget(memory_budget, memory_wait)
        limit_malloc_arenas()
        self._executor = ThreadPoolExecutor(workers, thread_name_prefix="zw-compute")
        self._process_pool: pebble.ProcessPool | None = None
        self._busy = {"thread": 0, "process": 0}
        self._lock = threading.Lock()
        self._inflight: dict[str, asyncio.Task[Any]] = {}
        metrics.POOL_CAPACITY.set(self.capacity)

    @property
    def busy(self) -> int:
        return sum(self._busy.values())

    def _admit(self, kind: str) -> None:
        with self._lock:
            if self._busy[kind] >= self.capacities[kind]:
                metrics.POOL_SHED.inc()
                raise Problem(503, "Busy", "All compute workers are busy; retry shortly.",
                              kind="busy", headers={"Retry-After": "1"})
            self._busy[kind] += 1
            metrics.POOL_BUSY.set(self.busy)

    def _release(self, kind: str) -> None:
        with self._lock:
            self._busy[kind] -= 1
            metrics.POOL_BUSY.set(self.busy)

    def _processes(self) -> pebble.ProcessPool:
        with self._lock:
            if self._process_pool is None or not self._process_pool.active:
                self._process_pool = pebble.ProcessPool(
                    self.processes, context=_process_context(),
                    initializer=_watch_server, initargs=(os.getpid(),))
            return self._process_pool

    def start_processes(self) -> list[concurrent.futures.Future[int]]:
        """Start the worker processes now, not on the first Python-bound request.

        A cold start (the forkserver importing the core and loading the arc kernels)
        costs a few seconds of CPU; paid at service start, no client waits for it.
        Returns one no-op job per worker (their pids), nothing to wait for.
        """
        if not self.processes:
            return []
        pool = self._processes()
        return [pool.schedule(os.getpid, timeout=self.timeout) for _ in range(self.processes)]

    def _submit(self, kind: str, fn: Callable[..., T],
                args: tuple[Any, ...]) -> tuple[concurrent.futures.Future[T], Callable[[], None]]:
        """Start the job; returns its future and how to stop it at its deadline."""
        if kind == "process":
            job = self._processes().schedule(fn, args=args, timeout=self.timeout)
            return job, lambda: None  # pebble terminates the worker at the deadline
        thread_job = _ThreadJob()
        future = self._executor.submit(thread_job.run, fn, args)
        return future, thread_job.stop

    async def run(self, operation: str, fn: Callable[..., T], *args: Any,
                  in_process: bool = False, memory: int = 0) -> T:
        """Run ``fn(*args)`` in the pool, or shed with 503 when its kind is full.

        With ``in_process`` (and processes configured) it runs in a worker process:
        ``fn`` and ``args`` must then pickle (a module-level function, plain data).
        ``memory`` is the computation's estimated peak, held against the budget.
        A slot is held until the job has really finished or stopped, not until the
        caller stops waiting. Past the deadline the job is stopped and the caller
        gets a 503 ``timeout`` problem; a worker process that dies costs its job a 503.
        """
        kind = "process" if in_process and self.processes else "thread"
        self._admit(kind)
        try:
            await self.memory.acquire(memory)
        except BaseException:
            self._release(kind)
            raise
        loop = asyncio.get_running_loop()
        start = time.perf_counter()

        def done(_: concurrent.futures.Future[T]) -> None:
            metrics.COMPUTE_SECONDS.labels(operation).observe(time.perf_counter() - start)
            self._release(kind)
            if memory >= TRIM_AFTER_BYTES:
                malloc_trim()
                want_trim()
            with contextlib.suppress(RuntimeError):  # the loop is gone: nobody waits
                loop.call_soon_threadsafe(
                    lambda: asyncio.ensure_future(self.memory.release(memory)))

        try:
            job, stop = self._submit(kind, fn, args)
        except BaseException:
            self._release(kind)
            await self.memory.release(memory)
            raise
        job.add_done_callback(done)
        # Thread jobs: the deadline counts from the start, queueing included (the
        # queue is short: max_pending); pebble counts from when a worker takes it.
        timer = loop.call_later(self.timeout, stop) if kind == "thread" else None
        try:
            return await asyncio.wrap_future(job)
        except (DeadlineExceeded, concurrent.futures.TimeoutError):
            raise _timed_out(self.timeout) from None
        except pebble.ProcessExpired:
            raise _worker_lost() from None
        except asyncio.CancelledError:
            # the caller went away: a queued job is dropped, a running fit stopped
            job.cancel()
            raise
        finally:
            if timer is not None:
                timer.cancel()

    async def run_once(self, key: str, operation: str, fn: Callable[..., T], *args: Any,
                       in_process: bool = False, memory: int = 0) -> tuple[T, bool]:
        """Like :meth:`run`, but concurrent calls with the same key share one computation.

        Returns the result and whether it was shared with a call already in flight.
        The computation belongs to no single caller: one that is cancelled (its client
        went away) stops waiting, and the others still get the result.
        """
        pending = self._inflight.get(key)
        if pending is not None:
            return await asyncio.shield(pending), True
        task: asyncio.Task[Any] = asyncio.ensure_future(
            self.run(operation, fn, *args, in_process=in_process, memory=memory))
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
        if self._process_pool is not None:
            # running fits are terminated: a stopping server neither waits for them
            # nor leaves their workers behind
            self._process_pool.stop()
            self._process_pool.join(timeout=10)


def _timed_out(seconds: float) -> Problem:
    return Problem(503, "Compute deadline exceeded",
                   f"the computation ran past the deadline of {seconds:g} s "
                   "(ZW_COMPUTE_TIMEOUT_SECONDS) and was stopped; ask for less work (a "
                   "coarser grid or a larger tolerance)", kind="timeout")


def _worker_lost() -> Problem:
    return Problem(503, "Worker lost", "A compute worker process stopped; retry shortly.",
                   kind="busy", headers={"Retry-After": "1"})
