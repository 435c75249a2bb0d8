"""``POST /v1/zmaps`` (STL to z-map) and ``GET /v1/tasks/{task_id}/models/{index}``
(a stored grid as JSON or ``.npy``)."""

from __future__ import annotations

from typing import Annotated, Any, Literal

import anyio
import numpy as np
import orjson
from fastapi import APIRouter, Header, Path, Query, Request, Response
from pydantic import ValidationError
from starlette.datastructures import UploadFile

from service.deps import PoolDep, SettingsDep, StoreDep
from service.grids import canonical_grid, npy_bytes, render_grids, stored_grid
from service.problems import Problem
from service.routers import responses
from service.schemas.common import TASK_ID_PATTERN, GridOut
from service.schemas.zmaps import ZMapParams, ZMapResult
from service.tasks import not_modified, serve_task
from service.uploads import MULTIPART, NPY
from zwcore.errors import InvalidInputError
from zwcore.io import rasterise, read_stl, zmap_grid
from zwcore.io.mesh import ZMapGrid

router = APIRouter(prefix="/v1", tags=["zmaps"])

STL_TYPES = ("model/stl", "application/sla", "application/vnd.ms-pki.stl", "model/x.stl-binary",
             "model/x.stl-ascii", "application/octet-stream")

#: (triangle, node) pairs one z-map may cost, per grid cell allowed: the work bound.
PAIRS_PER_CELL = 8


def zmap_result(tri: np.ndarray, grid: ZMapGrid, background: float | None,
                max_pairs: int) -> dict[str, Any]:
    res = rasterise(tri, grid, background=background, max_pairs=max_pairs)
    pts = tri.reshape(-1, 3)
    notes = []
    n_under = int(res.undercut.sum())
    if n_under:
        notes.append(f"undercut: at {n_under} nodes ({n_under * grid.dx * grid.dy:.4g} mm²) a "
                     "surface hides under the top one; the z-map keeps only the top, so a "
                     "3-axis plan from +z leaves material there")
    if res.covered.sum() < res.z.size:
        notes.append(f"{res.z.size - int(res.covered.sum())} nodes lie outside the part and "
                     f"hold the background height {res.background:g} mm")
    return {
        "grid": canonical_grid(res.z, x0=grid.x0, y0=grid.y0, dx=grid.dx, dy=grid.dy,
                               interpolation="bilinear"),
        "background": res.background,
        "background_source": "default" if background is None else "request",
        "triangles": len(tri), "triangles_used": res.triangles_used,
        "bounds": {"min": pts.min(axis=0).tolist(), "max": pts.max(axis=0).tolist()},
        "covered_nodes": int(res.covered.sum()), "undercut_nodes": n_under,
        "undercut_area": n_under * grid.dx * grid.dy, "notes": notes,
    }


async def _stl_and_params(request: Request, params: ZMapParams) -> tuple[bytes, ZMapParams]:
    media = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if media in STL_TYPES:
        return await request.body(), params
    if media != MULTIPART:
        raise Problem(415, "Unsupported media type", f"send the STL as model/stl (binary or "
                      f"ASCII) or as the part 'stl' of {MULTIPART}; got {media or 'nothing'}",
                      kind="unsupported-media-type",
                      errors=[{"field": "content-type",
                               "reason": f"{media or 'none'} unsupported"}])
    try:
        form = await request.form(max_files=2, max_fields=16)
    except Exception as exc:  # python-multipart's errors are not one family
        raise InvalidInputError("body", f"unreadable multipart/form-data ({exc})") from None
    data, fields = None, params.model_dump(exclude_unset=True)
    try:
        for key, value in form.multi_items():
            if key == "stl" and isinstance(value, UploadFile) and data is None:
                data = await value.read()
            elif key == "stl" or key in fields:
                raise InvalidInputError(key, "given twice, or stl not as a file part")
            elif isinstance(value, str):
                fields[key] = value
            else:
                raise InvalidInputError(key, "a file part; only stl is a file")
    finally:
        await form.close()
    if data is None:
        raise InvalidInputError("stl", "missing: send the STL as a file part named stl")
    try:
        return data, ZMapParams.model_validate(fields)
    except ValidationError as exc:
        err = exc.errors()[0]
        name = ".".join(str(p) for p in err["loc"]) or "body"
        raise InvalidInputError(name, str(err["msg"])) from None


def _prepare(data: bytes, p: ZMapParams, max_cells: int) -> tuple[np.ndarray, ZMapGrid]:
    tri = read_stl(data)
    return tri, zmap_grid(tri, dx=p.dx, dy=p.dy, nx=p.nx, ny=p.ny, x0=p.x0, y0=p.y0,
                          max_cells=max_cells)


@router.post(
    "/zmaps", response_model=ZMapResult, operation_id="create_zmap",
    summary="STL to z-map: the part seen from +z",
    responses={**responses(413, 415), 200: {
        "description": "the z-map task; with Accept: application/x-npy the grid alone as "
        ".npy (float64), geometry in X-Grid-* headers, task id in X-Task-Id",
        "content": {NPY: {"schema": {"type": "string", "format": "binary"}}}}},
    openapi_extra={"requestBody": {"required": True, "content": {
        "model/stl": {"schema": {"type": "string", "format": "binary",
                                 "description": "binary or ASCII STL, mm"}},
        MULTIPART: {"schema": {"type": "object", "required": ["stl"], "properties": {
            "stl": {"type": "string", "format": "binary", "description": "the STL file"},
            **{k: {"type": "string", "description": f.description or ""}
               for k, f in ZMapParams.model_fields.items()}}}}}}})
