"""Serving a task: hash, conditional request, cache, compute, respond.

Every operation's route is thin: it validates its body, names the canonical
request and hands a compute function to :func:`serve_task`.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Callable, Mapping
from typing import Any

import anyio
import numpy as np
import orjson
from fastapi import Request, Response
from fastapi.responses import StreamingResponse

from service import asynctasks, metrics
from service.compute import ComputePool
from service.hashing import task_id as make_task_id
from service.problems import Problem
from service.render import stream_body
from service.settings import Settings
from service.store import TaskStore
from zwcore.errors import ZwError

log = logging.getLogger("zwplan.tasks")

JSON = "application/json"


def _etag(tid: str) -> str:
    return f'"{tid}"'


def not_modified(request: Request, tid: str, stored: bool) -> bool:
    """True when ``If-None-Match`` names this task (strong or weak, in a list), or is
    ``*`` and a stored result exists (RFC 9110: ``*`` matches any current representation)."""
    header = request.headers.get("if-none-match")
    if not header:
        return False
    for tag in header.split(","):
        tag = tag.strip()
        if (tag == "*" and stored) or tag.removeprefix("W/").strip('"') == tid:
            return True
    return False


async def response_bytes(response: Response) -> bytes:
    """The whole body of an answer from :func:`respond`, streamed or not (for routes that
    re-shape a result, e.g. into a file)."""
    if isinstance(response, StreamingResponse):
        chunks = [c if isinstance(c, bytes) else str(c).encode()
                  async for c in response.body_iterator]
        return b"".join(chunks)
    return bytes(response.body)


#: Results up to this size are rendered in one piece (in a worker thread).
STREAM_ABOVE_BYTES = 1 << 20


async def respond(body: bytes, tid: str, encoding: str, cache: str) -> Response:
    """The stored body for this client: grids rendered off the event loop, and large
    results streamed (see :mod:`service.render`)."""
    headers = {"ETag": _etag(tid), "X-Cache": cache}
    if len(body) > STREAM_ABOVE_BYTES:
        return StreamingResponse(stream_body(body, encoding), media_type=JSON, headers=headers)
    if encoding != "float64" and b'"z_b64"' in body:
        body = await anyio.to_thread.run_sync(
            lambda: b"".join(stream_body(body, encoding)))
    return Response(body, media_type=JSON, headers=headers)


def encode_result(tid: str, operation: str, compute: Callable[..., dict[str, Any]],
                  args: tuple[Any, ...]) -> tuple[bytes, float]:
    """The stored body of a task and the milliseconds its computation took (runs in
    the compute pool, in a thread or a worker process)."""
    start = time.perf_counter()
    result = {"task_id": tid, "operation": operation, **compute(*args)}
    out = orjson.dumps(result, option=orjson.OPT_SERIALIZE_NUMPY)
    return out, round((time.perf_counter() - start) * 1000, 2)


async def serve_task(request: Request, store: TaskStore, pool: ComputePool, *, operation: str,
                     params: Mapping[str, Any], arrays: Mapping[str, np.ndarray] | None,
                     compute: Callable[..., dict[str, Any]], args: tuple[Any, ...] = (),
                     in_process: bool = False, encoding: str = "float64", memory: int = 0,
                     respond_async: bool = False) -> Response:
    """Answer one operation from the cache or by computing it.

    ``compute(*args)`` returns the result as plain data with grids in canonical
    form (:func:`service.grids.canonical_grid`); it runs in the compute pool, in a
    worker process when ``in_process`` (then it and ``args`` must pickle).
    ``memory`` is its estimated peak (admission by memory). With ``respond_async``
    a result not stored yet is computed in the background: 202 and a Location.
    """
    # A float32 upload is exactly float32 by construction: skip the hashing check.
    exact = dict.fromkeys(arrays or {}, True) if encoding == "float32" else None
    tid = await anyio.to_thread.run_sync(make_task_id, operation, params, arrays, exact)
    # metrics are labelled by the OpenAPI operation id, as the request metrics and logs are
    label = getattr(request.scope.get("route"), "operation_id", None) or operation
    request.state.task_id = tid
    # The task id is the content hash, so a named tag is answered without the store.
    if not_modified(request, tid, stored=False):
        request.state.cache = "not-modified"
        return Response(status_code=304, headers={"ETag": _etag(tid)})
    body = await anyio.to_thread.run_sync(store.get, tid)
    if body is not None and not_modified(request, tid, stored=True):
        request.state.cache = "not-modified"
        return Response(status_code=304, headers={"ETag": _etag(tid)})
    if body is not None:
        metrics.CACHE.labels(label, "hit").inc()
        request.state.cache = "hit"
        return await respond(body, tid, encoding, "hit")
    job = (tid, label, encode_result, tid, operation, compute, args)
    if respond_async:
        return await _accept(request, store, pool, job, in_process, memory)

    (result, compute_ms), shared = await pool.run_once(*job, in_process=in_process,
                                                       memory=memory)
    request.state.compute_ms = compute_ms
    outcome = "shared" if shared else "miss"
    metrics.CACHE.labels(label, outcome).inc()
    request.state.cache = outcome
    if not shared:
        await anyio.to_thread.run_sync(store.put, tid, result)
    return await respond(result, tid, encoding, outcome)


def _settings(request: Request) -> Settings:
    settings: Settings = request.app.state.settings
    return settings


def lost_after(settings: Settings) -> float:
    return (settings.compute_timeout_seconds + settings.memory_wait_seconds
            + asynctasks.LOST_AFTER_MARGIN)


def status_response(doc: dict[str, Any], code: int) -> Response:
    tid = doc["task_id"]
    headers = {"Location": f"/v1/tasks/{tid}"}
    if doc["status"] in ("pending", "running"):
        headers["Retry-After"] = "1"
    return Response(orjson.dumps(doc), status_code=code, media_type=JSON, headers=headers)


async def _accept(request: Request, store: TaskStore, pool: ComputePool,
                  job: tuple[Any, ...], in_process: bool, memory: int) -> Response:
    """202 Accepted for a task computed in the background (or already under way)."""
    tid, label, operation = job[0], job[1], job[4]
    settings = _settings(request)
    ttl = settings.task_state_ttl_seconds
    request.state.cache = "async"
    state = await asynctasks.read_state(store, tid, lost_after(settings))
    if state is not None and state["status"] in ("pending", "running"):
        return status_response(state, 202)  # already under way here or on another replica
    created = round(time.time(), 3)
    pending = asynctasks.state_doc(tid, operation, "pending", 0.0, created)
    await asynctasks.write_state(store, pending, ttl)

    async def background() -> None:
        try:
            await asynctasks.write_state(
                store, asynctasks.state_doc(tid, operation, "running", 0.1, created), ttl)
            (result, _ms), shared = await pool.run_once(*job, in_process=in_process,
                                                        memory=memory)
            metrics.CACHE.labels(label, "shared" if shared else "miss").inc()
            await asynctasks.write_state(
                store, asynctasks.state_doc(tid, operation, "running", 0.9, created), ttl)
            if not shared:
                await anyio.to_thread.run_sync(store.put, tid, result)
            done = asynctasks.state_doc(tid, operation, "done", 1.0, created)
            await asynctasks.write_state(store, done, ttl)
        except asyncio.CancelledError:
            raise
        except Exception as exc:
            if not isinstance(exc, (Problem, ZwError)):
                log.exception("asynchronous task %s failed", tid)
            failed = asynctasks.state_doc(tid, operation, "failed", 0.0, created,
                                          error=asynctasks.problem_doc(exc))
            await asynctasks.write_state(store, failed, ttl)

    asynctasks.spawn(background())
    return status_response(pending, 202)
