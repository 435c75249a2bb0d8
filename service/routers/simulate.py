"""``POST /v1/simulate``: what a tool really leaves and engages, from cutting simulation."""

from __future__ import annotations

import hashlib
from typing import Any

import anyio
import numpy as np
import orjson
from fastapi import APIRouter, Depends, Request, Response

from service import asynctasks
from service.bodies import OffLoopRoute
from service.compute import ComputePool
from service.deps import PoolDep, PreferAsyncDep, SettingsDep, StoreDep
from service.grids import canonical_grid, decode_grid, grid_encoding
from service.hashing import canonical_bytes, core_build
from service.hashing import task_id as make_task_id
from service.problems import Problem
from service.routers import if_none_match, responses
from service.schemas.common import Grid
from service.schemas.simulate import SimulateRequest, SimulateResult
from service.settings import Settings
from service.store import TaskStore
from service.tasks import lost_after, serve_task
from service.toolpaths import plan_inputs_key, program_key
from zwcore import Tool, ZMap
from zwcore.errors import InvalidInputError, LimitExceededError
from zwcore.grid.zmap import Interpolation, stock_top_at_or_above
from zwcore.scanline.planner import plan_scanline
from zwcore.scanline.replay import PlanReplay, replay_passes
from zwcore.sim import gouge, rest_material, rest_regions, simulate_pass, simulation_work
from zwcore.toolpath.verify_plan import ProgramReplay, replay_program

# Estimated peak memory per part node (admission by memory): part, stock, CL and the
# machined surface with their temporaries; a conservative guess, not measured.
SIMULATE_BYTES = 160
#: The same for a plan simulated again: the plan's own peak (with its pass models) and the
#: replay's stock grids; a conservative guess, not measured.
SIMULATE_PLAN_BYTES = 320
#: Rest material above this counts toward ``rest.area_fraction`` unless the request says.
DEFAULT_TOLERANCE = 0.01

router = APIRouter(prefix="/v1", tags=["simulate"], route_class=OffLoopRoute)


def _aligned(grid: Grid, part: ZMap, max_cells: int, field: str) -> np.ndarray:
    """A second grid on the part's nodes: same shape, origin and spacing."""
    other = decode_grid(grid, max_cells, field)
    if other.shape != part.shape:
        raise InvalidInputError(f"{field}.shape", f"{list(other.shape)} differs from the "
                                f"part's {list(part.shape)}")
    for name in ("x0", "y0", "dx", "dy"):
        if not np.isclose(getattr(other, name), getattr(part, name), rtol=1e-9, atol=1e-9):
            raise InvalidInputError(f"{field}.{name}", f"{getattr(other, name)!r} differs "
                                    f"from the part's {getattr(part, name)!r}")
    return other.z


def simulate_result(part: ZMap, tool: Tool, stock: np.ndarray | float, cl: np.ndarray | None,
                    interpolation: Interpolation, tolerance: float) -> dict[str, Any]:
    sim = simulate_pass(part, tool, stock, cl=cl, interpolation=interpolation)
    regions = rest_regions(sim.stock, part, tolerance)
    notes = []
    if sim.gouge > 0:
        notes.append(f"the CL positions cut up to {sim.gouge:.6g} mm into the part")
    if not sim.depth.flute_length_ok:
        notes.append(f"the tool meets up to {sim.depth.max:.6g} mm of stock, more than its "
                     f"{tool.flute_length:g} mm flutes: split the pass")
    return {
        "interpolation": interpolation,
        "tool": {"id": tool.id, "kind": tool.kind, "diameter": tool.diameter,
                 "flute_length": tool.flute_length},
        "stock_top": float(stock) if np.ndim(stock) == 0 else None,
        "cl_source": "drop_cutter" if cl is None else "request",
        "machined": canonical_grid(sim.stock, x0=part.x0, y0=part.y0, dx=part.dx, dy=part.dy,
                                   interpolation=interpolation),
        "gouge": sim.gouge,
        "rest": {"max": sim.rest.max, "p95": sim.rest.p95, "mean": sim.rest.mean,
                 "volume": sim.rest.volume, "area_fraction": regions.area_fraction},
        "depth_of_cut": {"max": sim.depth.max, "mean": sim.depth.mean,
                         "flute_length": tool.flute_length,
                         "flute_length_ok": sim.depth.flute_length_ok},
        "notes": notes,
    }


