"""``GET /v1/tasks/{task_id}``: a stored result, or where an asynchronous task stands."""

from __future__ import annotations

import re
from collections.abc import Iterator
from typing import Annotated, Literal

import anyio
import orjson
from fastapi import APIRouter, Depends, Path, Query, Request, Response
from fastapi.responses import StreamingResponse

from service import asynctasks
from service.deps import SettingsDep, StoreDep
from service.problems import PROBLEM_JSON, Problem
from service.routers import if_none_match, responses
from service.schemas.tasks import TaskResult, TaskStatus
from service.tasks import lost_after, not_modified, respond, status_response
from service.toolpaths import program_key

router = APIRouter(prefix="/v1", tags=["tasks"])

_OPERATION = re.compile(rb'"operation":"([a-z_]+)"')

TaskId = Annotated[str, Path(pattern="^[0-9a-f]{64}$", description="SHA-256, hex")]


def _unknown(task_id: str) -> Problem:
    return Problem(404, "Not found", f"no stored result for task {task_id}",
                   kind="unknown-task", errors=[{"field": "task_id", "reason": "unknown"}])


@router.get("/tasks/{task_id}", response_model=TaskResult, operation_id="get_task",
            summary="The stored result of an earlier call",
            responses=responses(202, 404, conditional=True), dependencies=[Depends(if_none_match)])
async def get_task(
    request: Request,
    store: StoreDep,
    settings: SettingsDep,
    task_id: TaskId,
    grid_encoding: Annotated[
        Literal["rows", "float32", "float64"],
        Query(description="encoding of returned grids: rows, or base64 of this dtype")] = "rows",
) -> Response:
    """The result (200); while an asynchronous task is pending or running, its state
    (202, ``Retry-After``); when it failed, the problem a synchronous call would have
    answered, with its status."""
    body = await anyio.to_thread.run_sync(store.get, task_id)
    if body is not None and not_modified(request, task_id, stored=True):
        return Response(status_code=304, headers={"ETag": f'"{task_id}"'})
    if body is None:
        state = await asynctasks.read_state(store, task_id, lost_after(settings))
        if state is None or state["status"] == "done":  # done but evicted: unknown now
            raise _unknown(task_id)
        if state["status"] == "failed":
            error = state["error"]
            return Response(orjson.dumps({**error, "instance": request.url.path}),
                            status_code=error["status"], media_type=PROBLEM_JSON)
        return status_response(state, 202)
    request.state.task_id = task_id
    request.state.cache = "hit"
    return await respond(body, task_id, grid_encoding, "hit")


@router.get("/tasks/{task_id}/status", response_model=TaskStatus,
            operation_id="get_task_status", summary="Where a task stands",
            responses=responses(404))
async def get_task_status(store: StoreDep, settings: SettingsDep,
                          task_id: TaskId) -> Response:
    """``pending``, ``running``, ``done`` or ``failed`` with a progress fraction; a
    result stored by a synchronous call is ``done``."""
    state = await asynctasks.read_state(store, task_id, lost_after(settings))
    if state is None or state["status"] != "done":
        stored = await anyio.to_thread.run_sync(store.get, task_id)
        if stored is not None:
            created = state["created"] if state else 0.0
            found = _OPERATION.search(stored, 0, 200)  # results begin with it
            operation = found.group(1).decode() if found else ""
            state = asynctasks.state_doc(task_id, operation, "done", 1.0, created)
    if state is None:
        raise _unknown(task_id)
    return status_response(state, 200)


@router.get("/tasks/{task_id}/program", operation_id="get_program",
            summary="The NC program of a plan computed with tool paths",
            response_class=StreamingResponse,
            responses={200: {"content": {"text/plain": {}},
                             "description": "the program (ISO 6983 G-code)"},
                       **responses(404)})
async def get_program(
    store: StoreDep,
    task_id: TaskId,
) -> StreamingResponse:
    program = await anyio.to_thread.run_sync(store.get, program_key(task_id))
    if program is None:
        known = await anyio.to_thread.run_sync(store.get, task_id)
        reason = ("the plan was computed without tool paths (send toolpaths: true)"
                  if known is not None else "no stored result for this task")
        raise Problem(404, "Not found", f"no NC program for task {task_id}: {reason}",
                      kind="no-program", errors=[{"field": "task_id", "reason": reason}])

    def chunks() -> Iterator[bytes]:
        for start in range(0, len(program), 1 << 20):
            yield program[start:start + (1 << 20)]

    name = f"zwplan-{task_id[:12]}.nc"
    return StreamingResponse(chunks(), media_type="text/plain; charset=utf-8", headers={
        "Content-Disposition": f'attachment; filename="{name}"', "ETag": f'"{task_id}.nc"'})
