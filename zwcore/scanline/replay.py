"""A scan-line plan's passes simulated again on its part: the planner's stock simulation,
run a second time from what the plan reports (issue 11 part 5).

Every pass of :class:`~zwcore.scanline.results.ScanlinePlan` is cut into the stock at the
part's input nodes with :func:`zwcore.scanline._stock.run_pass`, in machining order, from
the plan's flat stock top:

- its positions: points on the pass's reported scan lines every
  ``sim_position_spacing`` mm plus the segment ends (thinned as the planner thins a pass
  too large to simulate at every position), only inside its region when it has one;
- its CL: ``max(CL on the stage's target, CL against the part's nodes)``, raised to the
  highest stock within the ball's radius minus the flute length where that is higher
  (the flute rule: the plan's pass model is its target raised so that its tool path
  stays at least that high). The stage's target is the model of its last pass (the one
  that reaches it); a pass the planner ran without the lift (a stalled stage, its
  ``sim_flute_rule_ok`` false) runs without it here too;
- the stock after it: ``min(stock, CL + h)`` at every input node within the ball's radius.

So the replay is the planner's own simulation: its figures equal the plan's ``sim_*``
figures to float rounding, and its machined surface is what they were measured on.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.scanline._levels import rounding_guard
from zwcore.scanline._stock import StockSim, left_over, run_pass
from zwcore.scanline.results import ScanlinePlan, stage_at_nodes

__all__ = ["PassReplay", "PlanReplay", "replay_passes"]

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class PassReplay:
    """Figures of one pass, replayed.

    Attributes
    ----------
    stage : int
        Index of the pass in ``plan.stages``.
    tool : Tool
    positions : int
        Tool positions simulated.
    depth_max, depth_mean : float
        Real depth of cut: per position the highest stock node within the ball's radius
        of its axis minus its tip height (mean over the positions that cut), mm.
    flute_rule_ok : bool
        ``depth_max <= tool.flute_length``.
    gouge : float
        ``max(part - stock after the pass)`` at the input nodes, clipped at 0, mm.
    left_over_next_max, left_over_next_p95 : float
        Stock after the pass minus the next pass's model (the part after the last), mm.
    left_over_part_max, left_over_part_p95 : float
        Stock after the pass minus the part, mm.
    removed_volume : float
        mm³ (node area times the height removed).
    """

    stage: int
    tool: Tool
    positions: int
    depth_max: float
    depth_mean: float
    flute_rule_ok: bool
    gouge: float
    left_over_next_max: float
    left_over_next_p95: float
    left_over_part_max: float
    left_over_part_p95: float
    removed_volume: float


@dataclass(frozen=True, eq=False)
class PlanReplay:
    """The plan's passes replayed.

    Attributes
    ----------
    machined : (ny, nx) float64
        The simulated stock after the last pass, at the part's nodes.
    passes : tuple of PassReplay
        In machining order, one per stage of the plan.
    """

    machined: F64
    passes: tuple[PassReplay, ...]


def _guard(part: ZMap, plan: ScanlinePlan) -> float:
    """A few ulps of the heights in play (the planner's rounding guard): the planner lifts
    a position when the stock it meets exceeds the flute length by more than such a
    guard (rounding, not cutting)."""
    return rounding_guard(plan.stock_top, float(np.abs(part.z).max()),
                          *(s.tool.flute_length for s in plan.stages))


def _targets(plan: ScanlinePlan) -> list[F64]:
    """Per pass, its stage's target: the model of the last pass at its level with its tool."""
    last = {(s.level, s.tool.id): s.model for s in plan.stages}
    return [last[(s.level, s.tool.id)] for s in plan.stages]


def replay_passes(part: ZMap, plan: ScanlinePlan) -> PlanReplay:
    """Simulate every pass of a scan-line plan on its part again (module docstring).

    Parameters
    ----------
    part : ZMap
        The plan's input, ``(ny, nx)``.
    plan : ScanlinePlan
        A plan of ``part`` (:func:`zwcore.scanline.plan_scanline`).

    Returns
    -------
    PlanReplay
    """
    sim = StockSim(part, plan.stock_top, plan.cell_bound)
    guard = _guard(part, plan)
    out: list[PassReplay] = []
    stages = plan.stages
    for i, (s, target) in enumerate(zip(stages, _targets(plan), strict=True)):
        along = part.dx if s.lines.direction == "x" else part.dy
        stride = max(1, round(s.sim_position_spacing / along))
        before = sim.stock.copy()
        # s.region (rest regions): the model nodes the pass may cut, None for all
        done = run_pass(sim, target.copy(), s.spacing, s.tool, s.lines, stride, s.region,
                        guard, lift=s.sim_flute_rule_ok)
        nxt = part.z if i + 1 == len(stages) else stage_at_nodes(stages[i + 1], part)
        on_next, on_part = left_over(sim.stock, nxt), left_over(sim.stock, part.z)
        cut = done.cut
        out.append(PassReplay(
            stage=i, tool=s.tool, positions=cut.positions.size, depth_max=cut.depth_max,
            depth_mean=cut.depth_mean, flute_rule_ok=cut.depth_max <= s.tool.flute_length,
            gouge=cut.gouge, left_over_next_max=on_next[0], left_over_next_p95=on_next[1],
            left_over_part_max=on_part[0], left_over_part_p95=on_part[1],
            removed_volume=float((before - sim.stock).sum() * part.cell_area)))
    return PlanReplay(sim.stock, tuple(out))
