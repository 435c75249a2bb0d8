"""Models of ``POST /v1/simulate``: one tool machining a stock over a z-map."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field

from service.schemas.common import FiniteFloat, Grid, GridOut, StrictModel, ToolKind


class SimTool(StrictModel):
    """The end mill simulated."""

    id: str = Field("tool", min_length=1, max_length=64)
    kind: ToolKind = Field(description="ball or flat end mill")
    diameter: FiniteFloat = Field(ge=0.01, le=1000, description="mm")
    flute_length: FiniteFloat = Field(ge=0.01, le=1000, description="length of cut, mm")


class SimulateRequest(StrictModel):
    grid: Grid = Field(description="the part")
    interpolation: Literal["bilinear", "cell"] = Field(
        "bilinear", description="meaning of the part, stock and returned grids: bilinear "
        "between nodes (ball end mills, scan-line models) or flat cells (terraces)")
    tool: SimTool | None = Field(None, description="required")
    stock_top: FiniteFloat | None = Field(
        None, description="flat stock top, mm; default: part top + the tool's flute length")
    stock: Grid | None = Field(
        None, description="stock before the pass, on the part's nodes (same shape, origin and "
        "spacing), at or above the part; instead of stock_top")
    cl: Grid | None = Field(
        None, description="tool tip heights, one position per node of the part's grid (same "
        "shape, origin and spacing); default: the drop-cutter CL, so the tool machines "
        "everywhere it can (a morphological closing)")
    tolerance: FiniteFloat = Field(
        0.01, ge=1e-6, description="rest material above this counts toward rest_area_fraction")


class RestOut(BaseModel):
    max: float = Field(description="mm")
    p95: float = Field(description="95th percentile over the part's nodes, mm")
    mean: float = Field(description="mm")
    volume: float = Field(description="mm³")
    area_fraction: float = Field(description="share of nodes more than tolerance above the part")


class DepthOut(BaseModel):
    max: float = Field(description="highest stock inside the tool's cylinder above its tip, mm")
    mean: float = Field(description="over the positions that cut, mm")
    flute_length: float
    flute_length_ok: bool


class SimulateResult(BaseModel):
    task_id: str
    operation: Literal["simulate"]
    interpolation: Literal["bilinear", "cell"]
    tool: SimTool
    stock_top: float | None = Field(description="the flat stock top used, or null for a grid")
    cl_source: Literal["request", "drop_cutter"]
    machined: GridOut = Field(description="simulated stock after the pass")
    gouge: float = Field(description="max of part minus machined surface, mm (0: no gouge)")
    rest: RestOut = Field(description="machined surface over the part")
    depth_of_cut: DepthOut
    notes: list[str]
