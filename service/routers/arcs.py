"""``POST /v1/arcs``: a tangent-continuous chain of arcs and lines through a point curve."""

from __future__ import annotations

import math
from typing import Any

import anyio
import numpy as np
from fastapi import APIRouter, Request, Response

from service.deps import PoolDep, SettingsDep, StoreDep
from service.routers import responses
from service.schemas.arcs import ArcsRequest, ArcsResult
from service.tasks import serve_task
from zwcore.arcs.fit import ArcChain, Segment, fit_arcs
from zwcore.arcs.gcode import to_gcode
from zwcore.arcs.offset import offset_chain
from zwcore.errors import LimitExceededError

router = APIRouter(prefix="/v1", tags=["arcs"])


def _segment(s: Segment) -> dict[str, Any]:
    out: dict[str, Any] = {"kind": s.kind, "start": list(s.start), "end": list(s.end)}
    if s.kind == "arc":
        out.update(center=list(s.center or ()), radius=s.radius, ccw=s.ccw, sweep=s.sweep)
    return out


def arcs_result(points: np.ndarray, body: ArcsRequest) -> dict[str, Any]:
    """The ``/v1/arcs`` result (module level and plain arguments: it runs in a worker
    process, fitting being Python-bound)."""
    chain: ArcChain = fit_arcs(points, body.tolerance, closed=body.closed,
                               corner_angle_deg=body.corner_angle_deg,
                               max_radius=body.max_radius)
    result: dict[str, Any] = {
        "tolerance": body.tolerance, "closed": body.closed,
        "segments": [_segment(s) for s in chain.segments],
        "summary": {
            "n_segments": len(chain.segments), "n_arcs": chain.n_arcs, "n_lines": chain.n_lines,
            "max_deviation_points": chain.max_deviation_points,
            "max_deviation_chain": chain.max_deviation_chain,
            "max_kink_smooth_deg": math.degrees(chain.max_kink_smooth),
            "corners": list(chain.corners)},
    }
    path = chain
    if body.offset != 0.0:
        path, vanished, reversed_ = offset_chain(chain, body.offset)
        result["offset"] = {"distance": body.offset,
                            "segments": [_segment(s) for s in path.segments],
                            "vanished_arcs": list(vanished),
                            "reversed_segments": list(reversed_)}
    if body.gcode:
        result["gcode"] = to_gcode(path, feed=body.feed)
    return result


def _as_points(points: list[tuple[float, float]]) -> np.ndarray:
    return np.asarray(points, dtype=np.float64).reshape(-1, 2)


@router.post("/arcs", response_model=ArcsResult, operation_id="fit_arcs",
             summary="Fit a C1 chain of arcs and lines to a point curve", responses=responses(413))
async def post_arcs(body: ArcsRequest, request: Request, settings: SettingsDep, store: StoreDep,
                    pool: PoolDep) -> Response:
    """Fewest arcs and lines within ``tolerance`` of the polyline, both ways, joined
    tangentially except at real corners; G02/G03/G01 on request."""
    if len(body.points) > settings.max_points:
        raise LimitExceededError(
            "points", f"{len(body.points)} points exceed the limit of {settings.max_points}")
    points = await anyio.to_thread.run_sync(_as_points, body.points)
    # The fit and its dense two-sided check sample the curve at a fraction of the
    # tolerance: bound length / tolerance so no request can ask for unbounded work.
    length = float(np.hypot(*np.diff(points, axis=0).T).sum())
    if length / body.tolerance > settings.max_arc_resolution:
        raise LimitExceededError(
            "tolerance", f"curve length {length:.6g} mm over tolerance {body.tolerance:g} mm "
            f"exceeds {settings.max_arc_resolution:g}; use a larger tolerance")
    params = body.model_dump(exclude={"points"})
    return await serve_task(request, store, pool, operation="arcs", params=params,
                            arrays={"points": points}, compute=arcs_result,
                            args=(points, body.model_copy(update={"points": []})),
                            in_process=True)
