"""``GET /v1/tasks/{task_id}/preview.png``: a picture of a stored result.

Kinds drawn today: ``model`` (a z-map, an MRR level or a plan stage as a shaded relief;
without ``stage``, every level or stage side by side with its tool), ``stock`` (the stock
a simulated pass leaves, ``POST /v1/simulate``) and ``chain`` (arc chains over their input
points, corners marked). Rest regions (they need the part, which a simulate result does
not store) and tool paths are not drawn yet and are not in the ``kind`` enum.

Status codes: a schema-valid request for a picture the task cannot have is a 404 (a
kind the task has no data for, a stage it does not have) or a 409 (a grid task computed
without its models: the stored state, not the request, is what is missing).
"""

from __future__ import annotations

import io
from typing import Annotated, Any, Literal

import anyio
import numpy as np
import orjson
import pybase64
from fastapi import APIRouter, Path, Query, Request, Response

from service import previews
from service.cadfiles import input_key
from service.deps import PoolDep, StoreDep
from service.problems import Problem
from service.routers import responses
from service.store import TaskStore
from zwcore.io.gcode_program import program_runs

router = APIRouter(prefix="/v1", tags=["tasks"])

Kind = Literal["model", "stock", "chain"]
_GRID_OPS = ("mrr", "plan_scanline", "plan_contour")
_CHAIN_OPS = ("arcs", "arcs_gcode", "arcs_dxf")
#: Bumped when pictures change, so cached previews (by ETag) are redrawn.
_STYLE = "1"


def _no_preview(status: int, field: str, reason: str) -> Problem:
    return Problem(status, "No preview", f"{field}: {reason}", kind="no-preview",
                   errors=[{"field": field, "reason": reason}])


def _stage_missing(stage: int, count: int, what: str) -> Problem:
    return Problem(404, "Not found", f"{what} {stage} does not exist (the task has {count})",
                   kind="unknown-stage", errors=[{"field": "stage", "reason": "unknown"}])


def _panel(grid: dict[str, Any], title: str) -> previews.Panel:
    ny, nx = grid["shape"]
    z = np.frombuffer(pybase64.b64decode(grid["z_b64"]), dtype="<f8").reshape(ny, nx)
    return previews.Panel(z, grid["x0"], grid["y0"], grid["dx"], grid["dy"], title)


def _items(result: dict[str, Any]) -> tuple[list[dict[str, Any] | None], str, list[str]]:
    """The grids of a result, the name of one, and each one's title."""
    op = result["operation"]
    if op == "mrr":
        levels = result["levels"]
        return ([lv.get("grid") for lv in levels], "level",
                [f"level {lv['level']} ({result['wavelet']}, {lv['nx']} x {lv['ny']})"
                 for lv in levels])
    if op in ("plan_scanline", "plan_contour"):
        stages = result["stages"]
        titles = []
        for s in stages:
            t = s["tool"]
            titles.append(f"stage {s['index']}: {t['id']} ({t['kind']} Ø{t['diameter']:g}, "
                          f"flutes {t['flute_length']:g}), level {s['level']}")
        return [s.get("model") for s in stages], "stage", titles
    if op == "simulate":
        t = result["tool"]
        return ([result["machined"]], "stock",
                [f"stock after {t['id']} ({t['kind']} Ø{t['diameter']:g}), "
                 f"rest up to {result['rest']['max']:.3g} mm"])
    grid = result.get("grid")  # a z-map task
    return [grid], "grid", [f"z-map {result.get('task_id', '')[:12]}"]


def render_model(result: dict[str, Any], stage: int | None) -> bytes:
    grids, what, titles = _items(result)
    if any(g is None for g in grids):
        raise _no_preview(409, "include_models", "the task was computed without its "
                          "models; repeat the request with include_models=true")
    if stage is not None and stage >= len(grids):
        raise _stage_missing(stage, len(grids), what)
    if stage is not None:
        one = grids[stage]
        assert one is not None
        return previews.relief(_panel(one, titles[stage]))  # only this grid is decoded
    panels = [_panel(g, t) for g, t in zip(grids, titles, strict=True) if g is not None]
    if len(panels) == 1:
        return previews.relief(panels[0])
    name = result["operation"].replace("_", " ")
    return previews.overview(panels, f"{name}: {len(panels)} {what}s")


