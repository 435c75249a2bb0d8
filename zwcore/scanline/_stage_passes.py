"""The passes of every stage, with the flute rule on the simulated stock.

Per stage (a level's target ``T`` and its ball), passes follow until one reaches the
target: each pass starts from ``T``, is simulated over the stock the passes before it
left (:mod:`zwcore.scanline._stock`), and where a position would meet more than the
flute length ``L`` of stock within the ball's radius above its tip, the pass's model is
raised there (so is its CL, and the tool path's) and another pass with the same ball
follows. Each pass takes ``L`` (less the cusps of the one before) off the stock it
meets, so the stage gets down in about ``(stock - T) / L`` passes where the stock is
deep, and in one where it is not.

The pick-feed budget of a pass depends on whether it reaches its target (the finishing
tolerance, or half of the next ball's flute length) or not (half of its own): the
node-wise rule on the models (``M_{k-1} + h_{k-1} + e_{k-1} - L <= T``, the rule before
the simulated stock) guesses it, the simulation decides, and a finishing pass guessed
short that does reach the part is planned again on the finishing budget.

If lifting stops making progress (material this ball cannot remove stands within its
radius more than ``L`` above where it must go),
the rest of the stage runs without the lift, a note says so and ``depth_of_cut`` is false.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import partial

import numpy as np
from numpy.typing import NDArray

from zwcore.errors import PlanningError
from zwcore.grid.curvature import steepest_slope
from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.scanline._checks import PassSpec, axis_weights, eval_rows
from zwcore.scanline._passes import StripPlan, cell_cross_curvatures, cell_cross_slopes, plan_strips
from zwcore.scanline._stock import (
    CUSP_SHARE,
    PassMemo,
    SimulatedPass,
    StockSim,
    left_over,
    run_pass,
    stride_for,
)
from zwcore.scanline._threads import both
from zwcore.scanline._tool_choice import Level, Stage

__all__ = ["MAX_MODEL_NODES", "MAX_STAGES", "SCALLOP_FLUTE_SHARE", "passes", "upsampled"]

F64 = NDArray[np.float64]

#: A plan needing more passes than this is a stock/flute mismatch, not a plan
#: (and its stage models would not fit in memory for a large grid).
MAX_STAGES = 400

#: Stage-model nodes a plan may hold in all (2 GiB of float64): deep stock with
#: short flutes on a large grid means many full-resolution passes, and the plan
#: keeps every pass's model. Beyond this the request is refused, not the server.
MAX_MODEL_NODES = 1 << 28

#: An intermediate pass's scallops and rest may take at most this share of the
#: next pass's flute length (the rest of it is for the model difference).
SCALLOP_FLUTE_SHARE = 0.5

#: Nodes per block of rows for the full-resolution work on pass models.
_BLOCK_NODES = 1 << 15


def upsampled(coarse: F64, scale: int, shape: tuple[int, int]) -> F64:
    """``bilinear_at_fine_nodes(coarse, scale, shape)``, bit for bit, in blocks of rows.

    The whole-array version makes several full-size temporaries; on a large
    grid those cost more than the arithmetic (fresh pages, no cache reuse).
    """
    if scale == 1:
        return coarse[: shape[0], : shape[1]]
    ny, nx = shape
    ya = axis_weights(scale, ny, coarse.shape[0])
    xa = axis_weights(scale, nx, coarse.shape[1])
    out = np.empty(shape)
    rows = max(1, _BLOCK_NODES // max(nx, 1))
    for a in range(0, ny, rows):
        b = min(a + rows, ny)
        out[a:b] = eval_rows(coarse, scale, a, b, ya, xa)
    return out


def _reaches(on: F64, target: F64, shift: float) -> bool:
    """Whether ``on + shift`` stays at or below the target at every node (blocks of rows:
    no full-size temporaries)."""
    ny, nx = target.shape
    rows = max(1, _BLOCK_NODES // max(nx, 1))
    for a in range(0, ny, rows):
        b = min(a + rows, ny)
        if bool((on[a:b] + shift > target[a:b]).any()):
            return False
    return True


def _region(stage: Stage, stock: F64) -> NDArray[np.bool_] | None:
    """The stage's region on its model nodes (``None``: the whole part); a rule (a
    callable, :class:`zwcore.scanline._rest.RestRegion`) decides it from the simulated
    stock the stages before left."""
    region = stage[4] if len(stage) > 4 else None
    return region(stock) if callable(region) else region


@dataclass
class _Plan:
    """What every stage shares: the part, the simulated stock, the passes so far."""

    zmap: ZMap
    stock_top: float
    tolerance: float
    guard: float
    notes: list[str] | None
    sim: StockSim
    out: list[PassSpec] = field(default_factory=list)
    leaves: float = 0.0  # scallops and rest of the previous pass
    before: F64 | None = None  # the stock before the current pass (reused buffer)

    @property
    def extent_mm(self) -> tuple[float, float]:
        ny, nx = self.zmap.shape
        return (ny - 1) * self.zmap.dy, (nx - 1) * self.zmap.dx


#: A model whose slopes :meth:`_Stage._slopes` took (a copy), the level's spacing and
#: cells, and the slopes.
_Seen = tuple[F64, float, float, tuple[int, int], tuple[F64, F64, float]]


@dataclass
class _Stage:
    """One stage: its level, ball, the model it starts from (``on``) and its line plans."""

    lev: Level
    tool: Tool
    merged: tuple[int, ...]
    rest: float
    region: NDArray[np.bool_] | None
    on: F64
    first: bool
    next_flute: float | None
    lines: dict[tuple[bool, float, str], StripPlan] = field(default_factory=dict)
    finish_first: bool = False

    #: slopes already taken, shared by the plan's stages (:meth:`_slopes`)
    seen: list[_Seen] = field(default_factory=list)

    def __post_init__(self) -> None:
        lev = self.lev
        # Passes that do not reach the target plan their lines on a bound of the
        # slopes of the target and the model before (they lie between the two where
        # the flute rule does not raise them); the last one on the target's own.
        self.ax_t, self.ay_t, self.slope_t = self._slopes(lev.model)
        if self.first:
            self.ax_b, self.ay_b, self.slope_b = self.ax_t, self.ay_t, self.slope_t
        else:
            ax_o, ay_o, slope_o = self._slopes(self.on)
            self.ax_b, self.ay_b = np.maximum(self.ax_t, ax_o), np.maximum(self.ay_t, ay_o)
            self.slope_b = max(self.slope_t, slope_o)
        self.memo = PassMemo()  # the target's drop and the last pass, per position

    def _slopes(self, model: F64) -> tuple[F64, F64, float]:
        """Cross slopes per cell and steepest slope of ``model`` on the level; taken once
        per plan for equal models (the finishing stages share the part's level, and a
        stage that reached its target starts the next one from a copy of it)."""
        lev = self.lev
        for m, sx, sy, cells, got in self.seen:
            if ((sx, sy, cells) == (lev.sx, lev.sy, lev.cells) and m.shape == model.shape
                    and np.array_equal(m, model)):
                return got
        ax, ay = cell_cross_slopes(model, lev.sx, lev.sy, lev.cells)
        got = (ax, ay, steepest_slope(model, lev.sx, lev.sy, extent=lev.cells))
        # a copy: a pass's model may be raised in place later
        self.seen.append((model.copy(), lev.sx, lev.sy, lev.cells, got))
        return got

    def strips(self, reached: bool, tolerance: float, extent_mm: tuple[float, float],
               ) -> StripPlan:
        """The lines of a pass that reaches the target (or not)."""
        flute = self.tool.flute_length
        if reached and self.next_flute is None:
            budget, what = tolerance, f"the tolerance {tolerance:g} mm"
        else:
            following = flute if not reached or self.next_flute is None else self.next_flute
            budget = SCALLOP_FLUTE_SHARE * min(flute, following) - self.rest
            what = f"half the next pass's flute length ({budget:g} mm)"
        key = (reached, budget, what)
        if key not in self.lines:  # the passes that do not reach the target share theirs
            ax, ay = (self.ax_t, self.ay_t) if reached else (self.ax_b, self.ay_b)
            # Only the finishing lines on the part (the tolerance as budget, the whole
            # part) run every k-th grid line where the scallop with the concave kinks
            # across them allows (their model is the target: its kinks, computed here
            # only). A rest ball works in corners the larger balls left, which nearly
            # fit it: there the kinks of the level's model understate the part's
            # curvature (the R 3 ball in the 45 deg fillet left cusps on 2.73 mm radii),
            # so its lines stay on every grid line; roughing lines too (scallops at half
            # the next flute, measured: more lifted passes).
            coarse = reached and self.next_flute is None and self.region is None
            bends = (cell_cross_curvatures(self.lev.model, self.lev.sx, self.lev.sy,
                                           self.lev.cells) if coarse else None)
            self.lines[key] = plan_strips(ax, ay, self.lev.sx, self.lev.sy, extent_mm,
                                          self.tool.radius, budget, what, bends)
        return self.lines[key]


def _stride(tool: Tool, strips: StripPlan, tolerance: float, zmap: ZMap, sx: float,
            sy: float) -> int:
    """Input nodes between simulated positions along the lines: :func:`stride_for`, at
    most the level's spacing along them (every model cell on a line holds a position, so
    the flute lift reaches every stretch of the tool path), a power of two (positions on
    the model's columns)."""
    along_x = strips.direction == "x"
    d = zmap.dx if along_x else zmap.dy
    cap = round((sx if along_x else sy) / d)
    k = min(stride_for(tool, strips.scallop, tolerance, d), cap)
    return 1 << (k.bit_length() - 1)


def _one_pass(plan: _Plan, st: _Stage, lift: bool,
              ) -> tuple[F64, StripPlan, SimulatedPass, F64, bool]:
    """Simulate the stage's next pass; its model, lines, simulation, the stock before and
    whether its lines were laid for a pass that reaches the target."""
    lev, tool = st.lev, st.tool
    guess = st.finish_first or _reaches(st.on, lev.model,
                                        plan.leaves - tool.flute_length + plan.guard)
    # the stock before the pass, in one buffer per plan (a fresh full-grid copy per pass
    # cost more in page faults than in copying: 1 s of a 2049² plan)
    if plan.before is None:
        plan.before = np.empty_like(plan.sim.stock)
    before, gouge = plan.before, plan.sim.gouge
    np.copyto(before, plan.sim.stock)
    for attempt in (guess, True):
        strips = st.strips(attempt, plan.tolerance, plan.extent_mm)
        stride = _stride(tool, strips, plan.tolerance, plan.zmap, lev.sx, lev.sy)
        for _ in range(2):
            model = lev.model.copy()  # the flute rule raises it in place
            done = run_pass(plan.sim, model, (lev.sx, lev.sy), tool, strips.lines, stride,
                            st.region, plan.guard, lift=lift, memo=st.memo, before=before,
                            cusp=CUSP_SHARE * max(strips.scallop, plan.tolerance))
            if not (done.incremental and done.lifted_nodes and done.lowered == 0):
                break
            # A lifted pass that lowers nothing stalls the stage: decided on every
            # position (the incremental pass skips the ones that only re-cut their own
            # envelope, which in grid mode can still round lower).
            plan.sim.restore(before, gouge)
            st.memo.forget(strips.lines)
        if attempt or done.lifted_nodes or st.next_flute is not None:
            break
        plan.sim.restore(before, gouge)  # a finishing pass that reached: plan it again
        st.memo.forget(strips.lines)
        # (and while such passes still get lifted, start from the finishing lines)
        st.finish_first = True
    return model, strips, done, before, attempt


def _stall_note(tool: Tool, lev: Level) -> str:
    return (f"{tool.id} at level {lev.index}: the flute rule on the simulated stock (at most "
            f"{tool.flute_length:g} mm of stock within the ball's radius above its tip) "
            "cannot be met by lifting the pass: material it cannot remove stands higher "
            "than that above where it must go; use longer flutes or a smaller ball first")


def _stage_passes(plan: _Plan, st: _Stage) -> F64:
    """Append the stage's passes to ``plan.out``; returns the last pass's model."""
    lev, tool, zmap = st.lev, st.tool, plan.zmap
    scale = round(lev.sx / zmap.dx)  # input nodes per level spacing, 2**k
    # Lifted passes this stage may take: the stock over the part in quarter flutes, and a few.
    max_lifts = math.ceil((plan.stock_top - float(zmap.z.min()))
                          / (0.25 * tool.flute_length)) + 4
    lifts, stalled = 0, False
    while True:
        model, strips, done, before, on_target = _one_pass(plan, st, not stalled)
        reached = done.lifted_nodes == 0
        # what the previous pass left over this one's model, and this one over the part
        # (two threads: independent reads)
        left_part, left_next = both(partial(left_over, plan.sim.stock, zmap.z),
                                    partial(_left_next, plan, before, model, scale))
        if left_next is not None:
            plan.out[-1].left_next = left_next
        if not reached:
            lifts += 1
            if done.lowered == 0 or lifts > max_lifts:
                stalled = True
                if plan.notes is not None:
                    plan.notes.append(_stall_note(tool, lev))
        # the slope the pass's lines were laid on (an intermediate pass laid on the bound
        # may still reach the target: its cross slopes are the bound's)
        slope = st.slope_t if reached and on_target else st.slope_b
        plan.out.append(PassSpec(
            lev.index, lev.sx, lev.sy, tool, model, strips,
            slope, st.rest, st.merged, lev.concave_radius,
            lev.clipped, lev.raised, region=st.region, sim=done,
            left_part=left_part))
        _bounds(plan)
        plan.leaves = plan.out[-1].leaves
        if reached:
            return model
        st.on = model


def _left_next(plan: _Plan, before: F64, model: F64, scale: int
               ) -> tuple[float, float] | None:
    """What the previous pass left over this pass's model (None: no previous pass)."""
    if not plan.out:
        return None
    return left_over(before, upsampled(model, scale, plan.zmap.shape))


def _bounds(plan: _Plan) -> None:
    out = plan.out
    if len(out) > MAX_STAGES:
        raise PlanningError(
            "tools", f"reaching the part within the flute lengths needs more than "
            f"{MAX_STAGES} passes (stock top {plan.stock_top:g} mm, lowest point "
            f"{float(plan.zmap.z.min()):g} mm); use longer flutes or a lower stock")
    if sum(p.model.size for p in out) > MAX_MODEL_NODES:
        raise PlanningError(
            "grid", f"the plan's {len(out)}+ passes would hold more than "
            f"{MAX_MODEL_NODES} model nodes; send a coarser grid, longer flutes or "
            f"a lower stock")


def passes(zmap: ZMap, chosen: list[Stage], stock_top: float, tolerance: float, g: float,
           notes: list[str] | None = None, final_stock: list[F64] | None = None,
           cell_bound: bool = False) -> list[PassSpec]:
    """All passes of the chosen stages (coarse to fine), simulated in turn.

    Parameters
    ----------
    zmap : ZMap
        The part.
    chosen : list of Stage
        ``(level, tool, merged levels, rest[, region])`` per stage; a region given as a
        rule is decided when the stage begins, and a stage whose region is empty is
        dropped.
    stock_top, tolerance : float
    g : float
        Rounding guard (a few ulps of the heights in play).
    notes : list of str, optional
        Appended to where a stage cannot meet the flute rule by lifting.
    cell_bound : bool
        Small balls take the per-cell drop-cutter bound (:func:`zwcore.sim.coarse_grid`).
    final_stock : list, optional
        Receives the simulated stock after the last pass, ``(ny, nx)`` float64, then the
        stock before the first finishing stage (the roughing's; the stock top when every
        stage finishes).
    """
    plan = _Plan(zmap, stock_top, tolerance, g, notes, StockSim(zmap, stock_top, cell_bound))
    prev: F64 | None = None
    prev_level = 0
    seen: list[_Seen] = []
    roughed: F64 | None = None
    for n, stage in enumerate(chosen):
        lev, tool, merged, rest = stage[:4]
        region = _region(stage, plan.sim.stock)
        if region is not None and not region.any():
            continue  # a rest ball with nothing left to do
        if prev is None:
            on = np.full(lev.model.shape, stock_top)
        else:
            on = upsampled(prev, 1 << (lev.index - prev_level), lev.model.shape)
        # every stage on the part's level finishes (rest balls only add to it): its
        # pick-feed holds the tolerance
        finishing = lev.index == chosen[-1][0].index
        if finishing and roughed is None:
            roughed = plan.sim.stock.copy()
        next_flute = None if finishing else chosen[n + 1][1].flute_length
        st = _Stage(lev, tool, tuple(merged), rest, region, on, prev is None,
                    next_flute, seen=seen)
        prev = _stage_passes(plan, st)
        prev_level = lev.index
    if plan.out:
        plan.out[-1].left_next = plan.out[-1].left_part
    if final_stock is not None:
        final_stock.append(plan.sim.stock)
        final_stock.append(plan.sim.stock.copy() if roughed is None else roughed)
    return plan.out

