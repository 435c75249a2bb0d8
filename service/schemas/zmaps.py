"""Models of ``POST /v1/zmaps`` (STL to z-map)."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field

from service.schemas.common import GridOut


class ZMapParams(BaseModel):
    """How to lay the grid over the mesh: a cell size (``dx``, optional ``dy``) or a
    shape (``nx`` and ``ny``); query parameters, or form fields beside a multipart upload."""

    model_config = {"extra": "forbid"}

    dx: float | None = Field(None, ge=1e-6, le=1e6, allow_inf_nan=False,
                             description="node spacing along x, mm (or give nx and ny)")
    dy: float | None = Field(None, ge=1e-6, le=1e6, allow_inf_nan=False,
                             description="node spacing along y, mm; default dx")
    nx: int | None = Field(None, ge=2, le=1 << 20, description="nodes along x (with ny)")
    ny: int | None = Field(None, ge=2, le=1 << 20, description="nodes along y (with nx)")
    x0: float | None = Field(None, ge=-1e6, le=1e6, allow_inf_nan=False,
                             description="x of node (0, 0), mm; default the mesh's smallest x")
    y0: float | None = Field(None, ge=-1e6, le=1e6, allow_inf_nan=False,
                             description="y of node (0, 0), mm; default the mesh's smallest y")
    background: float | None = Field(
        None, ge=-1e6, le=1e6, allow_inf_nan=False,
        description="height of nodes outside the part, mm; default the mesh's lowest point")
    grid_encoding: Literal["rows", "float32", "float64"] = Field(
        "float64", description="encoding of the returned grid: rows, or base64 of this dtype")


class MeshBounds(BaseModel):
    min: tuple[float, float, float] = Field(description="[x, y, z] of the mesh, mm")
    max: tuple[float, float, float]


class ZMapResult(BaseModel):
    task_id: str
    operation: Literal["zmap"]
    grid: GridOut = Field(description="the z-map (bilinear): highest surface point above "
                          "each node; as .npy from GET /v1/tasks/{task_id}/models/0")
    background: float = Field(description="height given to nodes outside the part, mm")
    background_source: Literal["request", "default"] = Field(
        description="default: the mesh's lowest point")
    triangles: int = Field(description="triangles in the STL")
    triangles_used: int = Field(description="triangles with a footprint in the xy-plane "
                                "(vertical ones add nothing)")
    bounds: MeshBounds
    covered_nodes: int = Field(description="nodes some triangle lies above")
    undercut_nodes: int = Field(description="nodes above which a surface hides under the top "
                                "one (the line meets the mesh at three or more heights)")
    undercut_area: float = Field(description="undercut_nodes x dx x dy, mm²")
    notes: list[str]