def _inputs(body: SimulateRequest, max_cells: int, max_work: int
            ) -> tuple[ZMap, Tool, np.ndarray | float, np.ndarray | None]:
    if body.tool is None:
        raise InvalidInputError("tool", "required: the end mill to simulate"
                                + (" (a CL grid needs its tool)" if body.cl is not None
                                   else " (or a plan's task_id)"))
    part = decode_grid(body.grid, max_cells)
    t = body.tool
    tool = Tool(t.id, t.kind, t.diameter, t.flute_length)
    work = simulation_work(part.shape, tool, part.dx, part.dy)
    if work > max_work:
        raise LimitExceededError("tool.diameter", f"a Ø{t.diameter:g} tool over a "
                                 f"{part.shape[0]} x {part.shape[1]} grid at {part.dx:g} mm "
                                 f"needs {work:.3g} node-offset steps, more than {max_work}")
    stock = _stock(body, part, max_cells, float(part.z.max()) + tool.flute_length)
    cl = _aligned(body.cl, part, max_cells, "cl") if body.cl is not None else None
    return part, tool, stock, cl


def _stock(body: SimulateRequest, part: ZMap, max_cells: int, default: float
           ) -> np.ndarray | float:
    """The stock before the pass: the request's grid or flat top, else ``default``."""
    if body.stock is not None and body.stock_top is not None:
        raise InvalidInputError("stock", "give stock or stock_top, not both")
    if body.stock is not None:
        stock = _aligned(body.stock, part, max_cells, "stock")
        below = stock < part.z
        if below.any():
            i, k = np.argwhere(below)[0]
            raise InvalidInputError("stock", f"lies below the part at {int(below.sum())} "
                                    f"node(s), first row {i}, column {k}")
        return stock
    if body.stock_top is not None:
        return stock_top_at_or_above(body.stock_top, float(part.z.max()))
    return default


def _tolerance(body: SimulateRequest, default: float = DEFAULT_TOLERANCE) -> float:
    return default if body.tolerance is None else body.tolerance


def _digest(grid: np.ndarray | float | None) -> str | None:
    if not isinstance(grid, np.ndarray):
        return None
    dtype, data = canonical_bytes(grid)
    return hashlib.sha256(f"{dtype}{list(grid.shape)}".encode() + data).hexdigest()


@router.post("/simulate", response_model=SimulateResult, operation_id="simulate",
             summary="Cutting simulation: the surface a tool leaves and what it engages",
             responses=responses(202, 404, 409, 413, conditional=True),
             dependencies=[Depends(if_none_match)])
async def post_simulate(body: SimulateRequest, request: Request, settings: SettingsDep,
                        store: StoreDep, pool: PoolDep,
                        respond_async: PreferAsyncDep) -> Response:
    """One ball or flat end mill machining a stock over a part, with its tip on a given CL
    grid or, without one, at the drop-cutter height everywhere (the closing); or, with a
    scan-line plan's ``task_id``, that plan on its part: its NC program read back and every
    move swept (plans with tool paths), else its passes simulated again. Returns the
    machined surface and its figures: gouge, rest over the part, real depth of cut and the
    flute-length rule (per pass or tool stretch for a plan)."""
    if body.task_id is not None:
        return await simulate_plan_task(body, request, settings, store, pool, respond_async)
    part, tool, stock, cl = await anyio.to_thread.run_sync(
        _inputs, body, settings.max_grid_cells, settings.max_simulation_work)
    # The stock and CL grids may come in another encoding than the part (whose encoding
    # serve_task trusts for float32 exactness): they enter the task id by their own digest.
    params = {"stock_digest": await anyio.to_thread.run_sync(_digest, stock),
              "cl_digest": await anyio.to_thread.run_sync(_digest, cl),
              "grid": [part.x0, part.y0, part.dx, part.dy], "interpolation": body.interpolation,
              "tool": [tool.id, tool.kind, tool.diameter, tool.flute_length],
              "stock_top": stock if not isinstance(stock, np.ndarray) else None,
              "tolerance": _tolerance(body)}
    return await serve_task(
        request, store, pool, operation="simulate", params=params, arrays={"z": part.z},
        compute=lambda: simulate_result(part, tool, stock, cl, body.interpolation,
                                        _tolerance(body)),
        encoding=grid_encoding(body.grid), respond_async=respond_async,
        memory=part.z.size * SIMULATE_BYTES)


