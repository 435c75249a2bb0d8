"""``POST /v1/arcs``: a tangent-continuous chain of arcs and lines through a point curve."""

from __future__ import annotations

import hashlib
import io
import json
import math
from collections.abc import Callable
from typing import Annotated, Any

import anyio
import numpy as np
from fastapi import APIRouter, Depends, Query, Request, Response
from fastapi.exceptions import RequestValidationError
from pydantic import Field, ValidationError

from service import cadfiles
from service.deps import PoolDep, PreferAsyncDep, SettingsDep, StoreDep
from service.problems import Problem
from service.routers import if_none_match, responses
from service.schemas.arcs import ArcsRequest, ArcsResult
from service.schemas.cadfiles import DxfArcsResult, GcodeArcsResult
from service.settings import Settings
from service.store import TaskStore
from service.tasks import response_bytes, serve_task
from zwcore.arcs.fit import ArcChain, Segment, fit_arcs
from zwcore.arcs.gcode import rounding_budget, to_gcode
from zwcore.arcs.offset import offset_chain
from zwcore.errors import InvalidInputError, LimitExceededError

#: Estimated peak memory per point (a worker process's fit and its dense check).
ARC_POINT_BYTES = 4096

router = APIRouter(prefix="/v1", tags=["arcs"])


def _segment(s: Segment) -> dict[str, Any]:
    out: dict[str, Any] = {"kind": s.kind, "start": list(s.start), "end": list(s.end)}
    if s.kind == "arc":
        out.update(center=list(s.center or ()), radius=s.radius, ccw=s.ccw, sweep=s.sweep)
    return out


