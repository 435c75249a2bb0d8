"""The simulated stock of a scan-line plan: every pass's real tool positions, cut in turn.

A pass's positions are points on its scan lines (:class:`~zwcore.scanline.results.ScanLines`:
the level's grid lines whole, the extra segments where the plan has them), every
``stride`` input nodes along a line plus the segment ends, and only over the pass's
``region`` (level nodes; ``None``: everywhere). At each position ``c``:

- ``CL(c) = max(CL_model(c), CL_part(c))``: ``CL_model`` is the drop-cutter
  (:func:`zwcore.sim.drop_cutter`, bilinear) on the pass's model at the model's own
  nodes, bilinear between them (what the tool path follows); ``CL_part`` the exact
  drop-cutter against the part's input nodes, ``max over nodes q within R of
  z(q) - h(|q - c|)`` (no position cuts below a node of the part);
- the flute rule reads the stock before the pass: ``top(c)``, the highest stock node
  within ``R`` of the axis, and ``depth(c) = top(c) - CL(c)`` must stay at most the flute
  length ``L``; the planner lifts the pass where it would not (:func:`run_pass`);
- the stock after the pass is ``min(stock, CL(c) + h(|p - c|))`` at every input node
  ``p`` within ``R`` of a position: exact at the nodes for the positions.

Positions at discrete points leave more stock than the continuous motion of the tool
between them (a cusp of about ``ds² / (8R)`` on a flat, more on a slope climbed along the
line): the simulated stock is never below what the tool path leaves at the same CL,
which is the safe side for the next pass's flute rule and for the material-left
figures. ``ds`` is the input spacing along the line for the finishing ball; a coarse
pass, whose ball spans thousands of input nodes, keeps ``ds`` where that cusp stays under
a quarter of its own scallop (or of the tolerance, the larger).

Cost: three numba kernels visit, per position, the input nodes within ``R`` block by
block (8 x 8 nodes) and skip a block when its maximum cannot change the answer (branch
and bound for the drop-cutter and the top, a block whose stock lies under the ball
everywhere for the envelope): near linear in the positions times the nodes a ball
really touches. A stage's later passes on the same lines visit only the positions whose
CL may fall and those near stock that changed (:mod:`zwcore.scanline._stock_state`).
For a large ball with dense positions the envelope and the drop against the nodes run
as a line sweep instead (:mod:`zwcore.scanline._stock_sweep`: per line and node row a
1-D lower envelope, lines x rows x nodes instead of positions x footprint), whichever
costs less (:data:`zwcore.scanline._stock_lines.SWEEP_SHARE`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.scanline import _stock_bounds as _b
from zwcore.scanline import _stock_kernels as _k
from zwcore.scanline._stock_grid import GridMode
from zwcore.scanline._stock_lazy import exact_base, lazy_state
from zwcore.scanline._stock_lines import LineSweep, drop_nodes, drop_target, per_position
from zwcore.scanline._stock_state import (
    BLOCK,
    Last,
    PassMemo,
    Positions,
    State,
    TargetCL,
    block_max,
    grow_blocks,
    next_state,
)
from zwcore.scanline._stock_thin import Thinning
from zwcore.scanline.results import ScanLines
from zwcore.sim import drop_cutter, simulation_work
from zwcore.sim.cutting import PRUNE_FOOTPRINT

__all__ = [
    "BLOCK",
    "CUSP_SHARE",
    "DROP_SHARE",
    "INCREMENTAL",
    "THINNING",
    "PassMemo",
    "Positions",
    "SimulatedPass",
    "StockSim",
    "block_max",
    "drop",
    "interpolate",
    "left_over",
    "positions",
    "run_pass",
    "stride_for",
    "target_drop",
]

F64 = NDArray[np.float64]

#: The cusp discrete positions may leave along a line, as a share of the pass's scallop
#: (or of the tolerance, the larger).
CUSP_SHARE = 0.25


def stride_for(tool: Tool, scallop: float, tolerance: float, spacing: float) -> int:
    """Input nodes between positions along a line: the cusp ``ds² / (8R)`` of discrete
    positions on a flat stays under :data:`CUSP_SHARE` of ``max(scallop, tolerance)``."""
    allowance = CUSP_SHARE * max(scallop, tolerance)
    ds = math.sqrt(8.0 * tool.radius * allowance)
    return max(1, int(ds / spacing))


def positions(lines: ScanLines, part: ZMap, stride: int,
              region: NDArray[np.bool_] | None = None,
              spacing: tuple[float, float] | None = None) -> Positions:
    """Points on the segments every ``stride`` input nodes along them, plus their ends.

    Parameters
    ----------
    lines : ScanLines
    part : ZMap
        The input grid (``dx``, ``dy``, shape).
    stride : int
        >= 1.
    region : (my, mx) bool, optional
        Where on the pass's model nodes the ball machines: a position is kept when its
        nearest model node is in the region.
    spacing : (sx, sy), optional
        The model's node spacing (needed with ``region``).
    """
    along_x = lines.direction == "x"
    d = part.dx if along_x else part.dy
    step = stride * d
    u, v = _k.points(np.ascontiguousarray(lines.offset, dtype=np.float64),
                     np.ascontiguousarray(lines.start, dtype=np.float64),
                     np.ascontiguousarray(lines.stop, dtype=np.float64), step)
    x, y = (u, v) if along_x else (v, u)
    if region is not None and spacing is not None:
        keep = _k.in_region(x, y, np.ascontiguousarray(region), *spacing)
        x, y = x[keep], y[keep]
    return Positions(np.ascontiguousarray(x), np.ascontiguousarray(y), lines.direction)


def interpolate(grid: F64, sx: float, sy: float, pos: Positions) -> F64:
    """Bilinear interpolation of node values ``grid`` at the positions (clamped to the grid)."""
    return _k.interpolate(np.ascontiguousarray(grid), 1.0 / sx, 1.0 / sy, pos.x, pos.y)


def left_over(stock: F64, surface: F64) -> tuple[float, float]:
    """Largest and 95th-percentile ``stock - surface`` over the input nodes, mm (as
    ``np.percentile``; :func:`_stock_kernels.diff_max_p95` makes no temporaries)."""
    hi, p95 = _k.diff_max_p95(np.ascontiguousarray(stock), np.ascontiguousarray(surface))
    return float(hi), float(p95)


@dataclass(frozen=True, eq=False)
class PassCut:
    """One pass simulated: its positions, real depth of cut, and stock figures.

    Attributes
    ----------
    positions : Positions
    depth_max, depth_mean : float
        Of the depth of cut per position (highest stock before the pass within ``R`` of
        the axis, minus its CL, >= 0): largest, and mean over the positions that cut.
    gouge : float
        ``max(part - stock after)`` at the input nodes, clipped at 0.
    """

    positions: Positions
    depth_max: float
    depth_mean: float
    gouge: float

    @classmethod
    def of(cls, positions: Positions, depth: F64, gouge: float) -> PassCut:
        """From the depth of cut per position, (n,)."""
        top, mean = _k.positive_max_mean(depth)
        return cls(positions, float(top), float(mean), gouge)


class StockSim:
    """The simulated stock at the input nodes, lowered pass by pass.

    Parameters
    ----------
    part : ZMap
    stock_top : float
    """

    def __init__(self, part: ZMap, stock_top: float, cell_bound: bool = False) -> None:
        self.part = part
        #: small balls take the per-cell drop-cutter bound (:func:`zwcore.sim.coarse_grid`)
        self.cell_bound = cell_bound
        self.stock = np.full(part.shape, float(stock_top))
        self.zmax = block_max(part.z)
        #: a few ulps of the heights (:meth:`base_cl`)
        self.ulps = 8.0 * float(np.finfo(np.float64).eps) * (
            float(np.abs(part.z).max(initial=0.0)) + abs(float(stock_top)) + 1.0)
        #: ``max(part - stock)`` so far, clipped at 0 (kept over the blocks each pass lowers)
        self.gouge = max(0.0, float(part.z.max()) - float(stock_top))
        self._grid_key: tuple[Positions, NDArray[np.intp], float, GridMode | None] | None = None

    def restore(self, stock: F64, gouge: float) -> None:
        """Back to an earlier stock and its gouge."""
        self.stock[...] = stock
        self.gouge = gouge

    def base_cl(self, model_cl: F64, pos: Positions, tool: Tool) -> F64:
        """``max(model_cl, CL against the part's nodes)`` at the positions; where the
        part's nodes decide, raised by a few ulps of the heights: the cut kernels add the
        ball's profile in another order, and a CL that touches a node exactly could leave
        the stock an ulp under it."""
        model_cl = np.ascontiguousarray(model_cl)
        cl = drop_nodes(self.part.z, self.zmax, pos, model_cl, tool.radius, self.part.dx,
                        self.part.dy)
        nodes = cl > model_cl
        cl[nodes] += self.ulps
        return cl

    def top(self, pos: Positions, idx: NDArray[np.intp], tool: Tool, smax: F64,
            grid_ok: bool) -> F64:
        """Highest stock node within ``R`` of the positions ``idx`` (grid mode when they
        are most of the input nodes and ``grid_ok``; else the block bounds where they
        settle it, :func:`_stock_bounds.top_bounded`, and the kernel elsewhere)."""
        px, py = pos.x[idx], pos.y[idx]
        grid = self._grid(pos, idx, px, py, tool) if grid_ok else None
        if grid is not None:
            return grid.top(self.stock, smax, self.part, px, py, tool)
        part, r = self.part, tool.radius
        stock = self.stock

        def top_at(x: F64, y: F64) -> F64:  # per position: split between two threads
            return per_position(lambda a, b: _k.top(stock, smax, BLOCK, x[a:b], y[a:b], r,
                                                    part.dx, part.dy), x.size, r, part.dx,
                                part.dy)

        if not BOUNDS or px.size < BOUNDS_MIN:
            return top_at(px, py)
        grown = grow_blocks(smax, r, part.dx, part.dy)
        out, rest = _b.top_bounded(smax, grown, part.shape, px, py, r, part.dx, part.dy,
                                   BLOCK)
        if rest.size:
            out[rest] = top_at(px[rest], py[rest])
        return out

    def _grid(self, pos: Positions, idx: NDArray[np.intp], px: F64, py: F64,
              tool: Tool) -> GridMode | None:
        """:meth:`GridMode.of` the positions ``idx``, kept for the same ``pos`` and ``idx``
        (a first pass reads the top and cuts at the same positions)."""
        key = self._grid_key
        if key is None or key[0] is not pos or key[1] is not idx or key[2] != tool.radius:
            key = (pos, idx, tool.radius, GridMode.of(px, py, self.part, tool, BLOCK))
            self._grid_key = key
        return key[3]

    def cut(self, pos: Positions, idx: NDArray[np.intp], cl: F64, tool: Tool,
            grid_ok: bool) -> NDArray[np.bool_]:
        """Lower the stock by the ball at the positions ``idx`` with CL ``cl[idx]``;
        returns the blocks where a node was lowered."""
        smax = block_max(self.stock)
        touched = np.zeros(smax.shape, dtype=bool)
        px, py, c = pos.x[idx], pos.y[idx], np.ascontiguousarray(cl[idx])
        grid = self._grid(pos, idx, px, py, tool) if grid_ok else None
        if grid is not None:
            grid.cut(self.stock, smax, self.part, px, py, c, tool, touched)
            return touched
        part, r = self.part, tool.radius
        skip = (_b.settle(self.stock, px, py, c, r, part.dx, part.dy, BLOCK, touched)
                if BOUNDS and px.size >= BOUNDS_MIN else np.zeros_like(touched))
        sweep = LineSweep.of(px, py, pos.along, r, part.dx, part.dy)
        if sweep is not None:
            sweep.cut(self.stock, c, touched, skip)
        else:
            _k.cut(self.stock, smax, BLOCK, px, py, c, r, part.dx, part.dy, touched, skip)
        return touched


#: ``False``: the kernels alone, without the block bounds that settle most of a dense
#: pass first (:mod:`zwcore.scanline._stock_bounds`; the tests compare the two).
BOUNDS = True

#: Positions from which the block bounds are tried (their set-up costs a few block-grid
#: filters).
BOUNDS_MIN = 256


@dataclass(frozen=True, eq=False)
class SimulatedPass:
    """What :func:`run_pass` did: the cut and the model nodes the flute rule raised
    (``incremental``: as a stage's next pass, :func:`_stock_state.next_state`)."""

    cut: PassCut
    lifted_nodes: int
    spacing: float
    lowered: int
    incremental: bool = False


def run_pass(sim: StockSim, model: F64, spacing: tuple[float, float], tool: Tool,
             lines: ScanLines, stride: int, region: NDArray[np.bool_] | None,
             guard: float, *, lift: bool = True, target_cl: TargetCL | None = None,
             memo: PassMemo | None = None, before: F64 | None = None,
             cusp: float | None = None) -> SimulatedPass:
    """Simulate one pass over ``sim``'s stock, lifting ``model`` (in place) where the flute
    rule needs it.

    The positions' CL is ``max(CL on the model, CL against the part's nodes)``. Where the
    highest stock node within ``R`` minus the flute length ``L`` (plus ``guard``) lies
    above it, the position's CL is lifted to that height (every position then meets at
    most ``L`` of stock) and the model's nodes around it are raised (:func:`_lift`) so the
    tool path's CL is at least as high.

    Only the positions that may cut are visited by the kernels: a position whose CL on
    the model lies at or above the highest stock of the blocks its ball spans cuts
    nothing (and its depth of cut is 0). A position on a model node needs no drop-cutter
    against the part's nodes: the model contains them, and its CL there is at least
    that of any surface under it. The next pass of a stage on the same positions
    (``memo``) visits fewer still (:func:`_stock_state.next_state`).

    Parameters
    ----------
    target_cl : TargetCL, optional
        :func:`zwcore.sim.drop_cutter` of ``model`` as given (else from ``memo``, or
        :func:`target_drop`).
    memo : PassMemo, optional
        What the stage's passes share; updated to this pass.
    before : (ny, nx) float64, optional
        A copy of ``sim.stock`` as it is (else taken here when the pass is lifted).
    cusp : float, optional
        The cusp, mm, a thinned pass may leave between its simulated positions on a flat
        (:class:`_Thinning`; the planner gives :data:`CUSP_SHARE` of the pass's scallop or
        the tolerance, as :func:`stride_for` along the lines). ``None``: thinned as far as
        ``0.7 R``.

    Returns
    -------
    SimulatedPass
    """
    last = memo.find(lines, stride, region) if memo is not None and INCREMENTAL else None
    if last is not None:
        state = next_state(sim, tool, last)
    else:
        state = _first_state(sim, model, spacing, tool, lines, stride, region, target_cl,
                             memo, guard if lift else None, cusp)
    part = sim.part
    pos, cand, top, cl, depth = state.pos, state.cand, state.top, state.cl, state.depth
    base = state.base
    need = top[cand] - tool.flute_length + guard
    if state.exact is not None:  # the unlifted CL where the rule may now leave it
        vague = ~state.exact[cand] & ((need <= base[cand]) if lift else True)
        if vague.any():
            if target_cl is None and memo is not None:
                target_cl = memo.drop
            exact_base(sim, model, spacing, tool, pos, cand[vague], target_cl, base,
                       state.exact)
    bind = (need > base[cand]) if lift else np.zeros(cand.size, dtype=bool)
    lifted = 0
    if bind.any():
        bound = Positions(pos.x[cand[bind]], pos.y[cand[bind]])
        if state.thin.k == 1:
            lifted = _lift(model, spacing, bound, _on_nodes(bound, *spacing), need[bind])
        else:
            lifted = state.thin.lift(model, spacing, bound, need[bind])
    new = np.where(bind, need, base[cand])
    cutters = cand if state.first else cand[new < cl[cand]]
    cl[cand] = new
    d = top[cand] - new
    depth[cand] = np.where(np.isfinite(d), np.maximum(d, 0.0), 0.0)
    if lifted and before is None:
        before = sim.stock.copy()
    touched = sim.cut(pos, cutters, cl, tool, state.thin.k == 1)
    if memo is not None:
        memo.keep(lines, Last(state.lines, stride, region, pos, base, cl, top, depth,
                              touched, state.thin, state.exact))
    # nodes outside the blocks the pass lowered kept their stock
    sim.gouge = max(sim.gouge, _k.blocks_diff_max(part.z, sim.stock, touched, BLOCK))
    lowered = (-1 if not lifted or before is None
               else _k.blocks_lowered(sim.stock, before, touched, BLOCK, guard))
    along = part.dx if lines.direction == "x" else part.dy
    return SimulatedPass(PassCut.of(pos, depth, sim.gouge), lifted, stride * along, lowered,
                         not state.first)


def _first_state(sim: StockSim, model: F64, spacing: tuple[float, float], tool: Tool,
                 lines: ScanLines, stride: int, region: NDArray[np.bool_] | None,
                 target_cl: TargetCL | None, memo: PassMemo | None,
                 lazy: float | None = None, cusp: float | None = None) -> State:
    """Every position of the pass: CL on the target, the part's nodes where it may cut
    (``lazy``: the flute rule's guard of a lifted pass,
    :func:`zwcore.scanline._stock_lazy.lazy_state`)."""
    sx, sy = spacing
    part = sim.part
    thin = _Thinning.of(lines, part, stride, tool, spacing, cusp)
    pos = positions(thin.lines, part, stride * thin.k, region, spacing)
    if target_cl is None and memo is not None:
        if not memo.dropped:  # the stage's target: the first pass's model
            memo.drop, memo.dropped = target_drop(model, sx, sy, tool, pos.size,
                                                  sim.cell_bound), True
        target_cl = memo.drop
    elif target_cl is None:
        target_cl = target_drop(model, sx, sy, tool, pos.size, sim.cell_bound)
    if lazy is not None and BOUNDS and pos.size >= BOUNDS_MIN:
        return lazy_state(sim, model, spacing, tool, thin.lines, thin, pos, target_cl, lazy)
    if target_cl is None:  # a large ball on a fine model: dropped on its nodes here only
        cl = drop_target(model, pos, tool, sx, sy)
    else:
        cl = interpolate(target_cl.at(pos.x, pos.y), sx, sy, pos)
    smax = block_max(sim.stock)
    may = _k.may_cut(grow_blocks(smax, tool.radius, part.dx, part.dy), BLOCK,
                     pos.x, pos.y, cl, 1.0 / part.dx, 1.0 / part.dy)
    act = np.flatnonzero(may)
    off = act[~_on_nodes(Positions(pos.x[act], pos.y[act]), sx, sy)]
    if off.size:
        cl[off] = sim.base_cl(cl[off], Positions(pos.x[off], pos.y[off], pos.along), tool)
    top = np.full(pos.size, -np.inf)
    top[act] = sim.top(pos, act, tool, smax, thin.k == 1)
    return State(thin.lines, thin, pos, act, top, cl, cl.copy(), np.zeros(pos.size), True)


#: ``False``: no pass is thinned, whatever its work (``bench/bench_scanline_core.py
#: --unthinned``: what thinning changes in the plan).
THINNING = True

#: ``False``: a pass is thinned as far as ``0.7 R`` whatever the cusp its gaps leave (the
#: rule before; ``bench/bench_scanline_core.py --unthinned`` compares the three).
CUSP_THINNING = True

#: Node visits one pass's simulation may make (positions times the nodes within a ball's
#: radius): a Ø20 ball finishing a 1024² grid at 0.1 mm would make 3e10.
MAX_PASS_WORK = 1 << 26


class _Thinning(Thinning):
    """:class:`~zwcore.scanline._stock_thin.Thinning` with this module's limits, read at
    each call (:data:`MAX_PASS_WORK`, :data:`THINNING`, :data:`CUSP_THINNING`: the tests
    and the bench set them here)."""

    @classmethod
    def of(cls, lines: ScanLines, part: ZMap, stride: int, tool: Tool,
           spacing: tuple[float, float], cusp: float | None = None) -> Thinning:
        return cls.build(lines, part, stride, tool, spacing, cusp, MAX_PASS_WORK,
                         THINNING, CUSP_THINNING)


def _lift(model: F64, spacing: tuple[float, float], pos: Positions, node: NDArray[np.bool_],
          need: F64) -> int:
    """Raise ``model`` (in place) so the tool path's CL is at least ``need`` at the
    (binding) positions; ``node``: those on a model node. Returns the number of nodes
    raised.

    A binding position on a model node raises that node; one between nodes raises the
    corners that carry weight in its bilinear value. Either way the model under the
    position, so its drop-cutter CL, so the tool path's CL (bilinear between corner CLs
    that each are at least the model there) is at least ``need``. The simulation takes
    the position's CL as ``need`` itself (the least the rule allows): a bilinear model
    cannot follow a lift that rises steeply between nodes, and dropping the ball on the
    raised model lifted the positions beside such a rise above their own need, so they
    cut nothing and the stage never got down. The tool path may therefore stay above
    the simulated CL next to a lift (it cuts less there, never more).
    """
    sx, sy = spacing
    return int(_k.lift_nodes(model, 1.0 / sx, 1.0 / sy, pos.x, pos.y,
                             np.ascontiguousarray(need), node))


def target_drop(model: F64, sx: float, sy: float, tool: Tool, positions: int,
                cell_bound: bool = False) -> TargetCL | None:
    """:func:`drop` of a stage's target, or ``None`` where dropping the ball at the pass's
    ``positions`` alone costs less. With ``cell_bound``, :meth:`TargetCL.at` computes a
    small ball's per-cell bound (:mod:`zwcore.sim._cells`) on the nodes positions read,
    as they are read.

    The whole-model drop is a grey dilation (:func:`zwcore.sim.drop_cutter`): about three
    vector operations per four offsets of the ball's footprint at every model node, done
    once per stage; dropping at the positions costs the footprint per position (block
    skipping helps little on a model under the ball), per pass. The whole model is
    dropped when the ball's element is small (:data:`zwcore.sim.cutting.PRUNE_FOOTPRINT`),
    when it costs at most :data:`MAX_PASS_WORK` node visits, or when its nodes are at most
    :data:`DROP_SHARE` times the positions (a small ball at the input's level: its
    positions cover the model). Otherwise (a Ø20 ball finishing a fine model with few
    positions: 4e10 node visits at 1024² and 0.1 mm) each pass takes the bilinear
    drop-cutter on the rows around its positions only
    (:func:`~zwcore.scanline._stock_lines.drop_target`): the CL the tool paths take.
    """
    if simulation_work((1, 1), tool, sx, sy) <= PRUNE_FOOTPRINT:
        # a small element: the dilation is cheap (a Ø3 ball at 1025² and 0.1 mm, some
        # 0.1 s), on one thread (the plan's passes run on the plan's threads)
        return TargetCL(drop(model, sx, sy, tool, threads=1), model, sx, sy, tool, 1,
                        cell_bound)
    work = model.size * math.pi * (tool.radius / sx + 1.0) * (tool.radius / sy + 1.0)
    if work <= 4 * MAX_PASS_WORK or (INCREMENTAL and model.size <= DROP_SHARE * positions
                                     and work <= MAX_DROP_WORK):
        return TargetCL(drop(model, sx, sy, tool), model, sx, sy, tool, None, cell_bound)
    return None


#: Node-offset pairs beyond which a stage's target is not dropped on whole even when the
#: pass's positions cover its nodes (a Ø20 ball finishing a 1024² grid at 0.1 mm, 3.5e10:
#: about 40 s); its positions are dropped on the model's nodes by the line sweep instead.
MAX_DROP_WORK = 1 << 32


#: See :func:`target_drop`.
DROP_SHARE = 4

#: The next pass of a stage visits only what can change (:func:`_stock_state.next_state`), and
#: :func:`target_drop` weighs the drop against the positions. ``False``: every pass
#: simulates all its positions and the drop is bounded by the work alone (the method
#: before; for ``bench/bench_scanline_core.py`` and the tests that compare the two).
INCREMENTAL = True


def drop(model: F64, sx: float, sy: float, tool: Tool, threads: int | None = None) -> F64:
    """:func:`zwcore.sim.drop_cutter` (bilinear) on a model of spacing ``sx, sy``."""
    return drop_cutter(ZMap(model, dx=sx, dy=sy), tool, "bilinear", threads=threads)


def _on_nodes(pos: Positions, sx: float, sy: float) -> NDArray[np.bool_]:
    """Positions that sit on a node of spacing ``sx, sy`` (to 1e-9 of the spacing)."""
    return _k.on_nodes(pos.x, pos.y, 1.0 / sx, 1.0 / sy)
