"""Models of ``POST /v1/simulate``: one tool machining a stock over a z-map, or a stored
scan-line plan simulated again on its part."""

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
    tool: SimTool | None = Field(
        None, description="the end mill to simulate: required without task_id (and with a "
        "CL grid), refused with one (a plan's tools are its own)")
    task_id: str | None = Field(
        None, pattern="^[0-9a-f]{64}$", description="a finished scan-line plan "
        "(POST /v1/plans/scanline) to simulate on its part, which `grid` must be: its NC "
        "program read back and every move swept when it was planned with toolpaths: true, "
        "else its passes simulated again (the planner's stock simulation); instead of tool "
        "and cl")
    stock_top: FiniteFloat | None = Field(
        None, description="flat stock top, mm; default: part top + the tool's flute length "
        "(with task_id: the plan's stock top)")
    stock: Grid | None = Field(
        None, description="stock before the pass, on the part's nodes (same shape, origin and "
        "spacing), at or above the part; instead of stock_top (with task_id: only for a plan "
        "with toolpaths, whose program then runs on this stock)")
    cl: Grid | None = Field(
        None, description="tool tip heights, one position per node of the part's grid (same "
        "shape, origin and spacing); default: the drop-cutter CL, so the tool machines "
        "everywhere it can (a morphological closing)")
    tolerance: FiniteFloat | None = Field(
        None, ge=1e-6, description="rest material above this counts toward "
        "rest.area_fraction, mm; default 0.01 (with task_id: the plan's tolerance)")


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


class SpreadOut(BaseModel):
    max: float = Field(description="mm")
    p95: float = Field(description="95th percentile over the part's nodes, mm")


class PlanStageSimOut(BaseModel):
    """One pass of the plan (passes), or one tool stretch of its program (program)."""

    stages: list[int] = Field(description="indices of the plan's stages (passes) covered")
    tool: SimTool
    tool_number: int | None = Field(description="T word of the stretch (program); else null")
    positions: int | None = Field(description="tool positions simulated (passes); else null")
    moves: int | None = Field(description="program blocks of the stretch (program); else null")
    depth_of_cut: DepthOut | None = Field(
        description="real depth of cut on the simulated stock (passes); null for a program "
        "(its sweep measures removal, not the stock inside the cylinder)")
    gouge: float = Field(description="max of part minus the stock after it, mm")
    removed_volume: float = Field(description="mm³")
    left_over_next: SpreadOut = Field(
        description="stock after it minus the next pass's model (the part after the last)")
    left_over_part: SpreadOut = Field(description="stock after it minus the part")
    over_model: SpreadOut | None = Field(
        description="stock after the stretch minus its last pass's model (program); else null")
    rapid_in_material: float | None = Field(
        description="deepest a rapid went into the stock it met, mm (program; 0: in air)")
    below_part_moves: int | None = Field(
        description="moves whose sweep reaches below the part (program)")
    feed_length: float | None = Field(description="mm (program)")
    air_feed_length: float | None = Field(description="feed moves that met no material, mm "
                                          "(program)")


class PlanSimOut(BaseModel):
    task_id: str = Field(description="the plan simulated")
    source: Literal["program", "passes"] = Field(
        description="program: the plan's NC program read back (zwcore.toolpath.parse) and "
        "every move swept with its ball; passes: the plan's passes simulated again")
    tolerance: float = Field(description="the plan's finishing tolerance, mm")
    tool_sequence: list[str]
    stages: list[PlanStageSimOut]
    rapid_in_material: float | None = Field(description="largest over the program, mm "
                                            "(program); else null")
    below_part_moves: int | None = Field(description="program; else null")
    program_ended: bool | None = Field(description="the program ends with M30 (program)")


class SimulateResult(BaseModel):
    task_id: str
    operation: Literal["simulate"]
    interpolation: Literal["bilinear", "cell"]
    tool: SimTool | None = Field(description="the tool simulated; null for a plan")
    stock_top: float | None = Field(description="the flat stock top used, or null for a grid")
    cl_source: Literal["request", "drop_cutter", "plan_program", "plan_passes"]
    machined: GridOut = Field(description="simulated stock after the pass (or the plan)")
    gouge: float = Field(description="max of part minus machined surface, mm (0: no gouge)")
    rest: RestOut = Field(description="machined surface over the part")
    depth_of_cut: DepthOut | None = Field(description="of the one tool; null for a plan (see "
                                          "plan.stages)")
    plan: PlanSimOut | None = Field(None, description="with task_id: the plan's figures")
    notes: list[str]
