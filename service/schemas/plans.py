"""Models of the plan operations: scan-line (ball end mills) and contour (flat end mills)."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field, StrictBool

from service.schemas.common import (
    FiniteFloat,
    Grid,
    GridOut,
    GridTask,
    StrictModel,
    ToolIn,
    ToolOut,
)
from service.schemas.toolpaths import ToolpathsOut


class ToolpathOptions(StrictModel):
    """Request fields shared by the plans for tool paths and the NC program."""

    toolpaths: StrictBool = Field(
        False, description="also compute tool paths, the NC program (GET "
        "/v1/tasks/{task_id}/program) and its verification by simulation")
    clearance: FiniteFloat | None = Field(
        None, description="safe height of rapids, mm; above the stock top (default: +5 mm)")
    rapid_feed: FiniteFloat = Field(15_000.0, gt=0, le=200_000,
                                    description="rapid rate for the time estimate, mm/min")


class ScanlinePlanRequest(ToolpathOptions):
    grid: Grid | None = Field(None, description="the z-map; or grid_task")
    grid_task: GridTask = None
    tools: list[ToolIn] | None = Field(
        None, description="ball end mills; default: the shipped library (GET /v1/tools)")
    tolerance: FiniteFloat = Field(
        0.01, ge=1e-6, description="finishing tolerance, mm: what the finished surface (the "
        "program's, with tool paths) may stand above the part where the plan finishes; the "
        "plan's scallops hold 70 % of it (scallop_tolerance in the response). At least "
        "1e-6: a finer one gave an infinite predicted scallop")
    stock_top: FiniteFloat | None = Field(
        None, description="top of the stock, mm; default: part top + first tool's flute length")
    include_models: StrictBool = Field(False, description="return each stage's model grid")


class RegionBoxOut(BaseModel):
    x_min: float
    y_min: float
    x_max: float
    y_max: float
    area: float = Field(description="mm²")


class ScanlineStageOut(BaseModel):
    index: int
    tool: ToolOut
    level: int
    spacing: tuple[float, float] = Field(description="[dx, dy] of the stage's level, mm")
    pick_feed: float = Field(description="smallest distance between scan lines, mm")
    pick_feed_max: float = Field(
        description="largest distance between adjacent lines over any cell, mm")
    pick_feed_reduced: bool
    pick_feed_reason: str | None = None
    reduced_strips: int = Field(description="strips between grid lines that got extra lines")
    scan_direction: Literal["x", "y"] = Field(description="scan lines run along this axis")
    scan_lines: int = Field(
        description="number of scan lines (an extra line counts once, whatever its segments)")
    steepest_slope_deg: float = Field(description="steepest slope of the stage model")
    cross_slope_deg: float = Field(
        description="steepest slope across the scan lines: the θ of the scallop rule")
    scallop_height: float = Field(description="predicted scallop at the pick-feed, mm")
    concave_radius: float | None = Field(
        description="smallest concave radius of the stage model, mm (null: no concave region)")
    max_depth_of_cut: float = Field(description="max of previous model minus this one, mm")
    mean_depth_of_cut: float = Field(description="removed volume over the grid area, mm")
    max_engagement: float = Field(
        description="model-node engagement incl. the previous stage's scallops and rest, mm "
        "(informative: the flute rule is on the simulated stock, sim_max_depth_of_cut)")
    rest_height: float = Field(description="material the ball cannot reach in corners, mm")
    removed_volume: float = Field(description="mm³")
    max_stock_left: float = Field(description="max height over the part after the stage, mm")
    pass_index: int = Field(description="1-based pass of this tool at this level")
    pass_count: int = Field(description="passes this tool makes at this level")
    passes: int = Field(description="same as pass_count")
    merged_levels: list[int] = Field(description="MRR levels that got this tool and merged")
    clipped_nodes: int = Field(
        description="level nodes clipped down to the previous stage (lift overshoot at walls)")
    raised_nodes: int = Field(description="level nodes raised again to restore containment")
    path_length: float = Field(
        description="length of the stage's scan lines, mm: the grid lines whole, extra lines "
        "only over the stretches whose slope needs them (plus one tool radius each side); "
        "moves between lines not counted")
    path_length_whole_strips: float = Field(
        description="path_length if every extra line ran its strip's whole length (the rule "
        "before extra lines were laid by region), mm")
    extra_segments: int = Field(description="segments of extra lines between the grid lines")
    model: GridOut | None = None
    # -- Simulated stock (issue 11 part 4): additive block, every field has a default.
    sim_positions: int = Field(0, description="tool positions simulated on the stage's "
                               "scan lines (inside its region when it has one)")
    sim_position_spacing: float = Field(
        0.0, description="distance between simulated positions along a line, mm")
    sim_max_depth_of_cut: float = Field(
        0.0, description="real depth of cut on the simulated stock: highest stock within the "
        "ball's radius of its axis minus its tip, largest over the positions, mm")
    sim_mean_depth_of_cut: float = Field(
        0.0, description="the same, mean over the positions that cut, mm")
    sim_flute_rule_ok: bool = Field(True, description="sim_max_depth_of_cut <= flute length")
    sim_lifted_nodes: int = Field(
        0, description="model nodes the flute rule on the simulated stock raised")
    sim_gouge: float = Field(
        0.0, description="max of part minus simulated stock after the stage, mm (0: none)")
    sim_left_over_next_max: float = Field(
        0.0, description="simulated stock after the stage minus the next stage's model "
        "(the part after the last stage): largest, mm")
    sim_left_over_next_p95: float = Field(0.0, description="the same, 95th percentile, mm")
    sim_left_over_part_max: float = Field(
        0.0, description="simulated stock after the stage minus the part: largest, mm")
    sim_left_over_part_p95: float = Field(0.0, description="the same, 95th percentile, mm")
    # --- tool choice by reach and rest regions (issue 11, parts 2-3) ---
    region_area_fraction: float = Field(
        1.0, description="share of the part's nodes this stage's ball machines (1: all)")
    region_boxes: list[RegionBoxOut] = Field(
        default_factory=list, description="bounding boxes of the region's connected parts "
        "(largest first, at most 64; empty when the stage machines the whole part)")
    region_count: int = Field(1, description="connected parts of the region")
    estimated_cut_length: float | None = Field(
        None, description="finishing stages: region area / the pick-feed that holds the "
        "tolerance on a flat, mm (what the choice of finishing balls minimises); null for "
        "roughing")
    reach_rest_max: float = Field(
        0.0, description="most material the ball leaves over its target in the reach "
        "simulation (finishing: over the part after it and the balls before), mm")
    reach_reason: str | None = Field(None, description="why this ball, from the simulation")
    region: GridOut | None = Field(
        None, description="with include_models: where the ball machines, 1 or 0 per node of "
        "the stage model's grid; null for a stage over the whole part")


class ScanlineReachOut(BaseModel):
    """The finishing balls chosen by simulated reach, and what none of them reaches."""

    finishing_tools: list[str] = Field(description="main finishing ball, then rest balls")
    finishing_cut_length: float = Field(
        description="estimated finishing cut length of those balls in their regions "
        "(area / flat pick-feed at the tolerance, plus 250 mm per tool change), mm")
    smallest_ball_cut_length: float = Field(
        description="the same estimate with the smallest library ball over the whole part, mm")
    cut_length_factor: float = Field(
        description="smallest_ball_cut_length / finishing_cut_length")
    unreachable_area: float = Field(
        description="area where even the last ball leaves more than the tolerance, mm²")
    unreachable_max_height: float = Field(description="most material left there, mm")
    needed_radius: float | None = Field(
        description="the part's smallest concave radius there: a ball that finishes it must "
        "be no larger, mm (null: nothing left)")


class ScanlineChecksOut(BaseModel):
    ok: bool
    containment: bool
    min_containment_margin: float
    depth_of_cut: bool = Field(description="the flute rule on the simulated stock: every "
                               "stage's real depth of cut (sim_max_depth_of_cut) is at most "
                               "its flute length")
    max_depth_over_flute: float | None = Field(
        description="largest sim_max_depth_of_cut minus flute length, mm (<= 0 when "
        "depth_of_cut holds; null: no stage cuts)")
    tool_radii_non_increasing: bool
    finishing_tolerance_met: bool
    last_model_is_part: bool
    tools_fit: bool = Field(description="informative: some library ball fits the sharpest "
                            "concave corner (false: the finishing ball leaves rest there)")
    # -- Simulated stock (issue 11 part 4): additive block, every field has a default.
    sim_no_gouge: bool = Field(True, description="the simulated stock never lies below the "
                               "part (to float rounding), after every stage")
    sim_max_gouge: float | None = Field(0.0, description="largest part minus simulated stock, mm")
    sim_left_over_part_max: float = Field(
        0.0, description="simulated stock after the last stage minus the part: largest, mm")
    sim_left_over_part_p95: float = Field(0.0, description="the same, 95th percentile, mm")
    models_nested: bool = Field(
        True, description="informative: every stage model lies at or under the one before "
        "(false where the flute rule lifted a stage above it)")
    max_model_rise: float = Field(0.0, description="largest rise of a stage model over the "
                                  "one before it, mm")


class ScanlinePlanResult(BaseModel):
    task_id: str
    operation: Literal["plan_scanline"]
    stock_top: float
    stock_top_source: Literal["request", "default"]
    tolerance: float
    scallop_tolerance: float = Field(
        description="the share of the tolerance the plan's scallops, rest regions and "
        "finished area hold (70 %), mm; the tool paths' chords take 25 % and 5 % is kept "
        "for their CL between the plan's positions, so the program stays within the "
        "tolerance where the plan finishes")
    cell_bound: bool = Field(
        description="whether small balls' drop-cutter CL (plan and tool paths) takes the "
        "ball's curvature under each cell of the z-map: on grids coarse for some ball of "
        "the library, where one plane per cell would stand more than scallop_tolerance "
        "above the surface")
    tool_sequence: list[str]
    stages: list[ScanlineStageOut]
    checks: ScanlineChecksOut
    notes: list[str]
    toolpaths: ToolpathsOut | None = None
    # --- tool choice by reach (issue 11, parts 2-3) ---
    reach: ScanlineReachOut | None = None


class ContourPlanRequest(ToolpathOptions):
    grid: Grid | None = Field(None, description="the z-map; or grid_task")
    grid_task: GridTask = None
    tools: list[ToolIn] | None = Field(
        None, description="flat end mills; default: the shipped library (GET /v1/tools)")
    stock_top: FiniteFloat | None = Field(
        None, description="top of the stock, mm; default: part top + first tool's flute length")
    strategy: Literal["uniform_load", "even_step"] = Field(
        "uniform_load", description="uniform_load: equal slab volumes (the seed's method); "
        "even_step: equal spacings")
    include_models: StrictBool = Field(False, description="return each stage's terraced model")
    tolerance: FiniteFloat = Field(0.05, ge=1e-4, le=10.0,
                                   description="arc fit tolerance of the tool paths, mm")
    stepover: FiniteFloat = Field(0.4, gt=0, le=0.5,
                                  description="clearing ring distance, fraction of the diameter")


class ContourStageOut(BaseModel):
    index: int
    tool: ToolOut
    level: int
    cell_size: tuple[float, float] = Field(description="[x, y] size of a model cell, mm")
    level_rule: str
    spacing_rule: str
    nominal_step: float | None = Field(description="target slab volume or step the rule aimed at")
    edited_coefficients: int = Field(description="Haar coefficients edited to make the terraces")
    z_levels: list[float] = Field(description="contour heights, descending, mm")
    spacings: list[float] = Field(description="distance between consecutive z_levels, mm")
    slab_volumes: list[float] = Field(description="volume each slab removes, mm³")
    volume_spread: float = Field(description="max/min - 1 over slabs the flute cap does not bind")
    flute_cap_binds: list[bool]
    removed_volume: float
    max_stock_left: float
    mean_stock_left: float
    model: GridOut | None = None


class ContourChecksOut(BaseModel):
    ok: bool
    containment: bool
    min_containment_margin: float
    spacings_positive: bool
    spacings_within_flute: bool
    max_volume_spread: float
    volumes_add_up: bool
    terraces_from_coefficients: bool


class ContourPlanResult(BaseModel):
    task_id: str
    operation: Literal["plan_contour"]
    stock_top: float
    stock_top_source: Literal["request", "default"]
    strategy: str
    contour_spacings: list[float]
    stages: list[ContourStageOut]
    checks: ContourChecksOut
    notes: list[str]
    toolpaths: ToolpathsOut | None = None
