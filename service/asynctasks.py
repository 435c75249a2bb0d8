"""Asynchronous tasks (``Prefer: respond-async``): state documents in the task store.

A task's state (pending, running, done, failed, a progress fraction, the problem
when it failed) is a small JSON document in the same store as results, under the
same content hash: the embedded store for one process, Redis with replicas, so any
replica answers for any task. The computation itself runs in the replica that
accepted the request, in its compute pool (the same single flight as synchronous
calls: a synchronous twin shares it). A replica that dies mid-task leaves a state
that is never finished; readers report such a task failed once it is older than
any computation may be (deadline plus memory wait plus a margin).

Work is not queued across replicas: each replica sheds (503) what it cannot take,
and a load balancer spreads the rest. Should cross-replica queueing be needed, the
engine to put on the compose file's Redis is RQ: a plain Redis list of jobs with
worker processes, no broker beyond the Redis already there, job timeouts that kill
the work horse (our deadline), and job ids we can set to the task id. (Celery
brings a broker abstraction and scheduler this service does not need; Dask
distributed is a cluster scheduler for task graphs, not a job queue.)
"""

from __future__ import annotations

import asyncio
import logging
import time
from typing import Any

import anyio
import orjson

from service.problems import PROBLEM_BASE, Problem
from service.store import TaskStore
from zwcore.errors import LimitExceededError, PlanningError, ZwError

log = logging.getLogger("zwplan.tasks")

#: Background computations of this process, kept referenced until they finish.
_RUNNING: set[asyncio.Task[Any]] = set()

#: Margin (s) beyond deadline and memory wait after which an unfinished task is lost.
LOST_AFTER_MARGIN = 60.0


def state_doc(tid: str, operation: str, status: str, progress: float, created: float,
              error: dict[str, Any] | None = None) -> dict[str, Any]:
    return {"task_id": tid, "operation": operation, "status": status, "progress": progress,
            "created": created, "updated": round(time.time(), 3), "error": error}


async def write_state(store: TaskStore, doc: dict[str, Any], ttl: int) -> None:
    await anyio.to_thread.run_sync(store.put_state, doc["task_id"], orjson.dumps(doc), ttl)


async def read_state(store: TaskStore, tid: str, lost_after: float) -> dict[str, Any] | None:
    raw = await anyio.to_thread.run_sync(store.get_state, tid)
    if raw is None:
        return None
    doc: dict[str, Any] = orjson.loads(raw)
    if doc["status"] in ("pending", "running") and time.time() - doc["created"] > lost_after:
        doc.update(status="failed", error=problem_doc(Problem(
            503, "Task lost", "the replica computing this task stopped; submit it again",
            kind="task-lost", headers={"Retry-After": "1"})))
    return doc


def problem_doc(exc: BaseException) -> dict[str, Any]:
    """The problem document a synchronous call would have answered with."""
    if isinstance(exc, Problem):
        kind = exc.kind
        doc: dict[str, Any] = {"type": kind if kind == "about:blank" else PROBLEM_BASE + kind,
                               "title": exc.title, "status": exc.status, "detail": exc.detail}
        if exc.errors:
            doc["errors"] = exc.errors
        return doc
    if isinstance(exc, ZwError):
        status, title, kind = (
            (413, "Request too large", "too-large") if isinstance(exc, LimitExceededError)
            else (422, "No plan possible", "no-plan") if isinstance(exc, PlanningError)
            else (422, "Invalid request", "validation"))
        return {"type": PROBLEM_BASE + kind, "title": title, "status": status,
                "detail": str(exc), "errors": [{"field": exc.field, "reason": exc.reason}]}
    return {"type": "about:blank", "title": "Internal error", "status": 500,
            "detail": "The service failed on this task; it has been logged."}


def spawn(coro: Any) -> asyncio.Task[Any]:
    task = asyncio.ensure_future(coro)
    _RUNNING.add(task)
    task.add_done_callback(_RUNNING.discard)
    return task


def cancel_all() -> None:
    for task in list(_RUNNING):
        task.cancel()
