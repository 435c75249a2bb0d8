"""Per-stage figures and the design's checks for the scan-line plan.

Every stage model is evaluated once at the input nodes, in blocks of rows that
stay in cache; the block evaluation performs the same floating-point
operations as :func:`zwcore.grid.sampling.bilinear_at_fine_nodes` (first along y,
then along x), so the figures and checks are those of that function, bit for
bit. The loop is block-major: for each block of rows every stage is evaluated
in machining order next to the block of the stage before it, so no stage is
ever held at full resolution (a plan at 2049 x 2049 has ~30 stages: a full
evaluation of each would be a gigabyte of fresh pages). From the evaluation
and the previous stage's come the depth of cut (min, max, removed volume by
the trapezoid rule, exact for the bilinear models), the stock left over the
part and the containment margin. Stage models are nested bilinear surfaces (a coarse
bilinear surface restricted to a finer cell is bilinear), so a difference of
two of them is bilinear on every input cell and its extremes sit on input
nodes: the node checks hold for the whole surface.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from zwcore.grid.tools import Tool
from zwcore.scanline._passes import StripPlan
from zwcore.scanline._stock import SimulatedPass
from zwcore.scanline.results import ScanlineChecks, ScanlineStage

__all__ = ["PassSpec", "axis_weights", "eval_rows", "figures"]

F64 = NDArray[np.float64]

#: Input nodes per block of rows.
_BLOCK_NODES = 1 << 16


@dataclass
class PassSpec:
    """One planned pass, before its figures."""

    level: int
    sx: float
    sy: float
    tool: Tool
    model: F64
    strips: StripPlan
    steepest_slope: float
    rest: float
    merged: tuple[int, ...]
    concave_radius: float
    clipped: int
    raised: int
    #: Where the pass's ball machines, on ``model``'s nodes (None: everywhere).
    region: NDArray[np.bool_] | None = None
    sim: SimulatedPass | None = None
    left_next: tuple[float, float] = (0.0, 0.0)
    left_part: tuple[float, float] = (0.0, 0.0)

    @property
    def leaves(self) -> float:
        """Stock above the model the next pass's flutes also take."""
        return self.strips.scallop + self.rest


def axis_weights(scale: int, n: int, m: int) -> tuple[NDArray[np.intp], NDArray[np.intp], F64]:
    """Lower and upper coarse index and weight of ``n`` fine nodes along an axis of ``m`` nodes."""
    idx = np.arange(n)
    lo = idx // scale
    t = (idx % scale) / scale
    hi = np.minimum(lo + 1, m - 1)
    return lo, hi, t


def eval_rows(coarse: F64, scale: int, a: int, b: int,
              ya: tuple[NDArray[np.intp], NDArray[np.intp], F64],
              xa: tuple[NDArray[np.intp], NDArray[np.intp], F64]) -> F64:
    """Rows ``a:b`` of ``bilinear_at_fine_nodes(coarse, scale, shape)``, same operations.

    First along y on the coarse columns, then along x. The x step is written
    per coarse cell with the ``scale`` weights broadcast instead of gathering
    ``rows[:, lo]`` and ``rows[:, hi]`` for every fine node: element
    ``(k, c, r)`` is ``rows[k, c] * (1 - r/s) + rows[k, hi(c)] * (r/s)``,
    the very products and sum of the gathered form, so the values are the
    same, bit for bit, at a fraction of the memory traffic.
    """
    nx = xa[0].size
    if scale == 1:
        return coarse[a:b, :nx]
    lo, hi, t = ya[0][a:b], ya[1][a:b], ya[2][a:b]
    rows = coarse[lo] * (1.0 - t)[:, None] + coarse[hi] * t[:, None]
    m = coarse.shape[1]
    cells = int(xa[0][-1]) + 1 if nx else 0  # coarse cells holding fine nodes
    tt = np.arange(scale) / scale
    hi_c = np.minimum(np.arange(cells) + 1, m - 1)
    out = rows[:, :cells, None] * (1.0 - tt) + rows[:, hi_c, None] * tt
    return np.asarray(out.reshape(rows.shape[0], cells * scale)[:, :nx], dtype=np.float64)