def _chains(result: dict[str, Any], stored_input: bytes | None
            ) -> tuple[list[list[dict[str, Any]]], list[np.ndarray], list[list[int]]]:
    op = result["operation"]
    if op == "arcs":
        points = [] if stored_input is None else [
            np.load(io.BytesIO(stored_input), allow_pickle=False)]
        return [result["segments"]], points, [result["summary"]["corners"]]
    if op == "arcs_gcode":
        runs = [r for r in result["runs"] if r["rewritten"]]
        pts = [] if stored_input is None else program_runs(stored_input.decode())
        kept = [p for p, r in zip(pts, result["runs"], strict=False) if r["rewritten"]]
        return [r["segments"] for r in runs], kept, [r["corners"] for r in runs]
    chains = [c for c in result["chains"] if c["fitted"]]
    return ([c["segments"] for c in chains], [np.asarray(c["points"]) for c in chains],
            [c["corners"] for c in chains])


def render_chain(result: dict[str, Any], stored_input: bytes | None, stage: int | None
                 ) -> bytes:
    chains, points, corners = _chains(result, stored_input)
    if stage is not None:
        if stage >= len(chains):
            raise _stage_missing(stage, len(chains), "chain")
        chains, corners = [chains[stage]], [corners[stage]]
        points = points[stage:stage + 1]
    n_arcs = sum(s["kind"] == "arc" for c in chains for s in c)
    n_seg = sum(len(c) for c in chains)
    title = (f"{len(chains)} chain(s): {n_arcs} arcs, {n_seg - n_arcs} lines"
             f"{'' if points else ' (input points not stored)'}")
    return previews.chain_picture(chains, points, corners, title)


def render(body: bytes, stored_input: bytes | None, stage: int | None, kind: str | None
           ) -> bytes:
    """The PNG of a stored result (runs in the compute pool)."""
    result = orjson.loads(body)
    op = result.get("operation", "")
    has = ["chain"] if op in _CHAIN_OPS else ["stock"] if op == "simulate" else ["model"]
    kind = kind or has[0]
    if kind not in has:
        raise _no_preview(404, "kind", f"a {op} task has no {kind} picture; it has: {has}")
    if kind == "chain":
        return render_chain(result, stored_input, stage)
    return render_model(result, stage)


def _etag(task_id: str, stage: int | None, kind: str | None) -> str:
    return f'"{task_id}.png.{stage}.{kind}.{_STYLE}"'


async def _load(store: TaskStore, task_id: str) -> tuple[bytes, bytes | None]:
    body = await anyio.to_thread.run_sync(store.get, task_id)
    if body is None:
        raise Problem(404, "Not found", f"no stored result for task {task_id}",
                      kind="unknown-task", errors=[{"field": "task_id", "reason": "unknown"}])
    stored = await anyio.to_thread.run_sync(store.get, input_key(task_id))
    return body, stored


@router.get("/tasks/{task_id}/preview.png", operation_id="get_preview",
            summary="A PNG picture of a stored result", response_class=Response,
            responses={200: {"content": {"image/png": {
                "schema": {"type": "string", "format": "binary"}}},
                "description": "the picture"}, **responses(304, 404, 409)})
async def get_preview(
    request: Request,
    store: StoreDep,
    pool: PoolDep,
    task_id: Annotated[str, Path(pattern="^[0-9a-f]{64}$", description="SHA-256, hex")],
    stage: Annotated[int | None, Query(
        ge=0, le=10_000, description="one MRR level, plan stage, G-code run or DXF chain "
        "(0-based, as listed in the result); omitted: all of them")] = None,
    kind: Annotated[Kind | None, Query(
        description="model: z-maps, MRR levels and plan stage models; stock: the stock a "
        "simulated pass leaves; chain: arc chains over their input points (arcs tasks); "
        "default: what the task has. Rest regions and tool paths are not drawn yet")] = None,
) -> Response:
    """Stage models as shaded reliefs with a colour bar in mm and a scale bar (grids over
    512 nodes a side are shown by block maxima), a plan's stages side by side with their
    tools, or arc chains over their input points with corners marked."""
    etag = _etag(task_id, stage, kind)
    if request.headers.get("if-none-match") == etag:
        return Response(status_code=304, headers={"ETag": etag})
    body, stored = await _load(store, task_id)
    request.state.task_id = task_id
    png = await pool.run("get_preview", render, body, stored, stage, kind)
    return Response(png, media_type="image/png",
                    headers={"ETag": etag, "Cache-Control": "private, max-age=86400"})

