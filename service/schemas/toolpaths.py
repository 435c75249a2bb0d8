"""Tool paths and NC program in plan responses (issue 12)."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field


class ToolpathStageOut(BaseModel):
    index: int = Field(description="stage index in the plan")
    kind: Literal["scanline", "contour"]
    tool_id: str
    tool_number: int = Field(description="T and H word of the stage")
    spindle_rpm: float
    feed: float = Field(description="mm/min")
    plunge_feed: float = Field(description="mm/min, ramps and plunges")
    ramp_angle_deg: float
    moves: int = Field(description="blocks of the stage's path")
    rapid_length: float = Field(description="mm")
    feed_length: float = Field(description="mm at the cutting feed")
    plunge_length: float = Field(description="mm at the plunge feed")
    time_min: float = Field(description="estimate: lengths over their feeds, no acceleration")
    figures: dict[str, float] = Field(description="path figures (lines, points, rings, arcs...)")
    move_kinds_b64: str = Field(
        description="uint8 per block, base64: 0 rapid, 1 line, 2 clockwise arc, 3 ccw arc")
    points_b64: str = Field(description="float32 (moves, 3) tip end points, little-endian base64")
    centers_b64: str = Field(description="float32 (moves, 2) arc centres (NaN for non-arcs)")


class VerificationStageOut(BaseModel):
    tool_number: int
    moves: int
    over_model_max: float | None = Field(
        description="simulated stock minus the stage model after the stage, max, mm")
    over_model_p95: float | None
    gouge: float = Field(description="part minus simulated stock after the stage, max, mm")
    rapid_in_material: float = Field(description="deepest rapid into the stock, mm (0)")
    removed_volume: float = Field(description="mm³")
    air_feed_length: float = Field(description="feed moves that met no material, mm")
    feed_length: float
    below_part_moves: int


class VerificationOut(BaseModel):
    """The program parsed back (independent parser) and simulated on the stock at the
    input resolution with every move swept (arcs included)."""

    gouge: float = Field(description="max part minus machined over the nodes, mm; must be 0")
    below_part_moves: int = Field(description="moves reaching below the part (0)")
    final_over_part_max: float = Field(description="machined minus part, max over all the "
                                       "nodes, mm (corners no ball reaches included)")
    final_over_part_p95: float
    finished_over_part_max: float = Field(
        description="machined minus part, max where the plan's own simulation says it "
        "finishes (within the tolerance), mm")
    finished_area_fraction: float = Field(
        description="share of the part where the plan says it finishes")
    within_tolerance: bool = Field(
        description="finished_over_part_max <= tolerance: the program holds the tolerance "
        "wherever the plan says it finishes")
    rapid_in_material: float = Field(description="deepest rapid into the stock, mm (0)")
    arc_radius_mismatch: float = Field(description="max |r_start - r_end| of the arcs, mm")
    stages: list[VerificationStageOut]


class ToolpathsOut(BaseModel):
    clearance: float = Field(description="safe height of rapids, mm")
    rapid_feed: float = Field(description="mm/min, for the time estimate")
    length: float = Field(description="total path length, mm")
    time_min: float = Field(description="total machining time estimate, minutes")
    program_bytes: int
    program_url: str = Field(description="GET this for the NC program (text/plain)")
    cl_source: str = Field(description="how the CL heights were computed")
    timings: dict[str, float] = Field(description="seconds per phase")
    stages: list[ToolpathStageOut]
    verification: VerificationOut | None
