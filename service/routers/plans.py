"""``POST /v1/plans/scanline`` and ``POST /v1/plans/contour``: stage models and tools."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import anyio
import numpy as np
import orjson
from fastapi import APIRouter, Depends, Request, Response
from pydantic import BaseModel

from service.deps import PoolDep, PreferAsyncDep, SettingsDep, StoreDep
from service.grids import canonical_grid
from service.hashing import core_build
from service.hashing import task_id as make_task_id
from service.routers import if_none_match, responses
from service.schemas.common import ToolIn
from service.schemas.plans import (
    ContourChecksOut,
    ContourPlanRequest,
    ContourPlanResult,
    ContourStageOut,
    ScanlineChecksOut,
    ScanlinePlanRequest,
    ScanlinePlanResult,
    ScanlineStageOut,
)
from service.store import TaskStore
from service.tasks import serve_task
from service.toolpaths import cutting, plan_inputs_key, program_key, toolpaths_section
from service.uploads import GridRoute, binary_grid_openapi, request_zmap
from zwcore import Tool, ZMap, default_tools, tool_library
from zwcore.contour.planner import plan_contour
from zwcore.errors import InvalidInputError, LimitExceededError
from zwcore.grid.tools import ToolKind
from zwcore.grid.zmap import MAX_ABS_HEIGHT
from zwcore.scanline.planner import plan_scanline
from zwcore.toolpath import contour_toolpaths, scanline_toolpaths

# Estimated peak memory per grid node (admission by memory): measured as peak RSS over
# the baseline of one plan of a 1024² part, including its encoded result, rounded up.
SCANLINE_BYTES = 40
SCANLINE_MODELS_BYTES = 120
CONTOUR_BYTES = 80

router = APIRouter(prefix="/v1/plans", tags=["plans"], route_class=GridRoute)


def _plain(value: Any) -> Any:
    """Dataclass fields as JSON data: tuples as lists, numpy scalars as floats, inf as null."""
    if isinstance(value, Tool):
        return {"id": value.id, "kind": value.kind, "diameter": value.diameter,
                "flute_length": value.flute_length}
    if isinstance(value, (tuple, list)):
        return [_plain(v) for v in value]
    if isinstance(value, (np.floating, float)):
        f = float(value)
        return f if math.isfinite(f) else None
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.bool_):
        return bool(value)
    return value


def _pick(obj: Any, model: type[BaseModel], skip: tuple[str, ...] = ()) -> dict[str, Any]:
    """The response model's fields, read off a core dataclass."""
    return {name: _plain(getattr(obj, name)) for name in model.model_fields
            if name not in skip and hasattr(obj, name)}


def _stages(stages: Sequence[Any], model: type[BaseModel],
            grid: Callable[[Any], dict[str, Any]] | None) -> list[dict[str, Any]]:
    """Stages in machining order as the response model lists them; ``grid`` renders a
    stage's model when the request asked for models."""
    out = []
    for index, stage in enumerate(stages):
        entry = _pick(stage, model, skip=("model", "index"))
        entry["index"] = index
        if grid is not None:
            entry["model"] = grid(stage)
        out.append(entry)
    return out


def _tools(given: list[ToolIn] | None, kind: ToolKind, max_tools: int) -> list[Tool]:
    """The validated library, largest first: the order a client lists tools in is not
    part of the task (the planner sorts them anyway)."""
    if given is None:
        return list(default_tools(kind))
    if len(given) > max_tools:
        raise LimitExceededError("tools", f"{len(given)} tools exceed the limit of {max_tools}")
    for i, t in enumerate(given):
        if t.kind is not None and t.kind != kind:
            raise InvalidInputError(f"tools[{i}].kind",
                                    f"a {t.kind} end mill; this plan takes {kind} end mills")
    return list(tool_library([Tool(t.id, kind, t.diameter, t.flute_length) for t in given],
                             kind))


def _tool_params(tools: list[Tool]) -> list[list[Any]]:
    return [[t.id, t.diameter, t.flute_length] for t in tools]


class ToolpathJob:
    """What a plan with ``toolpaths: true`` needs besides the plan: the request's options,
    the store that keeps the program and the task id it is kept under."""

    def __init__(self, body: Any, tools: list[Tool], store: TaskStore, max_bytes: int,
                 operation: str, params: dict[str, Any], zmap: ZMap) -> None:
        self.cutting = cutting(body.tools, tools)
        self.clearance = body.clearance
        self.rapid_feed = body.rapid_feed
        self.store = store
        self.max_bytes = max_bytes
        self.params = params
        self.params["toolpaths"] = {
            "clearance": body.clearance, "rapid_feed": body.rapid_feed,
            "cutting": [[t.id, *vars(self.cutting[t.id]).values()] for t in tools]}
        self.operation = operation
        self.zmap = zmap

    def task_id(self) -> str:
        return make_task_id(self.operation, self.params, {"z": self.zmap.z})

    def section(self, tp: Any) -> dict[str, Any]:
        tid = self.task_id()
        self.store.put(program_key(tid), tp.program.encode())
        return toolpaths_section(tp, tid)


