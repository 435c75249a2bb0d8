"""A lifted pass's unlifted CL found only where the flute rule may leave it
(:mod:`zwcore.scanline._stock`, :func:`lazy_state`)."""

from __future__ import annotations

from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.scanline import _stock_bounds as _b
from zwcore.scanline import _stock_kernels as _k
from zwcore.scanline._stock_lines import drop_target
from zwcore.scanline._stock_state import (
    BLOCK,
    Positions,
    State,
    TargetCL,
    Thin,
    block_max,
    grow_blocks,
)
from zwcore.scanline.results import ScanLines

__all__ = ["Sim", "exact_base", "lazy_state"]

F64 = NDArray[np.float64]


class Sim(Protocol):
    """The simulated stock as read here (:class:`zwcore.scanline._stock.StockSim`)."""

    part: ZMap
    stock: F64
    zmax: F64

    def top(self, pos: Positions, idx: NDArray[np.intp], tool: Tool, smax: F64,
            grid_ok: bool) -> F64: ...

    def base_cl(self, model_cl: F64, pos: Positions, tool: Tool) -> F64: ...


def lazy_state(sim: Sim, model: F64, spacing: tuple[float, float], tool: Tool,
               lines: ScanLines, thin: Thin, pos: Positions, target_cl: TargetCL | None,
               guard: float) -> State:
    """The first state of a lifted pass (``_stock._first_state``), its unlifted CL found
    only where the flute rule may leave it.

    The drop-cutter of a large ball at every position (on the model's nodes when the
    target is not dropped whole, against the part's nodes off them) is most of a dense
    pass's cost, yet where the highest stock within ``R`` less the flute length lies
    above an upper bound of that CL the position is lifted whatever the CL is (a facing
    pass over the stock top). The bound: the largest model node (and part node, off
    the model's nodes) the ball can reach, by blocks (``_stock_state.grow_blocks``); a
    drop-cutter CL is never above the highest node within ``R``. The top is read first,
    at the positions a lower bound of the CL (``_stock_bounds.nearest_low``) does not
    rule out; the exact CL is found at the others and kept, the bound where the
    position is lifted (``State.exact``; ``_stock.run_pass`` finds the exact CL when a
    later pass needs it, :func:`exact_base`). The pass is the eager one's, bit for bit
    (tests).
    """
    sx, sy = spacing
    part, r = sim.part, tool.radius
    on = _k.on_nodes(pos.x, pos.y, 1.0 / sx, 1.0 / sy)
    if target_cl is None:
        low = _b.nearest_low(model, sx, sy, pos.x, pos.y, r)
        high = _b.block_at(grow_blocks(block_max(model), r, sx, sy), BLOCK, pos.x, pos.y,
                           1.0 / sx, 1.0 / sy)
    else:
        low = _k.interpolate(target_cl.at(pos.x, pos.y), 1.0 / sx, 1.0 / sy, pos.x, pos.y)
        high = low.copy()
    part_high = _b.block_at(grow_blocks(sim.zmax, r, part.dx, part.dy), BLOCK, pos.x,
                            pos.y, 1.0 / part.dx, 1.0 / part.dy)
    high = np.where(on, high, np.maximum(high, part_high))
    smax = block_max(sim.stock)
    may = _k.may_cut(grow_blocks(smax, r, part.dx, part.dy), BLOCK, pos.x, pos.y, low,
                     1.0 / part.dx, 1.0 / part.dy)
    act = np.flatnonzero(may)
    top = np.full(pos.size, -np.inf)
    top[act] = sim.top(pos, act, tool, smax, thin.k == 1)
    base = low  # exact where ``on`` with a dropped target; never read where not ``act``
    exact = np.ones(pos.size, dtype=bool)
    base[act] = high[act]
    exact[act] = False
    need = top[act] - tool.flute_length + guard
    exact_base(sim, model, spacing, tool, pos, act[need <= high[act]], target_cl, base,
               exact)
    return State(lines, thin, pos, act, top, base, base.copy(), np.zeros(pos.size),
                 True, exact)


def exact_base(sim: Sim, model: F64, spacing: tuple[float, float], tool: Tool,
                pos: Positions, idx: NDArray[np.intp], target_cl: TargetCL | None, base: F64,
                exact: NDArray[np.bool_]) -> None:
    """The unlifted CL at the positions ``idx`` (into ``base``, in place): on the
    target (dropped whole, or on the model's nodes at the positions) and against the
    part's nodes off the model's nodes."""
    if idx.size == 0:
        return
    sx, sy = spacing
    sub = Positions(pos.x[idx], pos.y[idx], pos.along)
    if target_cl is None:
        cl = drop_target(model, sub, tool, sx, sy)
    else:
        cl = _k.interpolate(target_cl.at(sub.x, sub.y), 1.0 / sx, 1.0 / sy, sub.x, sub.y)
    off = np.flatnonzero(~_k.on_nodes(sub.x, sub.y, 1.0 / sx, 1.0 / sy))
    if off.size:
        cl[off] = sim.base_cl(cl[off], Positions(sub.x[off], sub.y[off], pos.along), tool)
    base[idx] = cl
    exact[idx] = True
