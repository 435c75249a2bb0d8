"""Models of ``POST /v1/mrr``."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field, StrictBool, StrictInt

from service.schemas.common import Grid, GridOut, GridTask, StrictModel


class MrrRequest(StrictModel):
    grid: Grid | None = Field(None, description="the z-map; or grid_task")
    grid_task: GridTask = None
    wavelet: Literal["haar", "single_knot"] = Field(
        "haar", description="haar: flat cells (contour machining); single_knot: bilinear "
        "(scan-line machining)")
    levels: StrictInt | None = Field(None, ge=0, le=64,
                               description="analysis steps to take; default: all")
    include_models: StrictBool = Field(False, description="return every level's grid")


class MrrLevel(BaseModel):
    level: int = Field(description="0 is the coarsest; the input is the last level")
    nx: int
    ny: int
    dx: float = Field(description="node spacing along x at this level, mm")
    dy: float
    padding: tuple[int, int] = Field(
        description="[rows, columns] appended (edge repeated) before this level was halved")
    containment_margin: float = Field(
        description="min over input nodes of this level minus the input, in the level's "
        "own interpolation; >= 0 means no overcut")
    max_abs_detail: float = Field(
        description="largest |detail| refining this level; 0 at the input")
    nonzero_details: int = Field(description="non-zero detail coefficients refining this level")
    grid: GridOut | None = None


class MrrResult(BaseModel):
    task_id: str
    operation: Literal["mrr"]
    wavelet: Literal["haar", "single_knot"]
    lifted: bool
    interpolation: Literal["bilinear", "cell"]
    depth: int = Field(description="number of analysis steps J")
    levels: list[MrrLevel] = Field(description="from the coarsest to the input")