def scanline_result(zmap: ZMap, tools: list[Tool], tolerance: float, stock_top: float | None,
                    include_models: bool, job: ToolpathJob | None = None) -> dict[str, Any]:
    plan = plan_scanline(zmap, tools, tolerance=tolerance, stock_top=stock_top)
    section = None
    if job is not None:
        tp = scanline_toolpaths(zmap, plan, cutting=job.cutting,
                                clearance=job.clearance, rapid_feed=job.rapid_feed,
                                max_bytes=job.max_bytes)
        section = job.section(tp)

    def model(stage: Any) -> dict[str, Any]:
        # Single-knot nodes sit on input nodes: the origin is the input's.
        sx, sy = stage.spacing
        return canonical_grid(stage.model, x0=zmap.x0, y0=zmap.y0, dx=sx, dy=sy,
                              interpolation="bilinear")

    stages = _stages(plan.stages, ScanlineStageOut, model if include_models else None)
    for entry, stage in zip(stages, plan.stages, strict=True):
        entry.update(_region_fields(stage, zmap, include_models))
    return {"stock_top": plan.stock_top, "stock_top_source": plan.stock_top_source,
            "tolerance": tolerance, "scallop_tolerance": plan.scallop_tolerance,
            "cell_bound": plan.cell_bound,
            "tool_sequence": list(plan.tool_sequence),
            "stages": stages,
            "checks": _pick(plan.checks, ScanlineChecksOut), "notes": list(plan.notes),
            **({"toolpaths": section} if section is not None else {}),
            **({"reach": _reach_summary(plan.reach)} if plan.reach is not None else {})}


def _region_fields(stage: Any, zmap: ZMap, include_models: bool) -> dict[str, Any]:
    """A scan-line stage's rest region: boxes in the grid's coordinates, and its mask
    grid (1/0 per node of the stage model's grid) when models were asked for."""
    boxes = [{"x_min": zmap.x0 + b[0], "y_min": zmap.y0 + b[1], "x_max": zmap.x0 + b[2],
              "y_max": zmap.y0 + b[3], "area": b[4]} for b in stage.region_boxes]
    region = None
    if include_models and stage.region is not None:
        sx, sy = stage.spacing
        region = canonical_grid(stage.region.astype(np.float64), x0=zmap.x0, y0=zmap.y0,
                                dx=sx, dy=sy, interpolation="cell")
    return {"region_boxes": boxes, "region": region}


def _reach_summary(reach: Any) -> dict[str, Any]:
    out = {name: _plain(getattr(reach, name)) for name in (
        "finishing_tools", "finishing_cut_length", "smallest_ball_cut_length",
        "unreachable_area", "unreachable_max_height", "needed_radius")}
    out["cut_length_factor"] = reach.smallest_ball_cut_length / reach.finishing_cut_length
    return out


def bound_contour_slabs(zmap: ZMap, tools: list[Tool], given: list[ToolIn] | None,
                        stock_top: float | None, max_slabs: int) -> None:
    """Refuse a contour plan whose slab count would be unbounded (413).

    A stage places about ``depth / min(flute_length, diameter)`` contour heights
    (heavy roughing: ``depth / flute_length``), and the core has no cap: a 0.001 mm
    flute under a 1e6 mm stock asked for 10**9 slabs and held a worker for good.
    """
    part_top, bottom = float(zmap.z.max()), float(zmap.z.min())
    if stock_top is not None and not part_top <= stock_top <= MAX_ABS_HEIGHT:
        return  # the core rejects this stock top with a 422 naming it
    top = part_top + tools[0].flute_length if stock_top is None else stock_top
    depth = top - bottom
    for tool in tools:
        step = min(tool.flute_length, tool.diameter)
        if depth / step <= max_slabs:
            continue
        if given is None:
            field = "stock_top"
        else:
            index = next(i for i, t in enumerate(given) if t.id == tool.id)
            name = "flute_length" if tool.flute_length <= tool.diameter else "diameter"
            field = f"tools[{index}].{name}"
        raise LimitExceededError(
            field, f"tool {tool.id} would need about {depth / step:.3g} contour slabs over "
            f"{depth:g} mm of stock (step {step:g} mm), more than the limit of {max_slabs}; "
            "use a larger tool or a lower stock_top")


