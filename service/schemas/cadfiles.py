"""Models of ``POST /v1/arcs`` with a G-code program or a DXF drawing as the body."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field

from service.schemas.arcs import SegmentOut


class GcodeRunOut(BaseModel):
    first_line: int = Field(description="1-based input line of the run's first G01 block")
    last_line: int = Field(description="1-based input line of the run's last G01 block")
    z: float = Field(description="the run's constant Z")
    moves_before: int
    moves_after: int
    rewritten: bool = Field(
        description="false: the chain had no fewer blocks than the run, which was kept verbatim")
    segments: list[SegmentOut] = Field(description="the chain (empty when not rewritten)")
    corners: list[int] = Field(description="junctions kept sharp (i: between segment i and i+1)")
    max_deviation_points: float = Field(description="max distance run polyline -> chain")
    max_deviation_chain: float = Field(description="max distance chain -> run polyline")


class GcodeSummary(BaseModel):
    moves_before: int = Field(description="motion blocks (G00..G03, canned cycles) in the input")
    moves_after: int = Field(description="motion blocks in the rewritten program")
    bytes_before: int
    bytes_after: int
    max_deviation: float = Field(
        description="largest two-sided deviation of any rewritten run from its G01 polyline")
    runs: int = Field(description="runs of two or more G01 moves in the XY plane at constant Z")
    runs_rewritten: int
    unparsable_lines: int = Field(
        description="lines not read as G-code: kept verbatim, and they end any run")
    unparsable_line_numbers: list[int] = Field(description="their 1-based numbers (first 1000)")
    decimals: int = Field(description="digits after the point in the written coordinates")


class GcodeArcsResult(BaseModel):
    """A G-code program whose G01 runs became C1 arc chains."""

    task_id: str
    operation: Literal["arcs_gcode"]
    tolerance: float
    program: str = Field(description="the rewritten program")
    summary: GcodeSummary
    runs: list[GcodeRunOut]
    notes: list[str]


class DxfChainOut(BaseModel):
    source: str = Field(description="DXF type of the source entity")
    handle: str = Field(description="the source entity's handle")
    layer: str
    closed: bool
    fitted: bool = Field(description="false: a LINE, ARC or CIRCLE passed through unchanged")
    segments: list[SegmentOut]
    points: list[tuple[float, float]] = Field(
        description="the polyline the chain was fitted to: the vertices, or the flattened "
                    "spline (its ends for a passed-through entity)")
    corners: list[int] = Field(
        description="junctions where the chain is not tangent-continuous (i: end of segment i)")
    max_deviation_points: float = Field(description="max distance source polyline -> chain")
    max_deviation_chain: float = Field(description="max distance chain -> source polyline")


class DxfSummary(BaseModel):
    entities: dict[str, int] = Field(description="model-space entities read, by DXF type")
    chains: int
    n_segments: int
    n_arcs: int
    n_lines: int
    max_deviation: float = Field(
        description="largest two-sided deviation of a fitted chain from its source curve "
                    "(splines: from their flattening, itself within a tenth of the tolerance)")


class DxfArcsResult(BaseModel):
    """A DXF drawing's curves as LINE and ARC entities."""

    task_id: str
    operation: Literal["arcs_dxf"]
    tolerance: float
    dxf: str = Field(description="the chains as a DXF (R2010) of LINE, ARC and CIRCLE entities")
    summary: DxfSummary
    chains: list[DxfChainOut]
    notes: list[str]