def _trapezoid_weights(n: int) -> F64:
    w = np.ones(n)
    w[0] = w[-1] = 0.5
    return w


@dataclass
class _Reductions:
    """Per pass, over the input nodes: depth of cut extremes, volume, stock left extremes."""

    cut_min: list[float]
    cut_max: list[float]
    volume: list[float]  # trapezoid sums, in cells (times the cell area: mm³)
    left_max: list[float]
    left_min: list[float]


def _evaluate(part: F64, depth: int, passes: Sequence[PassSpec], stock_top: float,
              ) -> _Reductions:
    """Evaluate every pass once at the input nodes and reduce, block-major.

    Every row block of every pass is evaluated once, in machining order, next
    to the block of the pass before it (still in cache), instead of keeping a
    full-resolution evaluation of each pass. Per pass, the blocks are reduced
    in the same order as a pass-major loop would, so every figure is the same,
    bit for bit.
    """
    ny, nx = part.shape
    wy = _trapezoid_weights(ny)
    wx = _trapezoid_weights(nx)
    rows = max(8, _BLOCK_NODES // max(nx, 1))
    n = len(passes)
    scales = [1 << (depth - p.level) for p in passes]
    axes = [(axis_weights(sc, ny, p.model.shape[0]), axis_weights(sc, nx, p.model.shape[1]))
            for sc, p in zip(scales, passes, strict=True)]
    red = _Reductions([math.inf] * n, [-math.inf] * n, [0.0] * n, [-math.inf] * n,
                      [math.inf] * n)
    for a in range(0, ny, rows):
        b = min(a + rows, ny)
        pa = part[a:b]
        wa = wy[a:b]
        prev: F64 | None = None
        for i, p in enumerate(passes):
            cur = eval_rows(p.model, scales[i], a, b, axes[i][0], axes[i][1])
            cut = (stock_top - cur) if prev is None else (prev - cur)
            red.cut_min[i] = min(red.cut_min[i], float(cut.min()))
            red.cut_max[i] = max(red.cut_max[i], float(cut.max()))
            red.volume[i] += float(wa @ cut @ wx)
            left = cur - pa
            red.left_max[i] = max(red.left_max[i], float(left.max()))
            red.left_min[i] = min(red.left_min[i], float(left.min()))
            prev = cur
    return red


def _stage(p: PassSpec, index: tuple[int, int], cut_max: float, volume: float, area: float,
           engagement: float, left_max: float) -> ScanlineStage:
    """The stage record of one pass (``index``: pass index and count at its level)."""
    sp = p.strips
    return ScanlineStage(
        tool=p.tool, level=p.level, spacing=(p.sx, p.sy), pick_feed=sp.pick_feed,
        pick_feed_reduced=sp.reason is not None, pick_feed_reason=sp.reason,
        scan_direction=sp.direction, scan_lines=max(sp.scan_lines, 2),
        steepest_slope_deg=math.degrees(math.atan(p.steepest_slope)),
        scallop_height=sp.scallop,
        max_depth_of_cut=cut_max, mean_depth_of_cut=volume / area if area > 0 else 0.0,
        max_engagement=engagement, rest_height=p.rest, removed_volume=volume,
        max_stock_left=left_max,
        pass_index=index[0], pass_count=index[1], concave_radius=p.concave_radius,
        merged_levels=p.merged, cross_slope_deg=math.degrees(math.atan(sp.cross_slope)),
        pick_feed_max=sp.pick_feed_max, reduced_strips=sp.reduced_strips,
        clipped_nodes=p.clipped, raised_nodes=p.raised, path_length=sp.path_length,
        path_length_whole_strips=sp.path_length_whole_strips, extra_segments=sp.extra_segments,
        lines=sp.lines, model=p.model, region=p.region, **_sim_fields(p))


def _sim_fields(p: PassSpec) -> dict[str, Any]:
    """The stage's figures from the simulated stock (none without a simulation)."""
    if p.sim is None:
        return {}
    cut = p.sim.cut
    return {
        "sim_positions": cut.positions.size, "sim_position_spacing": p.sim.spacing,
        "sim_max_depth_of_cut": cut.depth_max, "sim_mean_depth_of_cut": cut.depth_mean,
        "sim_flute_rule_ok": cut.depth_max <= p.tool.flute_length,
        "sim_lifted_nodes": p.sim.lifted_nodes, "sim_gouge": cut.gouge,
        "sim_left_over_next_max": p.left_next[0], "sim_left_over_next_p95": p.left_next[1],
        "sim_left_over_part_max": p.left_part[0], "sim_left_over_part_p95": p.left_part[1]}


def figures(part: F64, depth: int, dx: float, dy: float, passes: Sequence[PassSpec],
            stock_top: float, tolerance: float, guard: float = 0.0,
            ) -> tuple[list[ScanlineStage], ScanlineChecks]:
    """Stages with their figures, and the checks, from one evaluation per stage
    (``guard``: the rounding allowance of the simulated gouge)."""
    ny, nx = part.shape
    cell = dx * dy
    area = (ny - 1) * dy * (nx - 1) * dx
    counts: dict[tuple[int, str], int] = {}
    for p in passes:
        key = (p.level, p.tool.id)
        counts[key] = counts.get(key, 0) + 1
    seen: dict[tuple[int, str], int] = {}
    red = _evaluate(part, depth, passes, stock_top)

    leaves = 0.0
    margin = math.inf
    rise = -math.inf
    fit = True
    stages: list[ScanlineStage] = []
    for i, p in enumerate(passes):
        volume = red.volume[i] * cell
        # Containment is of the part (and under the stock): a pass may rise above the
        # one before it where the flute rule on the simulated stock lifted it (the
        # earlier ball could not follow its model there); that is reported apart.
        margin = min(margin, red.left_min[i], red.cut_min[i] if i == 0 else math.inf)
        rise = max(rise, -red.cut_min[i])
        engagement = red.cut_max[i] + leaves
        fit = fit and (p.tool.radius <= p.concave_radius or p.rest > 0.0)
        key = (p.level, p.tool.id)
        seen[key] = seen.get(key, 0) + 1
        stages.append(_stage(p, (seen[key], counts[key]), red.cut_max[i], volume, area,
                             engagement, red.left_max[i]))
        leaves = p.leaves
    radii = [s.tool.radius for s in stages]
    last = stages[-1].model
    # min()/max() skip NaN, so a NaN anywhere must fail the checks explicitly.
    finite = math.isfinite(margin)
    checks = ScanlineChecks(
        containment=finite and margin >= 0.0,
        min_containment_margin=margin,
        **_sim_checks(stages, guard),
        tool_radii_non_increasing=all(a >= b for a, b in itertools.pairwise(radii)),
        finishing_tolerance_met=stages[-1].scallop_height <= tolerance,
        last_model_is_part=last.shape == part.shape and bool(np.array_equal(last, part)),
        tools_fit=fit,
        models_nested=rise <= 0.0, max_model_rise=max(rise, 0.0),
    )
    return stages, checks


def _sim_checks(stages: Sequence[ScanlineStage], guard: float) -> dict[str, Any]:
    """The checks from the simulated stock (``guard``: the rounding allowance of the
    gouge, a few ulps of the heights in play). ``depth_of_cut`` is the flute rule on the
    simulated stock: the node-wise rule on the models it replaced said true while the
    balls met far more than their flutes between the coarse nodes (issue 11)."""
    gouge = max(s.sim_gouge for s in stages)
    over = max((s.sim_max_depth_of_cut - s.tool.flute_length for s in stages
                if s.sim_positions), default=-math.inf)
    ok = math.isfinite(gouge) and not math.isnan(over)
    return {"depth_of_cut": ok and all(s.sim_flute_rule_ok for s in stages),
            "max_depth_over_flute": over,
            "sim_no_gouge": ok and gouge <= guard, "sim_max_gouge": gouge,
            "sim_left_over_part_max": stages[-1].sim_left_over_part_max,
            "sim_left_over_part_p95": stages[-1].sim_left_over_part_p95}
