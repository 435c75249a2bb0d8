"""The plan's reach figures from its simulated stock (issue 11, parts 2-3).

Every figure here is read off what the plan's passes really leave
(:mod:`zwcore.scanline._stock`): a stage's region is the mask its passes were simulated
in, what is left is the final simulated stock minus the part, and the unreachable area
is where that exceeds the tolerance. The estimate that ranked the main ball
(:mod:`zwcore.scanline._regions`) only supplies the main ball's reason and the
smallest-ball comparison.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.scanline._regions import TOOL_CHANGE_MM, Chain, flat_pick_feed, region_boxes
from zwcore.scanline._rest import RestRegion
from zwcore.scanline._tool_choice import Stage
from zwcore.scanline.results import ReachSummary, ScanlineChecks, ScanlineStage
from zwcore.sim import RegionBox

__all__ = ["with_reach"]

F64 = NDArray[np.float64]


def _rest_reason(rule: RestRegion, frac: float, tol: float) -> str:
    prev = rule.previous.id if rule.previous is not None else "the ball before"
    than = ("the simulated stock (the closing of " + prev + " too large to compute)"
            if rule.against_stock else prev + "'s")
    where = (f"positions within its radius whose ball cuts into stock more than {tol:g} mm "
             "above the part" if rule.cut_tested else
             "grown by its radius (too many positions to test which of them cut)")
    return (f"simulated stock: {rule.seed_nodes} nodes still more than {tol:g} mm above the "
            f"part (up to {rule.left_before:.4g} mm) where {rule.tool.id}'s bilinear closing "
            f"lies more than {tol:g} mm below {than}; {where}: {100 * frac:.3g} % of the part")


def _left_note(last: Tool, tol: float, area: float, height: float, sharp: float,
               need: float) -> str:
    text = (f"no tool reaches everywhere: after the last ball {last.id} (R {last.radius:g} "
            f"mm) the simulated stock stays more than {tol:g} mm above the part on "
            f"{area:.4g} mm² (up to {height:.4g} mm)")
    if sharp > 0.0:
        text += (f"; {sharp:.4g} mm² of it in corners sharper than the ball, which would "
                 f"need a ball of radius at most {need:.3g} mm (the part's concave radius)")
    if sharp < area:
        text += (f"; {area - sharp:.4g} mm² where the part is not sharper than the ball: "
                 "left by the passes (scallops, the grid's border where the scan lines end, "
                 "steep chords that hold the ball up on the bilinear surface)")
    return text


def with_reach(zmap: ZMap, stages: list[ScanlineStage], checks: ScanlineChecks,
               chosen: Sequence[Stage], chain: Chain, final_stock: F64, tol: float,
               notes: list[str]) -> tuple[list[ScanlineStage], ScanlineChecks, ReachSummary]:
    """The reach figures on every pass, ``tools_fit`` and the plan's reach summary.

    Parameters
    ----------
    zmap : ZMap
        The part, ``(ny, nx)``.
    stages : list of ScanlineStage
    checks : ScanlineChecks
    chosen : sequence of Stage
        The stages as chosen (finishing rest stages carry their :class:`RestRegion`).
    chain : Chain
        The estimate that ranked the main ball (and the part's concave radii).
    final_stock : (ny, nx) float64
        The simulated stock after the last pass.
    tol : float
    notes : list of str
        Appended to where even the last ball leaves more than ``tol``.
    """
    info = {(c.level.index, c.tool.id): c for c in chosen}
    dx, dy = zmap.dx, zmap.dy
    out = []
    finishing: list[tuple[str, float, float]] = []  # (tool id, area, pick-feed), per ball
    # a stage's passes share its region: its share and boxes once (labelling is full-grid)
    of_region: dict[int, tuple[float, int, tuple[RegionBox, ...]]] = {}
    for s_ in stages:
        c = info[(s_.level, s_.tool.id)]
        rule = c.region if isinstance(c.region, RestRegion) else None
        if c.reach is None and rule is None:
            out.append(s_)
            continue
        region = s_.region
        boxes: tuple[RegionBox, ...]
        if region is None:
            frac, count, boxes = 1.0, 1, ()
        else:
            if id(region) not in of_region:
                of_region[id(region)] = (float(region.mean()), *region_boxes(region, dx, dy))
            frac, count, boxes = of_region[id(region)]
        area = frac * zmap.z.size * dx * dy
        cut: float | None = None
        if s_.level == stages[-1].level:
            pf = flat_pick_feed(s_.tool.radius, tol)
            cut = area / pf
            if s_.pass_index == 1:
                finishing.append((s_.tool.id, area, pf))
        reason = c.reach.reason if c.reach is not None else _rest_reason(rule, frac, tol)  # type: ignore[arg-type]
        out.append(dataclasses.replace(
            s_, region_area_fraction=frac, region_count=count,
            region_boxes=tuple((b.x_min, b.y_min, b.x_max, b.y_max, b.area) for b in boxes),
            estimated_cut_length=cut, reach_rest_max=s_.sim_left_over_part_max,
            reach_reason=reason))
    left = final_stock - zmap.z
    above = left > tol
    unreachable = float(above.sum()) * dx * dy
    height = float(left[above].max()) if above.any() else 0.0
    last = out[-1].tool
    rho = chain.rho  # the part's concave radii
    sharp = above & (rho < last.radius)  # a smaller ball would be needed there
    need = float(rho[sharp].min()) if sharp.any() else math.inf
    if above.any():
        notes.append(_left_note(last, tol, unreachable, height, float(sharp.sum()) * dx * dy,
                                need))
    roughing_fit = all(c.tool.radius <= c.level.concave_radius or c.rest > 0.0
                       or c.reach is not None or c.region is not None for c in chosen)
    # the tools fit unless material is left in corners sharper than the last ball (what
    # the passes leave elsewhere is in the figures, not a question of fit)
    checks = dataclasses.replace(checks, tools_fit=roughing_fit and not sharp.any())
    length = sum(a / pf for _, a, pf in finishing) + TOOL_CHANGE_MM * (len(finishing) - 1)
    summary = ReachSummary(
        finishing_tools=tuple(t for t, _, _ in finishing),
        finishing_cut_length=length, smallest_ball_cut_length=chain.smallest_everywhere,
        unreachable_area=unreachable, unreachable_max_height=height, needed_radius=need)
    return out, checks, summary
