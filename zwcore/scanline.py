"""Scan-line plan for ball end mills (design section 3; seed 000, 6.1 and 6.2).

Everything comes off one lifted single-knot MRR of the part:

1. ``analyse(z, "single_knot")``: level ``j`` is a bilinear model of spacing
   ``(dx, dy) * 2**(J-j)`` that contains every finer level and the part.
2. Tool choice per level from the level model itself: the largest library
   ball whose radius is at most the level's smallest concave radius
   (:mod:`zwcore.curvature`). Levels are taken from the finest (the part,
   which fixes the finishing tool) towards the coarsest; a coarser level
   becomes a stage only when it admits a strictly larger ball than the stage
   after it, so radii never grow in machining order; a level that admits the
   same ball merges into the finer stage, and one that admits a smaller ball
   (a sharp coarse crease) or is coarser than its ball can follow (spacing
   >= diameter) is skipped.
3. Pick-feed: the level's spacing (paths run along grid lines). The scallop
   on the steepest slope ``theta`` of the stage model is
   ``R - sqrt(R^2 - (p / (2 cos theta))^2)``. The finishing pass must meet
   ``tolerance``; any other pass must leave at most half of the next pass's
   flute length (its scallops are stock for that pass). Where the spacing
   is too coarse for that, the pick-feed is reduced and the stage says why.
   A roughing level may also take a ball larger than its concave radius when
   the material that ball cannot reach there (a grey closing of the level
   model by the ball, on the level's nodes) is at most a quarter of the next
   stage's flute length: steep walls make every coarse lifted model sharp at
   its own grid scale, and without this a part with a wall would be roughed
   with the finishing ball.
4. Flute-length lift (Fig. 6) on the stage's own nodes:
   ``M_k = max(A_j, M_{k-1} + h_{k-1} + e_{k-1} - L_k + g)``, where
   ``h_{k-1}`` and ``e_{k-1}`` are the previous pass's scallop and rest
   (stock the flutes also have to take) and ``g`` a
   few ulps of the heights, upward, so that float rounding can only leave
   more stock. Where ``M_k`` still lies above ``A_j`` the part was out of
   reach: another pass with the same tool at the same level follows, until
   the level model is reached. Extra passes are separate stages
   (``pass_index`` of ``pass_count``).

The checks are evaluated at every input node with
:func:`zwcore.sampling.bilinear_at_fine_nodes`. Stage models are nested
bilinear surfaces (a coarse bilinear surface restricted to a finer cell is
bilinear there), so a difference of two of them is bilinear on every input
cell and its extremes sit on input nodes: the node checks hold for the whole
surface.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from zwcore.curvature import min_concave_radius, steepest_slope
from zwcore.errors import InvalidInputError, PlanningError
from zwcore.sampling import bilinear_at_fine_nodes
from zwcore.tools import Tool, default_tools, tool_library
from zwcore.wavelets import analyse
from zwcore.zmap import ZMap

__all__ = [
    "MAX_STAGES",
    "ScanlineChecks",
    "ScanlinePlan",
    "ScanlineStage",
    "plan_scanline",
    "scallop_height",
]

F64 = NDArray[np.float64]

#: A plan needing more passes than this is a stock/flute mismatch, not a plan
#: (and its stage models would not fit in memory for a large grid).
MAX_STAGES = 400

#: An intermediate pass's scallops and rest may take at most this share of the
#: next pass's flute length (the rest of it is for the model difference).
SCALLOP_FLUTE_SHARE = 0.5

#: Rest material a roughing ball may leave in its model's sharper valleys, as a
#: share of the next stage's flute length.
REST_FLUTE_SHARE = 0.25

#: The rest of an oversized ball is computed only where it spans at most this
#: many nodes of its level each way (beyond, the concave-radius rule decides).
REST_MAX_CELLS = 4


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
        Distance between adjacent scan lines in mm.
    pick_feed_reduced : bool
        Whether ``pick_feed`` is below the level's spacing.
    pick_feed_reason : str or None
        Why it was reduced.
    scan_direction : {"x", "y"}
        Direction the scan lines run in (along the axis with the larger
        spacing, so the pick-feed is the smaller one).
    scan_lines : int
        Number of scan lines across the part at ``pick_feed``.
    steepest_slope_deg : float
        Steepest slope of the stage model, the ``theta`` of the scallop rule.
    scallop_height : float
        Predicted scallop at ``pick_feed`` on the steepest slope, in mm.
    max_depth_of_cut, mean_depth_of_cut : float
        ``M_{k-1} - M_k`` over the input nodes (mean: removed volume over the
        grid's area), in mm.
    max_engagement : float
        Largest ``M_{k-1} + h_{k-1} + e_{k-1} - M_k``: the depth of cut plus the
        previous pass's scallops and rest, what the flutes really take. At most
        the flute length.
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
    model : (my, mx) float64
        Node values of the stage model; node ``(c, d)`` at
        ``(x0 + d*sx, y0 + c*sy)`` with ``(sx, sy) = spacing``. Bilinear.
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
    model: F64 = field(repr=False)

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
        ``stock_top >= M_0 >= M_1 >= ... >= part`` at every input node.
    min_containment_margin : float
        Smallest ``M_{k-1} - M_k`` (and ``M_K - part``) over all nodes, mm.
    depth_of_cut : bool
        ``M_{k-1} + h_{k-1} + e_{k-1} - M_k <= L_k`` at every input node
        (stricter than the design's ``M_{k-1} - M_k <= L_k``: the previous
        pass's scallops ``h`` and rest ``e`` count).
    max_depth_over_flute : float
        Largest ``M_{k-1} + h_{k-1} + e_{k-1} - M_k - L_k``; <= 0 when the
        check holds.
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
    """

    containment: bool
    min_containment_margin: float
    depth_of_cut: bool
    max_depth_over_flute: float
    tool_radii_non_increasing: bool
    finishing_tolerance_met: bool
    last_model_is_part: bool
    tools_fit: bool

    @property
    def ok(self) -> bool:
        """All safety and contract checks hold."""
        return (self.containment and self.depth_of_cut and self.tool_radii_non_increasing
                and self.finishing_tolerance_met and self.last_model_is_part)


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
        Finishing scallop height asked for, mm.
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
    """

    stock_top: float
    stock_top_source: Literal["request", "default"]
    tolerance: float
    depth: int
    stages: tuple[ScanlineStage, ...]
    tool_sequence: tuple[str, ...]
    checks: ScanlineChecks
    notes: tuple[str, ...]
    timings: tuple[tuple[str, float], ...] = ()


# --------------------------------------------------------------------------
# Scallops and pick-feeds
# --------------------------------------------------------------------------


def scallop_height(pick_feed: float, slope: float, radius: float) -> float:
    """Scallop height of a ball on a slope, design section 3.

    Parameters
    ----------
    pick_feed : float
        Distance between scan lines, mm.
    slope : float
        ``tan(theta)`` of the surface across the scan lines.
    radius : float
        Ball radius, mm.

    Returns
    -------
    float
        ``R - sqrt(R^2 - e^2)`` with ``e = p / (2 cos theta)``; ``inf`` when
        ``e > R`` (the ball does not reach between adjacent lines).
    """
    e = 0.5 * pick_feed * math.sqrt(1.0 + slope * slope)
    if e > radius:
        return math.inf
    # Written without the cancellation of R - sqrt(R^2 - e^2) for small e.
    return e * e / (radius + math.sqrt(max(radius * radius - e * e, 0.0)))


def _pick_feed_for(scallop: float, slope: float, radius: float) -> float:
    """Largest pick-feed whose scallop on ``slope`` is at most ``scallop``."""
    b = min(scallop, radius)
    e = math.sqrt(b * (2.0 * radius - b))
    # A hair under the exact value so the recomputed scallop is <= the target
    # despite rounding.
    return 2.0 * e / math.sqrt(1.0 + slope * slope) * (1.0 - 1e-9)


@dataclass
class _Level:
    index: int
    model: F64
    sx: float
    sy: float
    extent: tuple[int, int]  # nodes inside the input's extent
    cells: tuple[int, int]  # cells touching the input's extent
    concave_radius: float
    fit: Tool | None


@dataclass
class _Pass:
    level: int
    tool: Tool
    model: F64
    pick_feed: float
    reduced: bool
    reason: str | None
    slope: float
    scallop: float
    rest: float
    merged: tuple[int, ...]

    @property
    def leaves(self) -> float:
        """Stock above the model the next pass's flutes also take."""
        return self.scallop + self.rest