# -- A stored scan-line plan, simulated again on its part (issue 11 part 5) -------------------


def _plan_problem(status: int, title: str, field: str, reason: str, kind: str,
                  headers: dict[str, str] | None = None) -> Problem:
    return Problem(status, title, f"{field}: {reason}", kind=kind,
                   errors=[{"field": field, "reason": reason}], headers=headers)


async def _stored_plan(store: TaskStore, settings: Settings, tid: str
                       ) -> tuple[dict[str, Any], dict[str, Any]]:
    """The stored plan result and the inputs it was computed from; problems for a task
    that is unknown (404), not finished (409), failed or not a scan-line plan (422)."""
    raw = await anyio.to_thread.run_sync(store.get, tid)
    if raw is None:
        state = await asynctasks.read_state(store, tid, lost_after(settings))
        if state is not None and state["status"] in ("pending", "running"):
            raise _plan_problem(409, "Conflict", "task_id", f"the task is {state['status']}: "
                                "simulate it once GET /v1/tasks/{task_id} answers 200",
                                "task-not-finished", {"Retry-After": "1"})
        if state is not None and state["status"] == "failed":
            error = state.get("error") or {}
            raise InvalidInputError("task_id", f"the task failed ({error.get('detail', '')}): "
                                    "there is no plan to simulate")
        raise _plan_problem(404, "Not found", "task_id", "no stored result for this task",
                            "unknown-task")
    result: dict[str, Any] = await anyio.to_thread.run_sync(orjson.loads, raw)
    if result.get("operation") != "plan_scanline":
        raise InvalidInputError("task_id", f"a {result.get('operation')} result, not a "
                                "scan-line plan")
    inputs_raw = await anyio.to_thread.run_sync(store.get, plan_inputs_key(tid))
    if inputs_raw is None:
        raise _plan_problem(404, "Not found", "task_id", "the plan's inputs are no longer "
                            "stored: send the plan request again, then this one", "unknown-task")
    inputs: dict[str, Any] = orjson.loads(inputs_raw)
    if inputs.get("core_build") != core_build():
        raise _plan_problem(409, "Conflict", "task_id", f"the plan was made by core build "
                            f"{inputs.get('core_build')}, this server runs {core_build()}: "
                            "plan again", "plan-of-another-build")
    return result, inputs


def _plan_part(body: SimulateRequest, max_cells: int, tid: str, params: dict[str, Any]
               ) -> ZMap:
    """The request's grid, which must be the plan's part (it hashes to the task id)."""
    part = decode_grid(body.grid, max_cells)
    for name, value in zip(("x0", "y0", "dx", "dy"), params["grid"], strict=True):
        if getattr(part, name) != value:
            raise InvalidInputError(f"grid.{name}", f"{getattr(part, name)!r}; the plan's "
                                    f"part has {value!r}")
    if make_task_id("plan_scanline", params, {"z": part.z}) != tid:
        raise InvalidInputError("grid", "not the part the plan was computed from (its "
                                "heights, shape, origin or spacing differ)")
    return part


