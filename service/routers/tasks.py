"""``GET /v1/tasks/{task_id}``: a stored result."""

from __future__ import annotations

from typing import Annotated, Literal

import anyio
from fastapi import APIRouter, Path, Query, Request, Response

from service.deps import StoreDep
from service.problems import Problem
from service.routers import responses
from service.schemas.tasks import TaskResult
from service.tasks import not_modified, respond

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
    return await respond(body, task_id, grid_encoding, "hit")