async def create_zmap(request: Request, settings: SettingsDep, store: StoreDep, pool: PoolDep,
                      params: Annotated[ZMapParams, Query()]) -> Response:
    """Each node holds the highest surface point straight above it (a z-buffer of the
    triangles); nodes outside the part get ``background``. Node (0, 0) sits at the
    mesh's lower-left corner unless ``x0``/``y0`` say otherwise. The result is a task:
    plan and MRR calls take its id as ``grid_task``, so a large part is uploaded once.
    Undercuts (a surface hidden under another) are counted and noted."""
    data, p = await _stl_and_params(request, params)
    tri, grid = await anyio.to_thread.run_sync(_prepare, data, p, settings.max_grid_cells)
    max_pairs = PAIRS_PER_CELL * settings.max_grid_cells
    spec = {"grid": [grid.x0, grid.y0, grid.dx, grid.dy, grid.nx, grid.ny],
            "background": p.background}
    as_npy = NPY in request.headers.get("accept", "").lower()
    response = await serve_task(
        request, store, pool, operation="zmap", params=spec, arrays={"triangles": tri},
        compute=lambda: zmap_result(tri, grid, p.background, max_pairs),
        encoding="float64" if as_npy else p.grid_encoding)
    if not as_npy or response.status_code != 200:
        return response
    result = orjson.loads(bytes(response.body))
    return _npy_response(result["grid"], "float64", result["task_id"],
                         {"X-Task-Id": result["task_id"],
                          "X-Cache": response.headers.get("x-cache", "")})


def _npy_response(grid: dict[str, Any], dtype: str, name: str,
                  headers: dict[str, str]) -> Response:
    """A stored grid as an ``.npy`` file, its geometry in ``X-Grid-*`` headers."""
    z, geo = stored_grid(grid)
    out = npy_bytes(z, dtype)
    headers = {**headers, "X-Grid-X0": repr(geo["x0"]), "X-Grid-Y0": repr(geo["y0"]),
               "X-Grid-Dx": repr(geo["dx"]), "X-Grid-Dy": repr(geo["dy"]),
               "X-Grid-Interpolation": geo["interpolation"],
               "Content-Disposition": f'attachment; filename="{name[:12]}.npy"'}
    return Response(out, media_type=NPY, headers=headers)


def _model_at(result: dict[str, Any], index: int) -> dict[str, Any] | None:
    op = result.get("operation")
    if op == "zmap":
        return result["grid"] if index == 0 else None
    items = result.get("levels") if op == "mrr" else result.get("stages")
    if not isinstance(items, list) or not 0 <= index < len(items):
        return None
    grid = items[index].get("grid" if op == "mrr" else "model")
    return grid if isinstance(grid, dict) else None


@router.get(
    "/tasks/{task_id}/models/{index}", response_model=GridOut, operation_id="get_task_model",
    tags=["tasks"], summary="One stored grid of a task, as JSON or .npy",
    responses={**responses(304, 404),
               200: {"description": "the grid; geometry in X-Grid-* headers for .npy",
                     "content": {NPY: {"schema": {"type": "string", "format": "binary"}}}}})
async def get_task_model(
    request: Request, store: StoreDep,
    task_id: Annotated[str, Path(pattern=TASK_ID_PATTERN, description="SHA-256, hex")],
    index: Annotated[int, Path(ge=0, le=1 << 16, description=(
        "z-map task: 0; MRR: the level (0 coarsest); plans: the stage, in machining order"))],
    accept: Annotated[str | None, Header(include_in_schema=False)] = None,
    dtype: Annotated[Literal["float32", "float64"], Query(
        description="element type: of the .npy, or of z_b64 with JSON")] = "float64",
    grid_encoding: Annotated[Literal["rows", "float32", "float64"] | None, Query(
        description="JSON only: rows, or base64 of this dtype (default: dtype)")] = None,
) -> Response:
    """``Accept: application/x-npy`` gets the heights as an ``.npy`` file (float32 rounded
    upward, so a stock model never moves into the part) with ``X-Grid-X0``,
    ``X-Grid-Y0``, ``X-Grid-Dx``, ``X-Grid-Dy`` and ``X-Grid-Interpolation``; any
    other ``Accept`` the grid as JSON. Plans and MRR results hold models only when
    computed with ``include_models``."""
    body = await anyio.to_thread.run_sync(store.get, task_id)
    if body is None:
        raise Problem(404, "Not found", f"no stored result for task {task_id}",
                      kind="unknown-task", errors=[{"field": "task_id", "reason": "unknown"}])
    grid = _model_at(orjson.loads(body), index)
    if grid is None:
        raise Problem(404, "Not found", f"task {task_id} holds no grid {index} (out of range, "
                      "or computed without include_models)", kind="unknown-model",
                      errors=[{"field": "index", "reason": "no such grid in this task"}])
    as_npy = bool(accept and NPY in accept.lower())
    # one tag per representation: the .npy and the JSON of a grid are different bytes
    tag = f"{task_id}-{index}-" + (f"npy-{dtype}" if as_npy else grid_encoding or dtype)
    etag = f'"{tag}"'
    if not_modified(request, tag, stored=True):
        return Response(status_code=304, headers={"ETag": etag})
    if as_npy:
        return await anyio.to_thread.run_sync(_npy_response, grid, dtype, f"{task_id}-{index}",
                                              {"ETag": etag})
    rendered = render_grids(grid, grid_encoding or dtype)
    return Response(orjson.dumps(rendered), media_type="application/json",
                    headers={"ETag": etag})