def arcs_result(points: np.ndarray, body: ArcsRequest) -> dict[str, Any]:
    """The ``/v1/arcs`` result (module level and plain arguments: it runs in a worker
    process, fitting being Python-bound)."""
    # the program as rounded stays within the tolerance: its rounding is budgeted
    chain: ArcChain = fit_arcs(points, body.tolerance, closed=body.closed,
                               corner_angle_deg=body.corner_angle_deg,
                               max_radius=body.max_radius,
                               reserve=rounding_budget(4) if body.gcode else 0.0,
                               seam=body.seam)
    result: dict[str, Any] = {
        "tolerance": body.tolerance, "closed": body.closed,
        "segments": [_segment(s) for s in chain.segments],
        "summary": {
            "n_segments": len(chain.segments), "n_arcs": chain.n_arcs, "n_lines": chain.n_lines,
            "max_deviation_points": chain.max_deviation_points,
            "max_deviation_chain": chain.max_deviation_chain,
            "max_kink_smooth_deg": math.degrees(chain.max_kink_smooth),
            "corners": list(chain.corners)},
        "seam": {"mode": body.seam, "index": chain.seam_index,
                 "start": list(chain.segments[0].start), "reversed": chain.seam_reversed},
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


#: The three bodies ``POST /v1/arcs`` reads, and what it answers.
ArcsAnyResult = Annotated[ArcsResult | GcodeArcsResult | DxfArcsResult,
                          Field(discriminator="operation")]
# Files are declared as one octet-stream body (what client generators support); the
# service also takes them as text/plain (a program) and application/dxf (a drawing).
_OPENAPI_EXTRA = {"requestBody": {"required": True, "content": {
    "application/json": {"schema": {"$ref": "#/components/schemas/ArcsRequest"}},
    "application/octet-stream": {"schema": {"type": "string", "format": "binary"}},
}}}
_FILE_RESPONSES: dict[int | str, dict[str, Any]] = {200: {"content": {
    "text/plain": {"schema": {"type": "string"}},
    cadfiles.DXF_MEDIA_TYPE: {"schema": {"type": "string"}}},
    "description": "JSON; or with `Accept: text/plain` the rewritten program, with "
                   "`Accept: application/dxf` the DXF"}}
#: Models the OpenAPI document lists although no route parameter names them.
OPENAPI_MODELS = (ArcsRequest,)
Tolerance = Annotated[float | None, Query(
    gt=0, allow_inf_nan=False,
    description="program or drawing only: two-sided band, in the file's units (default 0.01)")]
CornerAngle = Annotated[float | None, Query(
    gt=0, lt=180, allow_inf_nan=False,
    description="program or drawing only: turns sharper than this stay sharp (default 30)")]
MaxRadius = Annotated[float | None, Query(
    gt=0, allow_inf_nan=False,
    description="program only: arcs flatter than this radius become lines")]


def _with_files(declared: dict[int | str, dict[str, Any]]) -> dict[int | str, dict[str, Any]]:
    """``responses()`` with the 200 also offering the files (its headers kept)."""
    return {**declared, 200: {**declared.get(200, {}), **_FILE_RESPONSES[200]}}


def _media_type(request: Request) -> str:
    return request.headers.get("content-type", "application/json").split(";")[0].strip().lower()


def _json_body(raw: bytes) -> ArcsRequest:
    """The JSON body validated as FastAPI would (stdlib JSON, Python-mode validation)."""
    if not raw.strip():
        raise RequestValidationError([{"type": "missing", "loc": ("body",),
                                       "msg": "Field required", "input": None}])
    try:
        data = json.loads(raw)
    except (ValueError, RecursionError) as exc:
        raise RequestValidationError([{"type": "json_invalid", "loc": ("body", 0),
                                       "msg": "JSON decode error", "input": {},
                                       "ctx": {"error": str(exc)[:200]}}]) from None
    try:
        return ArcsRequest.model_validate(data)
    except ValidationError as exc:
        raise RequestValidationError(
            [{**e, "loc": ("body", *e["loc"])} for e in exc.errors()]) from None


def _wants(request: Request, media_type: str) -> bool:
    accept = request.headers.get("accept", "")
    return any(part.split(";")[0].strip().lower() == media_type for part in accept.split(","))


async def _as_file(response: Response, field: str, media_type: str) -> Response:
    if response.status_code != 200:
        return response
    text = json.loads(await response_bytes(response))[field]
    return Response(text, media_type=media_type, headers={
        k: v for k, v in response.headers.items() if k.lower() in ("etag", "x-cache")})


async def _points_arcs(raw: bytes, request: Request, settings: Settings, store: TaskStore,
                       pool: PoolDep, respond_async: bool) -> Response:
    # parsed and validated in a worker thread: the event loop never waits on a large body
    body = await anyio.to_thread.run_sync(_json_body, raw)
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
    # (the default seam is left out of the task id: a request of before the option names
    # the same task; the core's build in every task id already keeps old results apart)
    params = body.model_dump(exclude={"points"} | ({"seam"} if body.seam == "first_point"
                                                   else set()))
    response = await serve_task(request, store, pool, operation="fit_arcs", params=params,
                                arrays={"points": points}, compute=arcs_result,
                                args=(points, body.model_copy(update={"points": []})),
                                in_process=True, respond_async=respond_async,
                                memory=len(points) * ARC_POINT_BYTES)
    await _keep_input(request, response, store, lambda: _npy(points))
    return response


def _npy(points: np.ndarray) -> bytes:
    out = io.BytesIO()
    np.save(out, points, allow_pickle=False)
    return out.getvalue()


async def _keep_input(request: Request, response: Response, store: TaskStore,
                      encode: Callable[[], bytes]) -> None:
    """Store the input beside a freshly computed result: previews draw the chain over it."""
    if response.status_code == 200 and response.headers.get("x-cache") in ("miss", "shared"):
        tid = request.state.task_id
        await anyio.to_thread.run_sync(store.put, cadfiles.input_key(tid), encode())


def _decode_text(raw: bytes) -> str:
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        return raw.decode("latin-1")  # old controls' programs; every byte is a character


@router.post("/arcs", response_model=ArcsAnyResult, operation_id="fit_arcs",
             summary="Fit C1 chains of arcs and lines: a point curve, a G-code program or a DXF",
             responses=_with_files(responses(202, 413, 415, conditional=True)),
             dependencies=[Depends(if_none_match)], openapi_extra=_OPENAPI_EXTRA)
async def post_arcs(request: Request, settings: SettingsDep, store: StoreDep, pool: PoolDep,
                    respond_async: PreferAsyncDep, tolerance: Tolerance = None,
                    corner_angle_deg: CornerAngle = None, max_radius: MaxRadius = None) -> Response:
    """Fewest arcs and lines within ``tolerance`` of the polyline, both ways, joined
    tangentially except at real corners.

    - JSON (`ArcsRequest`): one point curve; G02/G03/G01 on request.
    - `text/plain` (or `application/octet-stream`, told apart from a DXF by its first
      lines): a G-code program; every run of G01 moves in the XY plane at constant Z
      becomes a chain, everything else stays in place (options as query parameters). The
      answer holds the rewritten program and a summary; `Accept: text/plain` gets the
      program alone.
    - `application/dxf` (also `image/vnd.dxf`, or `application/octet-stream`): an ASCII
      DXF; its LWPOLYLINE, POLYLINE and SPLINE entities become chains of LINE and ARC
      entities (bulges and ARC entities stay arcs). `Accept: application/dxf` gets the DXF alone.
    """
    raw = await request.body()
    kind = _media_type(request)
    if kind == "application/json" or kind.endswith("+json"):
        if tolerance is not None or corner_angle_deg is not None or max_radius is not None:
            raise InvalidInputError("query", "with a JSON body, options go in the body")
        return await _points_arcs(raw, request, settings, store, pool, respond_async)
    if kind == "application/octet-stream":
        kind = cadfiles.sniff(raw)
    tol = 0.01 if tolerance is None else tolerance
    corner = 30.0 if corner_angle_deg is None else corner_angle_deg
    limits = (settings.max_points, settings.max_arc_resolution)
    if kind in cadfiles.GCODE_TYPES:
        # reading costs per line: bound the lines as the point curve's points are bounded
        lines = raw.count(b"\n") + 1
        if lines > settings.max_points:
            raise LimitExceededError(
                "body", f"{lines} program lines exceed the limit of {settings.max_points}")
        text = await anyio.to_thread.run_sync(_decode_text, raw)
        response = await serve_task(
            request, store, pool, operation="arcs_gcode",
            params={"tolerance": tol, "corner_angle_deg": corner, "max_radius": max_radius,
                    "program_sha256": hashlib.sha256(text.encode()).hexdigest()},
            arrays=None, compute=cadfiles.gcode_result,
            args=(text, tol, corner, max_radius, *limits), in_process=True,
            respond_async=respond_async)
        await _keep_input(request, response, store, text.encode)
        return await _as_file(response, "program", "text/plain") if _wants(
            request, "text/plain") else response
    if kind in cadfiles.DXF_TYPES:
        if max_radius is not None:
            raise InvalidInputError("max_radius", "applies to programs and point curves only")
        response = await serve_task(
            request, store, pool, operation="arcs_dxf",
            params={"tolerance": tol, "corner_angle_deg": corner,
                    "dxf_sha256": hashlib.sha256(raw).hexdigest()},
            arrays=None, compute=cadfiles.dxf_result,
            args=(raw, tol, corner, *limits), in_process=True, respond_async=respond_async)
        wanted = next((t for t in cadfiles.DXF_TYPES if _wants(request, t)), None)
        return await _as_file(response, "dxf", wanted) if wanted else response
    raise Problem(415, "Unsupported media type",
                  f"body of type {kind!r}: send application/json (points), text/plain "
                  "(a G-code program) or application/dxf (a DXF drawing)",
                  kind="unsupported-media-type",
                  errors=[{"field": "content-type", "reason": f"{kind!r} is not read here"}])