def _plan_options(body: SimulateRequest, program: bool) -> None:
    """What a request with a task id may not hold."""
    if body.cl is not None:
        raise InvalidInputError("cl", "give a CL grid (with its tool) or a task_id, not both")
    if body.tool is not None:
        raise InvalidInputError("tool", "a plan is simulated with its own tools: give a tool "
                                "or a task_id, not both")
    if body.interpolation != "bilinear":
        raise InvalidInputError("interpolation", "a scan-line plan's part is bilinear between "
                                "nodes")
    if not program and (body.stock is not None or body.stock_top is not None):
        field = "stock" if body.stock is not None else "stock_top"
        raise InvalidInputError(field, "a plan without tool paths is simulated on its own "
                                "stock (its passes' flute lifts follow from it); another "
                                "stock needs a plan with toolpaths: true")


def _spread(pair: tuple[float, float]) -> dict[str, float]:
    return {"max": pair[0], "p95": pair[1]}


def _sim_tool(tool: Tool) -> dict[str, Any]:
    return {"id": tool.id, "kind": tool.kind, "diameter": tool.diameter,
            "flute_length": tool.flute_length}


def _passes_section(rp: PlanReplay) -> list[dict[str, Any]]:
    return [{"stages": [p.stage], "tool": _sim_tool(p.tool), "tool_number": None,
             "positions": p.positions, "moves": None,
             "depth_of_cut": {"max": p.depth_max, "mean": p.depth_mean,
                              "flute_length": p.tool.flute_length,
                              "flute_length_ok": p.flute_rule_ok},
             "gouge": p.gouge, "removed_volume": p.removed_volume,
             "left_over_next": _spread((p.left_over_next_max, p.left_over_next_p95)),
             "left_over_part": _spread((p.left_over_part_max, p.left_over_part_p95)),
             "over_model": None, "rapid_in_material": None, "below_part_moves": None,
             "feed_length": None, "air_feed_length": None} for p in rp.passes]


def _program_section(rp: ProgramReplay) -> list[dict[str, Any]]:
    return [{"stages": list(s.stages), "tool": _sim_tool(s.tool),
             "tool_number": s.tool_number, "positions": None, "moves": s.moves,
             "depth_of_cut": None, "gouge": s.gouge, "removed_volume": s.removed_volume,
             "left_over_next": _spread((s.left_over_next_max, s.left_over_next_p95)),
             "left_over_part": _spread((s.left_over_part_max, s.left_over_part_p95)),
             "over_model": _spread((s.over_model_max, s.over_model_p95)),
             "rapid_in_material": s.rapid_in_material, "below_part_moves": s.below_part_moves,
             "feed_length": s.feed_length, "air_feed_length": s.air_feed_length}
            for s in rp.stretches]


