"""``POST /v1/mrr``: the lifted wavelet multiresolution representation of a z-map."""

from __future__ import annotations

from typing import Any

import numpy as np
from fastapi import APIRouter, Request, Response

from service.deps import PoolDep, SettingsDep, StoreDep
from service.grids import canonical_grid
from service.routers import responses
from service.schemas.mrr import MrrRequest, MrrResult
from service.tasks import serve_task
from service.uploads import GridRoute, binary_grid_openapi, request_zmap
from zwcore import ZMap, analyse, at_fine_nodes

router = APIRouter(prefix="/v1", tags=["mrr"], route_class=GridRoute)


def _haar_margins(mrr_approx: list[np.ndarray], z: np.ndarray) -> list[float]:
    # Cell semantics: min over a block of (cell - node) = cell - block maximum, so an
    # independent max pyramid of the input gives every level's margin in O(N).
    margins = []
    blockmax = z
    for level in reversed(mrr_approx):
        margins.append(float((level - blockmax).min()))
        ny, nx = blockmax.shape
        padded = np.pad(blockmax, ((0, ny % 2), (0, nx % 2)), mode="edge")
        blockmax = np.maximum(np.maximum(padded[0::2, 0::2], padded[0::2, 1::2]),
                              np.maximum(padded[1::2, 0::2], padded[1::2, 1::2]))
    return margins[::-1]


def mrr_result(zmap: ZMap, wavelet: str, levels: int | None, include_models: bool
               ) -> dict[str, Any]:
    mrr = analyse(zmap.z, wavelet, levels=levels)
    J = mrr.depth
    if mrr.wavelet == "haar":
        margins = _haar_margins(mrr.approximations, zmap.z)
    else:
        margins = [float((at_fine_nodes(a, mrr.scale(j), zmap.shape, "bilinear") - zmap.z).min())
                   for j, a in enumerate(mrr.approximations)]
    out = []
    for j, approx in enumerate(mrr.approximations):
        s = mrr.scale(j)
        bands = mrr.details[j] if j < J else None
        # Padding is applied to a level before it is halved into level j - 1.
        padding = mrr.details[j - 1].padding if j > 0 else (0, 0)
        entry: dict[str, Any] = {
            "level": j, "ny": int(approx.shape[0]), "nx": int(approx.shape[1]),
            "dx": zmap.dx * s, "dy": zmap.dy * s, "padding": list(padding),
            "containment_margin": margins[j],
            "max_abs_detail": bands.max_abs() if bands else 0.0,
            "nonzero_details": bands.count_nonzero() if bands else 0,
        }
        if include_models:
            # Haar level values sit at the centre of their 2**s block of input nodes.
            off = (s - 1) / 2 if mrr.wavelet == "haar" else 0.0
            entry["grid"] = canonical_grid(
                approx, x0=zmap.x0 + off * zmap.dx, y0=zmap.y0 + off * zmap.dy,
                dx=zmap.dx * s, dy=zmap.dy * s, interpolation=mrr.interpolation)
        out.append(entry)
    return {"wavelet": mrr.wavelet, "lifted": mrr.lifted, "interpolation": mrr.interpolation,
            "depth": J, "levels": out}


@router.post("/mrr", response_model=MrrResult, operation_id="compute_mrr",
             summary="Multiresolution representation of a z-map", responses=responses(413, 415),
             openapi_extra=binary_grid_openapi(MrrRequest))
async def compute_mrr(body: MrrRequest, request: Request, settings: SettingsDep,
                      store: StoreDep, pool: PoolDep) -> Response:
    """Lifted (overcut-free) Haar or single-knot MRR: every level contains the part."""
    zmap, encoding = await request_zmap(request, body.grid, body.grid_task, settings, store)
    params = {"grid": [zmap.x0, zmap.y0, zmap.dx, zmap.dy], "wavelet": body.wavelet,
              "levels": body.levels, "include_models": body.include_models}
    return await serve_task(
        request, store, pool, operation="mrr", params=params, arrays={"z": zmap.z},
        compute=lambda: mrr_result(zmap, body.wavelet, body.levels, body.include_models),
        encoding=encoding)