# --------------------------------------------------------------------------
# The planner
# --------------------------------------------------------------------------


def _validate(tolerance: float, stock_top: float | None, top: float) -> tuple[float, float | None]:
    try:
        tol = float(tolerance)
    except (TypeError, ValueError):
        raise InvalidInputError("tolerance", f"must be a number, got {tolerance!r}") from None
    if not math.isfinite(tol) or tol <= 0.0:
        raise InvalidInputError("tolerance", f"must be a finite number > 0, got {tolerance!r}")
    if stock_top is None:
        return tol, None
    try:
        st = float(stock_top)
    except (TypeError, ValueError):
        raise InvalidInputError("stock_top", f"must be a number, got {stock_top!r}") from None
    if not math.isfinite(st):
        raise InvalidInputError("stock_top", f"must be finite, got {stock_top!r}")
    if st < top:
        raise InvalidInputError(
            "stock_top", f"must be at or above the part's highest point {top!r}, got {st!r}")
    return tol, st


def _largest_fitting(library: Sequence[Tool], radius: float) -> Tool | None:
    for tool in library:  # largest first
        if tool.radius <= radius:
            return tool
    return None


def _levels(zmap: ZMap, smoothing: float, library: Sequence[Tool]) -> list[_Level]:
    mrr = analyse(zmap.z, "single_knot")
    ny, nx = zmap.shape
    widest = library[0].diameter
    out = []
    for j, model in enumerate(mrr.approximations):
        s = mrr.scale(j)
        sx, sy = zmap.dx * s, zmap.dy * s
        extent = ((ny - 1) // s + 1, (nx - 1) // s + 1)
        cells = (-(-(ny - 1) // s), -(-(nx - 1) // s))
        if j < mrr.depth and min(sx, sy) >= widest:
            # No library ball can follow scan lines this far apart: not useful.
            out.append(_Level(j, model, sx, sy, extent, cells, math.nan, None))
            continue
        rho = min_concave_radius(model, sx, sy, smoothing=smoothing, extent=extent)
        out.append(_Level(j, model, sx, sy, extent, cells, rho,
                          _largest_fitting(library, rho)))
    return out


def _ball_rest(lev: _Level, radius: float) -> float:
    """Largest height of material a ball of ``radius`` leaves in the level model's valleys.

    Drop-cutter on the level's own nodes: the tool tip rests at
    ``max_y (A(x+y) - b(y))`` over the ball's footprint ``y``, with ``b`` the
    ball's lower hemisphere above its tip, and cuts down to
    ``min_y (tip(x-y) + b(y))``: a grey closing of ``A`` by ``-b``. The rest
    is that minus ``A``, over the nodes inside the input.
    """
    mx = math.floor(radius / lev.sx)
    my = math.floor(radius / lev.sy)
    oy, ox = np.mgrid[-my:my + 1, -mx:mx + 1]
    r2 = (ox * lev.sx) ** 2 + (oy * lev.sy) ** 2
    inside = r2 <= radius * radius
    hemi = radius - np.sqrt(np.where(inside, radius * radius - r2, 0.0))
    closed = ndimage.grey_closing(lev.model, footprint=inside, structure=-hemi, mode="nearest")
    rest = (closed - lev.model)[: lev.extent[0], : lev.extent[1]]
    return max(float(rest.max()), 0.0)


def _default_stock(top: float, tool: Tool) -> float:
    # A few ulps under top + L, so that the first pass's flute lift lands on
    # the top itself rather than a rounding above it (which would call for an
    # empty extra pass).
    st = top + tool.flute_length
    return st - 2.0 * _guard(st, top, tool.flute_length)


def _choose(levels: list[_Level], library: Sequence[Tool], requested: float | None,
            notes: list[str]) -> list[tuple[_Level, Tool, list[int], float]]:
    """Stages (level, tool, merged levels, rest) from coarse to fine; radii non-increasing.

    A level whose lifted model rises above the stock (the requested one, or
    the default for the tool it would get) cannot be cut from it and is
    skipped: the lift over a cliff overshoots the part's top, more so the
    coarser the level.
    """
    top = float(levels[-1].model.max())
    finest = levels[-1]
    finish = finest.fit
    if finish is None:
        finish = library[-1]
        notes.append(
            f"no tool fits the smallest concave radius of the part "
            f"({finest.concave_radius:.4g} mm); finishing with the smallest ball "
            f"{finish.id} (R {finish.radius:g} mm) leaves material in the sharpest corners")
    chosen: list[tuple[_Level, Tool, list[int], float]] = [(finest, finish, [], 0.0)]
    current = finish
    for lev in reversed(levels[:-1]):
        if math.isnan(lev.concave_radius):
            continue  # coarser than any ball can follow
        spacing = min(lev.sx, lev.sy)
        # An intermediate stage may use a ball larger than its model's concave
        # radius when what the ball cannot reach (its rest, grey closing on the
        # level's nodes) fits in a quarter of the next stage's flute length;
        # that rest counts against it like scallops do. Only tried where the
        # ball spans a few nodes (cheap, and the node sampling is fair).
        allowance = REST_FLUTE_SHARE * current.flute_length
        pick: tuple[Tool, float] | None = None
        high = float(lev.model.max())
        for tool in library:
            if tool.radius <= current.radius:
                break
            if spacing >= tool.diameter:
                continue  # the ball cannot follow this level's scan lines
            st = requested if requested is not None else _default_stock(top, tool)
            if high > st - _guard(st, top):
                continue
            if tool.radius <= lev.concave_radius:
                pick = (tool, 0.0)
                break
            if tool.radius <= REST_MAX_CELLS * spacing:
                rest = _ball_rest(lev, tool.radius)
                if rest <= allowance:
                    pick = (tool, rest)
                    break
        if pick is not None:
            chosen.append((lev, pick[0], [], pick[1]))
            current = pick[0]
        elif lev.fit is not None and lev.fit.id == current.id:
            chosen[-1][2].append(lev.index)
    chosen.reverse()
    return chosen


def _slope_and_pick(slope: float, lev: _Level, tool: Tool, budget: float,
                    finishing: bool) -> tuple[float, float, bool, str | None, float]:
    """Steepest slope, pick-feed, reduced?, reason, scallop of one pass."""
    spacing = min(lev.sx, lev.sy)
    h = scallop_height(spacing, slope, tool.radius)
    if h <= budget:
        return slope, spacing, False, None, h
    p = _pick_feed_for(budget, slope, tool.radius)
    theta = math.degrees(math.atan(slope))
    what = (f"the tolerance {budget:g} mm" if finishing
            else f"half the next pass's flute length ({budget:g} mm)")
    shown = "more than the ball radius" if math.isinf(h) else f"{h:.4g} mm"
    reason = (f"at the level spacing {spacing:g} mm the scallop on the steepest slope "
              f"({theta:.1f} deg) would be {shown}, over {what}")
    return slope, p, True, reason, scallop_height(p, slope, tool.radius)


def _guard(*values: float) -> float:
    # A few ulps of the largest magnitude in play: covers the rounding of one
    # subtraction and of evaluating the models at the input nodes.
    return 64.0 * float(np.finfo(np.float64).eps) * max(1.0, *(abs(v) for v in values))


def _passes(levels: list[_Level], chosen: list[tuple[_Level, Tool, list[int], float]],
            stock_top: float, tolerance: float) -> list[_Pass]:
    top_abs = max(abs(float(lv.model.max())) for lv in levels)
    low_abs = max(abs(float(lv.model.min())) for lv in levels)
    out: list[_Pass] = []
    prev: F64 | None = None
    prev_level = 0
    leaves = 0.0  # scallops and rest of the previous pass
    for n, (lev, tool, merged, rest) in enumerate(chosen):
        flute = tool.flute_length
        g = _guard(stock_top, top_abs, low_abs, flute)
        target = lev.model
        if prev is None:
            on = np.full(target.shape, stock_top)
        else:
            on = bilinear_at_fine_nodes(prev, 1 << (lev.index - prev_level), target.shape)
        next_flute = chosen[n + 1][1].flute_length if n + 1 < len(chosen) else None
        # Every pass of this stage is max(A, S + c) with S the incoming model
        # (or an earlier pass, itself such a max): along any cell edge its
        # slope is at most the larger of the two, so one bound serves every
        # pass (an upper bound: the scallop is never underestimated). The
        # last pass is the level model itself and gets its own slope.
        slope_a = steepest_slope(target, lev.sx, lev.sy, extent=lev.cells)
        slope_on = 0.0 if prev is None else steepest_slope(on, lev.sx, lev.sy,
                                                           extent=lev.cells)
        while True:
            lifted = on + (leaves - flute + g)
            model = np.maximum(target, lifted)
            reached = not bool((lifted > target).any())
            finishing = reached and next_flute is None
            if finishing:
                budget = tolerance
            else:
                following = flute if not reached or next_flute is None else next_flute
                budget = SCALLOP_FLUTE_SHARE * min(flute, following) - rest
            slope = slope_a if reached else max(slope_a, slope_on)
            slope, p, reduced, reason, h = _slope_and_pick(slope, lev, tool, budget, finishing)
            out.append(_Pass(lev.index, tool, model, p, reduced, reason, slope, h, rest,
                             tuple(merged)))
            if len(out) > MAX_STAGES:
                raise PlanningError(
                    "tools", f"reaching the part within the flute lengths needs more than "
                    f"{MAX_STAGES} passes (stock top {stock_top:g} mm, lowest point "
                    f"{float(levels[-1].model.min()):g} mm); use longer flutes or a lower stock")
            leaves = out[-1].leaves
            if reached:
                break
            on = model
        prev = model
        prev_level = lev.index
    return out


def _trapezoid_weights(n: int) -> F64:
    w = np.ones(n)
    w[0] = w[-1] = 0.5
    return w


def plan_scanline(zmap: ZMap, tools: Sequence[Tool] | None = None, *, tolerance: float = 0.01,
                  stock_top: float | None = None,
                  curvature_smoothing: float = 0.0) -> ScanlinePlan:
    """Plan scan-line machining of a z-map with ball end mills.

    Parameters
    ----------
    zmap : ZMap
        The finished part, ``(ny, nx)`` heights.
    tools : sequence of Tool, optional
        Ball end mills in the crib (default: the shipped library).
    tolerance : float
        Finishing scallop height, mm, finite and > 0.
    stock_top : float, optional
        Height of the flat stock; at least the part's highest point. Default:
        the highest point plus the first tool's flute length.
    curvature_smoothing : float
        Gaussian smoothing in cells before estimating concave radii (0: none;
        see :mod:`zwcore.curvature`, for noisy scans).

    Returns
    -------
    ScanlinePlan

    Raises
    ------
    InvalidInputError
        Bad ``tolerance``, ``stock_top`` or tool library.
    PlanningError
        The flute lengths would need more than :data:`MAX_STAGES` passes.
    """
    clock = [time.perf_counter()]
    timings: list[tuple[str, float]] = []

    def lap(name: str) -> None:
        now = time.perf_counter()
        timings.append((name, now - clock[0]))
        clock[0] = now

    part = zmap.z
    top = float(part.max())
    tol, requested = _validate(tolerance, stock_top, top)
    library = default_tools("ball") if tools is None else tool_library(tools, "ball")
    if not math.isfinite(curvature_smoothing) or curvature_smoothing < 0.0:
        raise InvalidInputError("curvature_smoothing",
                                f"must be finite and >= 0, got {curvature_smoothing!r}")
    lap("validate")

    notes: list[str] = []
    levels = _levels(zmap, float(curvature_smoothing), library)
    lap("mrr_and_curvature")

    chosen = _choose(levels, library, requested, notes)
    st = requested if requested is not None else _default_stock(top, chosen[0][1])
    lap("select")

    passes = _passes(levels, chosen, st, tol)
    lap("flute_lift")

    stages, checks = _figures(zmap, levels, passes, st, tol)
    lap("figures_and_checks")

    sequence: list[str] = []
    for s in stages:
        if not sequence or sequence[-1] != s.tool.id:
            sequence.append(s.tool.id)
    return ScanlinePlan(
        stock_top=st, stock_top_source="request" if requested is not None else "default",
        tolerance=tol, depth=len(levels) - 1, stages=tuple(stages),
        tool_sequence=tuple(sequence), checks=checks, notes=tuple(notes),
        timings=tuple(timings))


def _figures(zmap: ZMap, levels: list[_Level], passes: list[_Pass], stock_top: float,
             tolerance: float) -> tuple[list[ScanlineStage], ScanlineChecks]:
    part = zmap.z
    ny, nx = part.shape
    depth = len(levels) - 1
    wy = _trapezoid_weights(ny)
    wx = _trapezoid_weights(nx)
    cell = zmap.dx * zmap.dy
    area = (ny - 1) * zmap.dy * (nx - 1) * zmap.dx
    counts: dict[tuple[int, str], int] = {}
    for p in passes:
        key = (p.level, p.tool.id)
        counts[key] = counts.get(key, 0) + 1
    seen: dict[tuple[int, str], int] = {}

    prev_f: F64 | None = None
    leaves = 0.0
    margin = math.inf
    over = -math.inf
    fit = True
    stages: list[ScanlineStage] = []
    for p in passes:
        lev = levels[p.level]
        cur = bilinear_at_fine_nodes(p.model, 1 << (depth - p.level), (ny, nx))
        cut = (stock_top - cur) if prev_f is None else (prev_f - cur)
        cut_min = float(cut.min())
        cut_max = float(cut.max())
        volume = float(wy @ cut @ wx) * cell
        margin = min(margin, cut_min)
        engagement = cut_max + leaves
        over = max(over, engagement - p.tool.flute_length)
        left = float((cur - part).max())
        fit = fit and (p.tool.radius <= lev.concave_radius or p.rest > 0.0)
        key = (p.level, p.tool.id)
        seen[key] = seen.get(key, 0) + 1
        direction: Literal["x", "y"] = "x" if lev.sy <= lev.sx else "y"
        across = ((ny - 1) * zmap.dy) if direction == "x" else ((nx - 1) * zmap.dx)
        stages.append(ScanlineStage(
            tool=p.tool, level=p.level, spacing=(lev.sx, lev.sy), pick_feed=p.pick_feed,
            pick_feed_reduced=p.reduced, pick_feed_reason=p.reason, scan_direction=direction,
            scan_lines=math.ceil(across / p.pick_feed - 1e-9) + 1,
            steepest_slope_deg=math.degrees(math.atan(p.slope)), scallop_height=p.scallop,
            max_depth_of_cut=cut_max, mean_depth_of_cut=volume / area,
            max_engagement=engagement, rest_height=p.rest, removed_volume=volume,
            max_stock_left=left,
            pass_index=seen[key], pass_count=counts[key], concave_radius=lev.concave_radius,
            merged_levels=p.merged, model=p.model))
        prev_f = cur
        leaves = p.leaves
    assert prev_f is not None
    margin = min(margin, float((prev_f - part).min()))
    radii = [s.tool.radius for s in stages]
    last = stages[-1].model
    checks = ScanlineChecks(
        containment=margin >= 0.0,
        min_containment_margin=margin,
        depth_of_cut=over <= 0.0,
        max_depth_over_flute=over,
        tool_radii_non_increasing=all(a >= b for a, b in itertools.pairwise(radii)),
        finishing_tolerance_met=stages[-1].scallop_height <= tolerance,
        last_model_is_part=last.shape == part.shape and bool(np.array_equal(last, part)),
        tools_fit=fit,
    )
    return stages, checks
