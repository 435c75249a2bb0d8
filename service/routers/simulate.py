"""``POST /v1/simulate``: what a tool really leaves and engages, from cutting simulation."""

from __future__ import annotations

import hashlib
from typing import Any

import anyio
import numpy as np
from fastapi import APIRouter, Request, Response

from service.deps import PoolDep, SettingsDep, StoreDep
from service.grids import canonical_grid, decode_grid, grid_encoding
from service.hashing import canonical_bytes
from service.routers import responses
from service.schemas.common import Grid
from service.schemas.simulate import SimulateRequest, SimulateResult
from service.tasks import serve_task
from zwcore import Tool, ZMap
from zwcore.errors import InvalidInputError, LimitExceededError
from zwcore.grid.zmap import Interpolation, stock_top_at_or_above
from zwcore.sim import rest_regions, simulate_pass, simulation_work

router = APIRouter(prefix="/v1", tags=["simulate"])


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
                                + (" (a CL grid needs its tool)" if body.cl is not None else ""))
    part = decode_grid(body.grid, max_cells)
    t = body.tool
    tool = Tool(t.id, t.kind, t.diameter, t.flute_length)
    work = simulation_work(part.shape, tool, part.dx, part.dy)
    if work > max_work:
        raise LimitExceededError("tool.diameter", f"a Ø{t.diameter:g} tool over a "
                                 f"{part.shape[0]} x {part.shape[1]} grid at {part.dx:g} mm "
                                 f"needs {work:.3g} node-offset steps, more than {max_work}")
    if body.stock is not None and body.stock_top is not None:
        raise InvalidInputError("stock", "give stock or stock_top, not both")
    stock: np.ndarray | float
    if body.stock is not None:
        stock = _aligned(body.stock, part, max_cells, "stock")
        below = stock < part.z
        if below.any():
            i, k = np.argwhere(below)[0]
            raise InvalidInputError("stock", f"lies below the part at {int(below.sum())} "
                                    f"node(s), first row {i}, column {k}")
    elif body.stock_top is not None:
        stock = stock_top_at_or_above(body.stock_top, float(part.z.max()))
    else:
        stock = float(part.z.max()) + tool.flute_length
    cl = _aligned(body.cl, part, max_cells, "cl") if body.cl is not None else None
    return part, tool, stock, cl


def _digest(grid: np.ndarray | float | None) -> str | None:
    if not isinstance(grid, np.ndarray):
        return None
    dtype, data = canonical_bytes(grid)
    return hashlib.sha256(f"{dtype}{list(grid.shape)}".encode() + data).hexdigest()


@router.post("/simulate", response_model=SimulateResult, operation_id="simulate",
             summary="Cutting simulation: the surface a tool leaves and what it engages",
             responses=responses(413))
async def post_simulate(body: SimulateRequest, request: Request, settings: SettingsDep,
                        store: StoreDep, pool: PoolDep) -> Response:
    """One ball or flat end mill machining a stock over a part, with its tip on a given CL
    grid or, without one, at the drop-cutter height everywhere (the closing). Returns the
    machined surface and its figures: gouge, rest over the part, real depth of cut and the
    flute-length rule. (A plan's task id as input is planned for a later release.)"""
    part, tool, stock, cl = await anyio.to_thread.run_sync(
        _inputs, body, settings.max_grid_cells, settings.max_simulation_work)
    # The stock and CL grids may come in another encoding than the part (whose encoding
    # serve_task trusts for float32 exactness): they enter the task id by their own digest.
    params = {"stock_digest": await anyio.to_thread.run_sync(_digest, stock),
              "cl_digest": await anyio.to_thread.run_sync(_digest, cl),
              "grid": [part.x0, part.y0, part.dx, part.dy], "interpolation": body.interpolation,
              "tool": [tool.id, tool.kind, tool.diameter, tool.flute_length],
              "stock_top": stock if not isinstance(stock, np.ndarray) else None,
              "tolerance": body.tolerance}
    return await serve_task(
        request, store, pool, operation="simulate", params=params, arrays={"z": part.z},
        compute=lambda: simulate_result(part, tool, stock, cl, body.interpolation,
                                        body.tolerance),
        encoding=grid_encoding(body.grid))
