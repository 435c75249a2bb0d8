"""Result types of the scan-line plan (see :mod:`zwcore.scanline.planner`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from zwcore.grid.sampling import bilinear_at_fine_nodes
from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap

__all__ = ["CHORD_SHARE", "PATH_ALLOWANCE", "SCALLOP_SHARE", "ReachSummary", "ScanLines",
           "ScanlineChecks", "ScanlinePlan", "ScanlineStage"]

# The finishing tolerance is what the *program* may leave where the plan finishes; the
# plan's simulated stock is exact at its positions' CL, the program is not: its points are
# thinned to a chordal tolerance (one-sided, up to that much above the dropped CL) and
# its CL between the plan's positions comes from other samples (rows interpolated, lifts
# out of gouges). So the tolerance is split, and the plan holds only its share (without
# the split the program left up to 12 % over the tolerance where the plan finished).
#: Share of ``tolerance`` the tool paths' chordal thinning takes.
CHORD_SHARE = 0.25
#: Share kept for the paths' CL between the plan's positions (measured up to 1.6 %).
PATH_ALLOWANCE = 0.05
#: Share the plan's scallops, rest regions and ``finished`` hold.
SCALLOP_SHARE = 1.0 - CHORD_SHARE - PATH_ALLOWANCE

F64 = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class ScanLines:
    """The scan lines of one pass, as straight segments.

    Positions are in mm from the grid's first node (``x0``, ``y0``). For lines
    along x, ``offset`` is the line's y and ``start``/``stop`` its x range;
    along y the other way round. Sorted by offset, then start.

    Attributes
    ----------
    direction : {"x", "y"}
    offset, start, stop : (n,) float64
    """

    direction: Literal["x", "y"]
    offset: F64
    start: F64
    stop: F64

    @property
    def length(self) -> float:
        """Total length of the segments, mm."""
        return float(np.sum(self.stop - self.start))


@dataclass(frozen=True, eq=False)
class ScanlineStage:
    """One pass of a ball end mill over a stage model.

    Attributes
    ----------
    tool : Tool
    level : int
        MRR level of the model (``depth`` is the input grid).
    spacing : (float, float)
        ``(dx, dy)`` of the level in mm.
    pick_feed : float
        Distance between adjacent scan lines in mm: the smallest one where
        strips are reduced, else the level's spacing across the lines.
    pick_feed_reduced : bool
        Whether ``pick_feed`` is below the level's spacing (in some strip).
    pick_feed_reason : str or None
        Why it was reduced.
    scan_direction : {"x", "y"}
        Direction the scan lines run in: the one with the shorter total path (walls
        are climbed along the lines rather than stepped across).
    scan_lines : int
        Number of scan lines across the part (strip by strip pick-feeds; an
        extra line counts once however many segments it has).
    steepest_slope_deg : float
        Steepest slope of the stage model (any direction).
    scallop_height : float
        Largest predicted scallop over the cells, each at the largest distance
        between the lines present over it, on its steepest slope across the
        lines (a bound for the design's
        ``R - sqrt(R^2 - (p / (2 cos theta))^2)``), in mm. For a pass the flute rule
        raised (``sim_lifted_nodes > 0``) the slopes are those its lines were laid on,
        before the lift.
    max_depth_of_cut, mean_depth_of_cut : float
        ``M_{k-1} - M_k`` over the input nodes (mean: removed volume over the
        grid's area), in mm: model differences (the real depth of cut is
        ``sim_max_depth_of_cut``).
    max_engagement : float
        Largest ``M_{k-1} + h_{k-1} + e_{k-1} - M_k``: the depth of cut plus the
        previous pass's scallops and rest, on the model nodes. Informative since the
        flute rule is on the simulated stock (``sim_max_depth_of_cut``): a ball does not
        follow every node of its model, so this may exceed the flute length where the
        simulated depth does not.
    rest_height : float
        Material the ball leaves in valleys of its model sharper than itself
        (0 when it fits the model's concave radius; a roughing ball may be
        larger when this is at most a quarter of the next flute length). Stock
        for the next pass, like the scallops.
    removed_volume : float
        Volume between ``M_{k-1}`` and ``M_k`` over the grid, mm³ (exact for
        the bilinear models: trapezoid rule on the input nodes).
    max_stock_left : float
        Largest ``M_k - part`` over the input nodes, mm.
    pass_index, pass_count : int
        This is pass ``pass_index`` (1-based) of ``pass_count`` passes with
        the same tool at the same level; more than one where the flute length
        could not reach the level model in one pass.
    concave_radius : float
        Smallest concave radius of the stage's level model (before the flute
        lift), mm; ``inf`` if it has no concave region.
    merged_levels : tuple of int
        Coarser levels that admitted the same tool and were merged into this
        stage.
    cross_slope_deg : float
        Steepest slope *across* the scan lines (the slope component along the
        pick-feed direction), the ``theta`` the scallop rule uses: scallops
        between two lines depend on the surface's section across them. At most
        ``steepest_slope_deg``.
    pick_feed_max : float
        Largest distance between adjacent scan lines present over a cell (the
        level's spacing across the lines, unless every cell is reduced), mm.
    reduced_strips : int
        Strips between adjacent grid lines of the level whose pick-feed had to
        be reduced (the pick-feed is chosen strip by strip from the slope
        across the lines in that strip; 0 when ``pick_feed_reduced`` is false).
    clipped_nodes : int
        Level nodes where the lifted MRR level rose above the previous target
        (or the stock) and was clipped to it.
    raised_nodes : int
        Level nodes the containment repair raised after the clip.
    path_length : float
        Length of the pass's scan lines, mm: the nominal lines (the level's
        grid lines across the part) whole, the extra lines only over the
        stretches whose cells need them, each with a lead-in and lead-out of
        one tool radius. Moves between lines are not counted.
    path_length_whole_strips : float
        What ``path_length`` would be if every extra line ran the whole length
        of its strip (the rule before extra lines were laid by region), mm.
    extra_segments : int
        Segments of extra lines (an extra line may need several stretches).
    lines : ScanLines
        The segments themselves (nominal and extra), for tool paths and
        checks.
    model : (my, mx) float64
        Node values of the stage model; node ``(c, d)`` at
        ``(x0 + d*sx, y0 + c*sy)`` with ``(sx, sy) = spacing``. Bilinear.
    sim_positions : int
        Tool positions simulated: points on ``lines`` every ``sim_position_spacing`` mm
        (and the segment ends), only inside the stage's region when it has one.
    sim_position_spacing : float
        Distance between simulated positions along a line, mm.
    sim_max_depth_of_cut, sim_mean_depth_of_cut : float
        Real depth of cut from the simulated stock: per position, the highest stock
        node within the ball's radius of its axis minus its tip height (mean over the
        positions that cut), mm. At most the flute length.
    sim_flute_rule_ok : bool
        ``sim_max_depth_of_cut <= tool.flute_length``.
    sim_lifted_nodes : int
        Model nodes the flute rule on the simulated stock raised (the pass then does not
        reach its target and another pass with the same tool follows).
    sim_gouge : float
        ``max(part - simulated stock after the pass)`` at the input nodes, clipped at 0.
    sim_left_over_next_max, sim_left_over_next_p95 : float
        Simulated stock after the pass minus the next pass's model (the part after the
        last pass) at the input nodes: largest and 95th percentile, mm.
    sim_left_over_part_max, sim_left_over_part_p95 : float
        Simulated stock after the pass minus the part, mm.

    Tool choice by reach and rest regions (issue 11, parts 2 and 3; additive):

    region : (my, mx) bool or None
        Where this stage's ball machines, on the stage model's own nodes
        (``model.shape``): tool positions only at ``True`` nodes. ``None``: the
        whole part.
    region_area_fraction : float
        Share of the part's nodes in ``region`` (1 for the whole part).
    region_boxes : tuple of (x_min, y_min, x_max, y_max, area)
        Bounding boxes of the region's connected parts (8-connected), mm from the
        grid's first node, area in mm², largest first (at most 64; empty when the
        stage works over the whole part).
    region_count : int
        Connected parts of the region.
    estimated_cut_length : float or None
        Finishing stages: region area over the pick-feed that holds the tolerance
        on a flat, mm (what the choice of balls minimises); None for roughing.
    reach_rest_max : float
        Most material the ball leaves over its target in the reach simulation
        (finishing: over the part after this ball and the ones before), mm.
    reach_reason : str or None
        Why this ball, from the simulation.
    """

    tool: Tool
    level: int
    spacing: tuple[float, float]
    pick_feed: float
    pick_feed_reduced: bool
    pick_feed_reason: str | None
    scan_direction: Literal["x", "y"]
    scan_lines: int
    steepest_slope_deg: float
    scallop_height: float
    max_depth_of_cut: float
    mean_depth_of_cut: float
    max_engagement: float
    rest_height: float
    removed_volume: float
    max_stock_left: float
    pass_index: int
    pass_count: int
    concave_radius: float
    merged_levels: tuple[int, ...]
    cross_slope_deg: float
    pick_feed_max: float
    reduced_strips: int
    clipped_nodes: int
    raised_nodes: int
    path_length: float
    path_length_whole_strips: float
    extra_segments: int
    lines: ScanLines = field(repr=False)
    model: F64 = field(repr=False)
    # -- Simulated stock (issue 11 part 4, :mod:`zwcore.scanline._stock`): additive,
    # every field has a default. Figures of the pass's real tool positions cut into the
    # simulated stock at the input nodes.
    sim_positions: int = 0
    sim_position_spacing: float = 0.0
    sim_max_depth_of_cut: float = 0.0
    sim_mean_depth_of_cut: float = 0.0
    sim_flute_rule_ok: bool = True
    sim_lifted_nodes: int = 0
    sim_gouge: float = 0.0
    sim_left_over_next_max: float = 0.0
    sim_left_over_next_p95: float = 0.0
    sim_left_over_part_max: float = 0.0
    sim_left_over_part_p95: float = 0.0
    # --- tool choice by reach and rest regions (issue 11, parts 2-3) ---
    region: NDArray[np.bool_] | None = field(default=None, repr=False)
    region_area_fraction: float = 1.0
    region_boxes: tuple[tuple[float, float, float, float, float], ...] = ()
    region_count: int = 1
    estimated_cut_length: float | None = None
    reach_rest_max: float = 0.0
    reach_reason: str | None = None

    @property
    def passes(self) -> int:
        """Passes with this tool at this level (``pass_count``)."""
        return self.pass_count


@dataclass(frozen=True)
class ScanlineChecks:
    """The design's invariants, evaluated at every input node.

    Attributes
    ----------
    containment : bool
        ``stock_top >= M_0`` and ``M_k >= part`` for every pass at every input node.
        (Before the simulated stock this also required ``M_{k-1} >= M_k``; a pass now
        rises above the one before it where the flute rule on the simulated stock lifts
        it: see ``models_nested``.)
    min_containment_margin : float
        Smallest ``stock_top - M_0`` and ``M_k - part`` over all nodes, mm.
    depth_of_cut : bool
        The flute rule on the simulated stock: at every simulated position of every
        pass, the highest stock node within the ball's radius of its axis lies at most
        the flute length above its tip (``sim_max_depth_of_cut <= L`` for every stage).
        Before the simulated stock this was ``M_{k-1} + h_{k-1} + e_{k-1} - M_k <= L_k``
        on the model nodes (still reported per stage as ``max_engagement``), which held
        while the balls met far more than their flutes between coarse nodes.
    max_depth_over_flute : float
        Largest ``sim_max_depth_of_cut - L`` over the passes; <= 0 when the check holds
        (-inf without positions that cut).
    tool_radii_non_increasing : bool
    finishing_tolerance_met : bool
        The last pass's predicted scallop is at most ``tolerance``.
    last_model_is_part : bool
        The last stage model is the input grid, node for node.
    tools_fit : bool
        The finishing ball is no larger than the part's smallest concave
        radius and every other ball fits its model or has its rest accounted
        for. Informative, not part of :attr:`ok`: when no library ball fits
        the part's sharpest corner the plan still finishes with the smallest
        one (and says so in the notes).
    sim_no_gouge : bool
        The simulated stock never lies below the part at an input node (to the rounding
        guard of a few ulps), after every pass.
    sim_max_gouge : float
        Largest ``part - simulated stock`` over all passes and input nodes, clipped at 0.
    sim_left_over_part_max, sim_left_over_part_p95 : float
        Simulated stock after the last pass minus the part: what the plan leaves, mm.
    """

    containment: bool
    min_containment_margin: float
    depth_of_cut: bool
    max_depth_over_flute: float
    tool_radii_non_increasing: bool
    finishing_tolerance_met: bool
    last_model_is_part: bool
    tools_fit: bool
    # -- Simulated stock (issue 11 part 4): additive, every field has a default.
    sim_no_gouge: bool = True
    sim_max_gouge: float = 0.0
    sim_left_over_part_max: float = 0.0
    sim_left_over_part_p95: float = 0.0
    models_nested: bool = True
    max_model_rise: float = 0.0

    @property
    def ok(self) -> bool:
        """All safety and contract checks hold."""
        return (self.containment and self.depth_of_cut and self.tool_radii_non_increasing
                and self.finishing_tolerance_met and self.last_model_is_part
                and self.sim_no_gouge)


@dataclass(frozen=True)
class ReachSummary:
    """The finishing balls' reach over the part (issue 11, parts 2-3).

    Attributes
    ----------
    finishing_tools : tuple of str
        Main finishing ball first, then the rest balls in order.
    finishing_cut_length : float
        Estimated finishing cut length of those balls in their regions (area over
        the flat pick-feed holding the tolerance, plus ``TOOL_CHANGE_MM`` per
        change), mm.
    smallest_ball_cut_length : float
        The same estimate if the library's smallest ball finished the whole part, mm.
    unreachable_area : float
        Area where even the last ball leaves more than the tolerance, mm².
    unreachable_max_height : float
        Most material left there, mm.
    needed_radius : float
        Smallest concave radius of the part there (a ball that finishes it must be no
        larger), mm; inf when nothing is left.
    """

    finishing_tools: tuple[str, ...]
    finishing_cut_length: float
    smallest_ball_cut_length: float
    unreachable_area: float
    unreachable_max_height: float
    needed_radius: float


@dataclass(frozen=True, eq=False)
class ScanlinePlan:
    """A roughing-to-finishing sequence of ball end mill stages.

    Attributes
    ----------
    stock_top : float
        Height of the flat stock, mm (``M_{-1}``).
    stock_top_source : {"request", "default"}
        ``default``: the part's highest point plus the first tool's flute length.
    tolerance : float
        Finishing tolerance asked for, mm: what the surface (the program's, with tool
        paths) may stand above the part where the plan finishes.
    scallop_tolerance : float
        The share of it the plan's scallops, rest regions and ``finished`` hold,
        ``SCALLOP_SHARE * tolerance``; the rest is the tool paths' (chords, CL between
        the plan's positions).
    cell_bound : bool
        Whether small balls' CL takes the per-cell drop-cutter bound
        (:func:`zwcore.sim.coarse_grid`: the input grid is coarse for some ball of the
        library); the tool paths take the same.
    depth : int
        Number of MRR levels below the input (the input is level ``depth``).
    stages : tuple of ScanlineStage
        In machining order; the last one's model is the part.
    tool_sequence : tuple of str
        Tool ids in machining order, one per tool change (extra passes with the
        same tool are not repeated).
    checks : ScanlineChecks
    notes : tuple of str
        Warnings and decisions worth reading (no tool fits, levels skipped).
    timings : tuple of (str, float)
        Seconds spent per phase (for benchmarks; not part of the result).
    reach : ReachSummary or None
        The finishing balls' simulated reach.
    finished : (ny, nx) bool or None
        Where the plan's own simulated stock after its last pass lies within
        ``scallop_tolerance`` of the part: where the plan says it finishes (the tool
        paths' verification holds the program to ``tolerance`` there).
    """

    stock_top: float
    stock_top_source: Literal["request", "default"]
    tolerance: float
    scallop_tolerance: float
    cell_bound: bool
    depth: int
    stages: tuple[ScanlineStage, ...]
    tool_sequence: tuple[str, ...]
    checks: ScanlineChecks
    notes: tuple[str, ...]
    timings: tuple[tuple[str, float], ...] = ()
    # --- tool choice by reach (issue 11, parts 2-3) ---
    reach: ReachSummary | None = None
    finished: NDArray[np.bool_] | None = None


def stage_at_nodes(stage: ScanlineStage, part: ZMap) -> NDArray[np.float64]:
    """A scan-line stage's model at the part's input nodes (bilinear), ``(ny, nx)``."""
    return bilinear_at_fine_nodes(stage.model, round(stage.spacing[0] / part.dx), part.shape)
