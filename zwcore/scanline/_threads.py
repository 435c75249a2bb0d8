"""The plan's second thread: independent pieces of work run side by side.

The scan-line plan's heavy kernels are numba functions compiled ``nogil=True`` (the
line sweeps of :mod:`zwcore.scanline._stock_sweep`, the per-position kernels of
:mod:`zwcore.scanline._stock_kernels`, the nodal closings of :mod:`zwcore.sim`), so two
Python threads running them use two cores. :func:`both` runs two callables, one on a
helper thread and one on the caller's; the callers split work so that the two halves
give, together, exactly what the whole gives (disjoint outputs: positions, node rows),
so a plan is the same bit for bit with one thread or two (tests).

One helper thread per process (the machine this serves has two cores; the pyramid of
:mod:`zwcore.mrr._pyramid` keeps its own for the same reason). A call made *from* the
helper thread runs both callables on it in turn (no nested hand-off, no deadlock), and so
does every call while :data:`WORKERS` is 1 (the bench's one-thread figures, the tests'
reference). Callers ask :func:`split` before splitting their work: where the halves would
run in turn a split only adds its own cost (a band's halo, set-up done twice, a
speculative second candidate), so there the work runs whole, as on one thread.
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from typing import TypeVar

import numpy as np
from numpy.typing import NDArray

__all__ = ["WORKERS", "both", "cores", "each", "overlap_seconds", "split", "split_at_weight"]

T = TypeVar("T")
U = TypeVar("U")
V = TypeVar("V")


def cores() -> int:
    """Cores this process may run on (its affinity mask: a container or ``taskset`` may
    allow fewer than the machine has, and a second thread on one core only adds work)."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1  # pragma: no cover (no affinity mask on this platform)


#: Threads the plan uses: 2 where the process may run on two cores or more, else 1. The
#: bench and the tests set it to 1 for the one-thread reference.
WORKERS = 2 if cores() >= 2 else 1

_pool: ThreadPoolExecutor | None = None
_pool_lock = threading.Lock()
_local = threading.local()


def _executor() -> ThreadPoolExecutor:
    global _pool
    with _pool_lock:
        if _pool is None:
            _pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="zw-scanline",
                                       initializer=_mark_helper)
        return _pool


def _mark_helper() -> None:
    _local.helper = True


def _forget_pool() -> None:
    # a forked child inherits the pool object but not its thread: start afresh
    global _pool, _pool_lock
    _pool, _pool_lock = None, threading.Lock()


os.register_at_fork(after_in_child=_forget_pool)


def split() -> bool:
    """Whether a caller here should split its work in two for :func:`both`: two workers,
    and not on the helper thread (there :func:`both` runs the halves in turn, and a split
    only adds its own cost: a band's halo, a second pass over shared set-up)."""
    return WORKERS >= 2 and not getattr(_local, "helper", False)


def both(first: Callable[[], T], second: Callable[[], U]) -> tuple[T, U]:
    """``(first(), second())``, ``first`` on the helper thread while ``second`` runs here
    (in turn when :data:`WORKERS` is 1 or when called from the helper thread). The
    first error of either is raised, after both have ended."""
    if not split():
        return first(), second()
    spent = [0.0, 0.0]

    def timed(n: int, task: Callable[[], V]) -> V:
        t = time.thread_time()
        try:
            return task()
        finally:
            spent[n] = time.thread_time() - t

    fut: Future[T] = _executor().submit(timed, 0, first)
    try:
        b = timed(1, second)
    finally:
        a = fut.result()  # waits even when ``second`` raised (its buffers are shared)
        with _pool_lock:
            _overlap[0] += min(spent)
    return a, b


#: CPU seconds the two threads of :func:`both` ran side by side, summed over the calls
#: (the lesser of the two threads' CPU per call): the wall time the second core saves
#: on an idle machine (:func:`overlap_seconds`).
_overlap = [0.0]


def overlap_seconds(reset: bool = False) -> float:
    """CPU seconds run on the second thread alongside the first so far (the wall time the
    threads save on an otherwise idle machine, up to the hand-offs); ``reset``: start
    again from 0."""
    with _pool_lock:
        got = _overlap[0]
        if reset:
            _overlap[0] = 0.0
    return got


def each(tasks: Sequence[Callable[[], T]]) -> list[T]:
    """``[task() for task in tasks]``, the tasks shared by the helper thread and this one,
    each taking the next unclaimed task (so both stay busy when one gets less CPU; give
    the costliest first). The first error is raised, after both have ended."""
    out: list[T | None] = [None] * len(tasks)
    lock = threading.Lock()
    todo = iter(range(len(tasks)))

    def drain() -> None:
        while True:
            with lock:
                n = next(todo, None)
            if n is None:
                return
            out[n] = tasks[n]()

    if len(tasks) < 2:
        drain()
    else:
        both(drain, drain)
    return out  # type: ignore[return-value]


def split_at_weight(weights: NDArray[np.floating]) -> int:
    """The index ``m`` (``0 < m < n`` when ``n >= 2``) that splits ``weights`` ``(n,)``
    into two runs of about equal sums, ``[0, m)`` and ``[m, n)``."""
    n = weights.size
    if n < 2:
        return n
    cum = np.cumsum(weights, dtype=np.float64)
    m = int(np.searchsorted(cum, 0.5 * cum[-1])) + 1
    return min(max(m, 1), n - 1)
