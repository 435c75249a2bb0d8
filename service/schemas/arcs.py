"""Models of ``POST /v1/arcs``."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, Field, StrictBool

from service.schemas.common import FiniteFloat, StrictModel

Coordinate = Annotated[float, Field(strict=True, allow_inf_nan=False, ge=-1e6, le=1e6)]
Point = tuple[Coordinate, Coordinate]


class ArcsRequest(StrictModel):
    points: list[Point] = Field(min_length=2, description="ordered curve points [[x, y], ...], mm")
    tolerance: FiniteFloat = Field(0.1, gt=0, description="two-sided band half-width, mm")
    closed: StrictBool = Field(False, description="the curve closes on itself")
    corner_angle_deg: FiniteFloat = Field(
        30.0, gt=0, lt=180, description="turns sharper than this stay sharp corners")
    max_radius: FiniteFloat | None = Field(
        None, gt=0, description="arcs flatter than this radius become lines, mm")
    offset: FiniteFloat = Field(
        0.0, description="signed tool offset, mm (> 0: left of the direction of travel)")
    gcode: StrictBool = Field(False, description="also return the NC program")
    feed: FiniteFloat = Field(1000.0, gt=0, description="feed rate for the program, mm/min")
    seam: Literal["first_point", "free"] = Field(
        "first_point",
        description="where a closed chain starts: \"first_point\" at the first point; "
                    "\"free\" wherever fewer segments result (a curve with corners at its "
                    "first corner, a corner-free loop at a point of the input polyline, fitted "
                    "in either direction; the chain still runs in the input's direction, "
                    "`seam` in the result says where it starts). Open curves: no effect")


class SegmentOut(BaseModel):
    kind: Literal["arc", "line"]
    start: tuple[float, float]
    end: tuple[float, float]
    center: tuple[float, float] | None = None
    radius: float | None = None
    ccw: bool | None = None
    sweep: float | None = Field(None, description="signed sweep, rad (> 0 counter-clockwise)")


class ArcsSummary(BaseModel):
    n_segments: int
    n_arcs: int
    n_lines: int
    max_deviation_points: float = Field(description="max distance input polyline -> chain, mm")
    max_deviation_chain: float = Field(description="max distance chain -> input polyline, mm")
    max_kink_smooth_deg: float = Field(description="largest tangent kink at smooth junctions")
    corners: list[int] = Field(description="junctions kept sharp (i: between segment i and i+1)")


class SeamOut(BaseModel):
    mode: Literal["first_point", "free"] = Field(description="the request's `seam`")
    index: int = Field(
        description="input point the chain starts at (0 for \"first_point\"); when it "
                    "starts between two points, the first of them in the input's order")
    start: tuple[float, float] = Field(description="where the chain starts, mm")
    reversed: bool = Field(
        description="the chain was fitted to the reversed curve (fewer segments); it is "
                    "returned in the input's direction all the same")


class OffsetOut(BaseModel):
    distance: float
    segments: list[SegmentOut]
    vanished_arcs: list[int] = Field(
        description="arcs of the fitted chain whose radius would vanish or invert at this offset")
    reversed_segments: list[int] = Field(
        default_factory=list,
        description="segments of the fitted chain whose offset, trimmed at an inner corner, "
                    "runs backwards (a line whose direction flips, an arc that wraps the other "
                    "way): the offset is larger than the segment allows and the path gouges")


class ArcsResult(BaseModel):
    task_id: str
    operation: Literal["fit_arcs"]
    tolerance: float
    closed: bool
    segments: list[SegmentOut]
    summary: ArcsSummary
    seam: SeamOut
    offset: OffsetOut | None = None
    gcode: str | None = None
