"""``GET /v1/tasks/{task_id}``: a stored result."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Annotated, Literal

import anyio
from fastapi import APIRouter, Path, Query, Request, Response
from fastapi.responses import StreamingResponse

from service.deps import StoreDep
from service.problems import Problem
from service.routers import responses
from service.schemas.tasks import TaskResult
from service.tasks import not_modified, respond
from service.toolpaths import program_key

router = APIRouter(prefix="/v1", tags=["tasks"])


@router.get("/tasks/{task_id}", response_model=TaskResult, operation_id="get_task",
            summary="The stored result of an earlier call", responses=responses(304, 404))
async def get_task(
    request: Request,
    store: StoreDep,
    task_id: Annotated[str, Path(pattern="^[0-9a-f]{64}$", description="SHA-256, hex")],
    grid_encoding: Annotated[
        Literal["rows", "float32", "float64"],
        Query(description="encoding of returned grids: rows, or base64 of this dtype")] = "rows",
) -> Response:
    body = await anyio.to_thread.run_sync(store.get, task_id)
    if body is not None and not_modified(request, task_id, stored=True):
        return Response(status_code=304, headers={"ETag": f'"{task_id}"'})
    if body is None:
        raise Problem(404, "Not found", f"no stored result for task {task_id}",
                      kind="unknown-task", errors=[{"field": "task_id", "reason": "unknown"}])
    request.state.task_id = task_id
    request.state.cache = "hit"
    return respond(body, task_id, grid_encoding, "hit")


@router.get("/tasks/{task_id}/program", operation_id="get_program",
            summary="The NC program of a plan computed with tool paths",
            response_class=StreamingResponse,
            responses={200: {"content": {"text/plain": {}},
                             "description": "the program (ISO 6983 G-code)"},
                       **responses(404)})
async def get_program(
    store: StoreDep,
    task_id: Annotated[str, Path(pattern="^[0-9a-f]{64}$", description="SHA-256, hex")],
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