def contour_result(zmap: ZMap, tools: list[Tool], stock_top: float | None, strategy: str,
                   include_models: bool, job: ToolpathJob | None = None,
                   tolerance: float = 0.05, stepover: float = 0.4) -> dict[str, Any]:
    plan = plan_contour(zmap, tools, stock_top=stock_top, strategy=strategy)
    section = None
    if job is not None:
        tp = contour_toolpaths(zmap, plan, cutting=job.cutting, clearance=job.clearance,
                               tolerance=tolerance, stepover_fraction=stepover,
                               rapid_feed=job.rapid_feed, max_bytes=job.max_bytes)
        section = job.section(tp)

    def model(stage: Any) -> dict[str, Any]:
        cx, cy = stage.cell_size
        ox, oy = stage.origin  # centre of the first cell's block of input nodes
        return canonical_grid(stage.model, x0=ox, y0=oy, dx=cx, dy=cy, interpolation="cell")

    return {"stock_top": plan.stock_top, "stock_top_source": plan.stock_top_source,
            "strategy": plan.strategy, "contour_spacings": _plain(plan.contour_spacings),
            "stages": _stages(plan.stages, ContourStageOut, model if include_models else None),
            "checks": _pick(plan.checks, ContourChecksOut), "notes": list(plan.notes),
            **({"toolpaths": section} if section is not None else {})}


@router.post("/scanline", response_model=ScanlinePlanResult, operation_id="plan_scanline",
             summary="Scan-line plan: stage models and ball-end-mill sequence",
             responses=responses(202, 413, 415, conditional=True),
             dependencies=[Depends(if_none_match)],
             openapi_extra=binary_grid_openapi(ScanlinePlanRequest))
async def post_scanline_plan(body: ScanlinePlanRequest, request: Request, settings: SettingsDep,
                             store: StoreDep, pool: PoolDep,
                             respond_async: PreferAsyncDep) -> Response:
    """Roughing-to-finishing stage models from the lifted single-knot MRR, each with the
    largest ball end mill that fits its concave regions; no stage cuts into the part or
    deeper than its tool's flutes (see ``checks``)."""
    zmap, encoding = await request_zmap(request, body.grid, body.grid_task, settings, store)
    tools = _tools(body.tools, "ball", settings.max_tools)
    params = {"grid": [zmap.x0, zmap.y0, zmap.dx, zmap.dy], "tools": _tool_params(tools),
              "tolerance": body.tolerance, "stock_top": body.stock_top,
              "include_models": body.include_models}
    job = (ToolpathJob(body, tools, store, settings.max_program_bytes, "plan_scanline", params,
                       zmap) if body.toolpaths else None)

    def compute() -> dict[str, Any]:
        result = scanline_result(zmap, tools, body.tolerance, body.stock_top,
                                 body.include_models, job)
        # computed once per task id (a cache hit reuses what was kept with the result)
        keep_plan_inputs(store, request.state.task_id, params)
        return result

    return await serve_task(
        request, store, pool, operation="plan_scanline", params=params, arrays={"z": zmap.z},
        compute=compute, encoding=encoding, respond_async=respond_async,
        memory=zmap.z.size * (SCANLINE_MODELS_BYTES if body.include_models else SCANLINE_BYTES))


def keep_plan_inputs(store: TaskStore, task_id: str, params: dict[str, Any]) -> None:
    """Keep what a scan-line plan was computed from beside its result (small): what
    ``POST /v1/simulate`` with its task id plans again from (the part comes with that
    request and must hash, with these parameters, to the task id)."""
    store.put(plan_inputs_key(task_id),
              orjson.dumps({"operation": "plan_scanline", "core_build": core_build(),
                            "params": params}))


@router.post("/contour", response_model=ContourPlanResult, operation_id="plan_contour",
             summary="Contour plan: equal-load contour heights and terraced stage models",
             responses=responses(202, 413, 415, conditional=True),
             dependencies=[Depends(if_none_match)],
             openapi_extra=binary_grid_openapi(ContourPlanRequest))
async def post_contour_plan(body: ContourPlanRequest, request: Request, settings: SettingsDep,
                            store: StoreDep, pool: PoolDep,
                            respond_async: PreferAsyncDep) -> Response:
    """Per flat end mill, the z-levels of its waterline passes (equal slab volumes) and the
    terraced model it leaves, from the lifted Haar MRR by coefficient editing."""
    zmap, encoding = await request_zmap(request, body.grid, body.grid_task, settings, store)
    tools = _tools(body.tools, "flat", settings.max_tools)
    await anyio.to_thread.run_sync(bound_contour_slabs, zmap, tools, body.tools, body.stock_top,
                                   settings.max_contour_slabs)
    params = {"grid": [zmap.x0, zmap.y0, zmap.dx, zmap.dy], "tools": _tool_params(tools),
              "stock_top": body.stock_top, "strategy": body.strategy,
              "include_models": body.include_models}
    job = None
    if body.toolpaths:
        params["toolpath_options"] = [body.tolerance, body.stepover]
        job = ToolpathJob(body, tools, store, settings.max_program_bytes, "plan_contour", params,
                          zmap)
    return await serve_task(
        request, store, pool, operation="plan_contour", params=params, arrays={"z": zmap.z},
        compute=lambda: contour_result(zmap, tools, body.stock_top, body.strategy,
                                       body.include_models, job, body.tolerance, body.stepover),
        encoding=encoding, respond_async=respond_async,
        memory=zmap.z.size * CONTOUR_BYTES)