def plan_simulation(part: ZMap, tid: str, params: dict[str, Any], stored: tuple[list[str], int],
                    numbers: dict[int, str] | None, program: bytes | None,
                    stock: np.ndarray | float | None, tolerance: float | None
                    ) -> dict[str, Any]:
    """The plan computed again from its inputs, then its program (``numbers``: tool id by T
    number) or its passes simulated on the part. The planner is deterministic: the plan is
    the stored one (``stored``: its tool sequence and pass count, checked)."""
    tools = [Tool(t[0], "ball", t[1], t[2]) for t in params["tools"]]
    plan = plan_scanline(part, tools, tolerance=params["tolerance"],
                         stock_top=params["stock_top"])
    if (list(plan.tool_sequence), len(plan.stages)) != (list(stored[0]), stored[1]):
        raise RuntimeError(f"plan {tid} computed again differs from the stored one")
    tol = plan.tolerance if tolerance is None else tolerance
    by_id = {t.id: t for t in tools}
    notes: list[str] = []
    section: dict[str, Any] = {"task_id": tid, "tolerance": plan.tolerance,
                               "tool_sequence": list(plan.tool_sequence),
                               "rapid_in_material": None, "below_part_moves": None,
                               "program_ended": None}
    if program is not None and numbers is not None:
        prp = replay_program(part, plan, program.decode("ascii"),
                             {n: by_id[i] for n, i in numbers.items()}, stock)
        machined = prp.machined
        section.update(source="program", stages=_program_section(prp),
                       rapid_in_material=max(s.rapid_in_material for s in prp.stretches),
                       below_part_moves=sum(s.below_part_moves for s in prp.stretches),
                       program_ended=prp.ended)
        if section["rapid_in_material"] > 0:
            notes.append(f"a rapid goes {section['rapid_in_material']:.6g} mm into the stock")
    else:
        rpp = replay_passes(part, plan)
        machined = rpp.machined
        section.update(source="passes", stages=_passes_section(rpp))
        bad = [p.stage for p in rpp.passes if not p.flute_rule_ok]
        if bad:
            notes.append(f"passes {bad} meet more stock than their flutes")
    cut = gouge(part.z, machined)
    # a few ulps of the heights in play are rounding, not a cut (the planner's guard)
    if cut > 64.0 * float(np.finfo(np.float64).eps) * max(1.0, float(np.abs(machined).max())):
        notes.append(f"the plan cuts up to {cut:.6g} mm into the part")
    rest = rest_material(machined, part.z, part.cell_area)
    regions = rest_regions(machined, part, tol)
    return {
        "interpolation": "bilinear", "tool": None,
        "stock_top": plan.stock_top if stock is None else
        (float(stock) if np.ndim(stock) == 0 else None),
        "cl_source": f"plan_{section['source']}",
        "machined": canonical_grid(machined, x0=part.x0, y0=part.y0, dx=part.dx, dy=part.dy,
                                   interpolation="bilinear"),
        "gouge": cut,
        "rest": {"max": rest.max, "p95": rest.p95, "mean": rest.mean, "volume": rest.volume,
                 "area_fraction": regions.area_fraction},
        "depth_of_cut": None, "plan": section, "notes": notes}


async def simulate_plan_task(body: SimulateRequest, request: Request, settings: Settings,
                             store: TaskStore, pool: ComputePool, respond_async: bool
                             ) -> Response:
    """``POST /v1/simulate`` with a plan's task id."""
    tid = str(body.task_id)
    if body.cl is not None or body.tool is not None or body.interpolation != "bilinear":
        _plan_options(body, program=True)  # before any store access: the request alone
    result, inputs = await _stored_plan(store, settings, tid)
    params = inputs["params"]
    stored = (list(result["tool_sequence"]), len(result["stages"]))
    has_program = "toolpaths" in result
    _plan_options(body, program=has_program)
    part = await anyio.to_thread.run_sync(_plan_part, body, settings.max_grid_cells, tid,
                                          params)
    program = numbers = None
    if has_program:
        program = await anyio.to_thread.run_sync(store.get, program_key(tid))
        if program is None:
            raise _plan_problem(404, "Not found", "task_id", "the plan's NC program is no "
                                "longer stored: send the plan request again, then this one",
                                "no-program")
        numbers = {int(s["tool_number"]): str(s["tool_id"])
                   for s in result["toolpaths"]["stages"]}
    stock: np.ndarray | float | None = None
    if body.stock is not None or body.stock_top is not None:
        stock = await anyio.to_thread.run_sync(_stock, body, part, settings.max_grid_cells,
                                               0.0)
    sim_params = {"plan_task": tid, "stock_digest": await anyio.to_thread.run_sync(_digest, stock),
                  "stock_top": stock if isinstance(stock, float) else None,
                  "tolerance": body.tolerance}
    return await serve_task(
        request, store, pool, operation="simulate", params=sim_params, arrays=None,
        compute=lambda: plan_simulation(part, tid, params, stored, numbers, program, stock,
                                        body.tolerance),
        encoding=grid_encoding(body.grid), respond_async=respond_async,
        memory=part.z.size * SIMULATE_PLAN_BYTES)
