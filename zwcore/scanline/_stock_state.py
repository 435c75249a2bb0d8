"""What the passes of a stage share in the simulated stock (:mod:`zwcore.scanline._stock`):
positions, block maxima, and the state per position that lets a stage's next pass visit
only what can change (:func:`next_state`)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.scanline import _stock_kernels as _k
from zwcore.scanline.results import ScanLines
from zwcore.sim import CellBound, takes_cell_bound

__all__ = ["BLOCK", "Last", "PassMemo", "Positions", "Sim", "State", "TargetCL", "Thin",
           "block_max", "grow_blocks", "next_state", "read_nodes"]

F64 = NDArray[np.float64]

#: Input nodes per side of the blocks the kernels skip whole.
BLOCK = 8


def block_max(z: F64, b: int = BLOCK) -> F64:
    """``(ceil(ny/b), ceil(nx/b))``: the largest value of every ``b x b`` block of nodes."""
    out: F64 = _k.block_max(np.ascontiguousarray(z), b)
    return out


@dataclass(frozen=True, eq=False)
class Positions:
    """Tool positions of one pass: ``x, y`` in mm from the grid's first node, ``(n,)``;
    ``along``: the direction of the scan lines they lie on (``"x"``, ``"y"``; ``None``:
    not known, the line-sweep kernels are not used)."""

    x: F64
    y: F64
    along: str | None = None

    @property
    def size(self) -> int:
        return int(self.x.size)


class Thin(Protocol):
    """A pass's thinning (:class:`_stock_thin.Thinning`): every ``k``-th line and point."""

    @property
    def k(self) -> int: ...

    def lift(self, model: F64, spacing: tuple[float, float], pos: Positions,
             need: F64) -> int: ...


class Sim(Protocol):
    """The simulated stock as :func:`next_state` reads it (:class:`_stock.StockSim`)."""

    part: ZMap
    stock: F64

    def top(self, pos: Positions, idx: NDArray[np.intp], tool: Tool, smax: F64,
            grid_ok: bool) -> F64: ...


class PassMemo:
    """What the passes of one stage share: the drop-cutter of its target (computed once)
    and, per set of scan lines, the last pass on them, per position (:func:`_next_state`),
    with every block any pass lowered since."""

    def __init__(self) -> None:
        self._last: dict[int, tuple[ScanLines, Last]] = {}
        #: the target's drop-cutter once computed (``dropped``; ``None``: per position)
        self.drop: TargetCL | None = None
        self.dropped = False

    def find(self, lines: ScanLines, stride: int,
             region: NDArray[np.bool_] | None) -> Last | None:
        """The last pass on these lines (same stride and region), if any."""
        got = self._last.get(id(lines))
        if got is None or got[0] is not lines:
            return None
        last = got[1]
        return last if last.stride == stride and last.region is region else None

    def keep(self, lines: ScanLines, last: Last) -> None:
        """Record a pass on ``lines``; the blocks it lowered count for the others too."""
        for _, other in self._last.values():
            np.logical_or(other.touched, last.touched, out=other.touched)
        self._last[id(lines)] = (lines, last)

    def forget(self, lines: ScanLines) -> None:
        """Drop the state of a pass on ``lines`` that was undone (its stock restored: the
        blocks it lowered stay marked for the others, which only costs a re-read)."""
        self._last.pop(id(lines), None)



@dataclass(frozen=True, eq=False)
class Last:
    """One pass, per position, for the next pass of its stage.

    ``base`` is the unlifted CL (the target's; where the position may cut, at least the
    part's nodes' too), ``cl`` the CL it cut at, ``top`` the highest stock before it
    within ``R`` (-inf where that is known to lie at or under ``base``), ``depth`` its
    depth of cut, ``touched`` the blocks whose stock it lowered.
    """

    lines: ScanLines
    stride: int
    region: NDArray[np.bool_] | None
    pos: Positions
    base: F64
    cl: F64
    top: F64
    depth: F64
    touched: NDArray[np.bool_]
    thin: Thin
    #: where ``base`` is the unlifted CL itself; elsewhere an upper bound of it, left so
    #: because the flute rule lifted the position above that bound (``None``: everywhere)
    exact: NDArray[np.bool_] | None = None


@dataclass(frozen=True, eq=False)
class State:
    """A pass before the flute rule: positions, the ones to decide again (``cand``),
    and per position the highest stock within ``R``, unlifted CL, CL and depth so far
    (fresh arrays: the pass fills ``cl`` and ``depth`` at ``cand``)."""

    lines: ScanLines
    thin: Thin
    pos: Positions
    cand: NDArray[np.intp]
    top: F64
    base: F64
    cl: F64
    depth: F64
    first: bool
    exact: NDArray[np.bool_] | None = None  # as :attr:`Last.exact`


def next_state(sim: Sim, tool: Tool, last: Last) -> State:
    """The next pass on the last pass's positions, visiting only what can change.

    The stock only falls, and the last pass left it at or under the ball at every
    position. So a position not lifted last time (CL = its unlifted CL) whose stock
    within ``R`` is unchanged keeps its CL, depth and (not) binding, and cuts nothing;
    one whose highest stock within ``R`` lay at or under its unlifted CL keeps that too.
    Decided again: the positions lifted last time (their CL may fall, and they cut
    where it does) and those within ``R`` of a block any pass lowered since the last
    one on these positions (their highest stock within ``R`` is read again).
    """
    part = sim.part
    pos = last.pos
    top = last.top  # updated in place: the last pass's figures are kept as numbers
    grown = grow_blocks(last.touched.astype(np.float64), tool.radius, part.dx, part.dy)
    # a position whose unlifted CL is only bounded is read again whatever that bound
    base = last.base if last.exact is None else np.where(last.exact, last.base, -np.inf)
    dirty = _k.near_blocks(grown, BLOCK, pos.x, pos.y, top, base, 1.0 / part.dx,
                           1.0 / part.dy)
    if dirty.size:
        top[dirty] = sim.top(pos, dirty, tool, block_max(sim.stock), last.thin.k == 1)
    again = last.cl > last.base
    again[dirty] = True
    cand = np.flatnonzero(again)
    return State(last.lines, last.thin, pos, cand, top, last.base, last.cl, last.depth,
                 False, last.exact)


def grow_blocks(smax: F64, r: float, dx: float, dy: float) -> F64:
    """Block maxima grown by the blocks a ball of radius ``r`` centred in a block reaches."""
    # a position lies within half a spacing of the node whose block it is looked up in
    reach = r + max(dx, dy)
    ga, gb = math.ceil(reach / (BLOCK * dy)), math.ceil(reach / (BLOCK * dx))
    out: F64 = ndimage.maximum_filter(smax, size=(2 * ga + 1, 2 * gb + 1), mode="nearest")
    return out


class TargetCL:
    """A stage target's whole drop-cutter CL, with a small ball's per-cell bound
    (:class:`zwcore.sim.CellBound`) computed on the nodes positions read, when they first
    read them: a node's value is then the same whichever passes read it first (the
    per-cell bound of a node does not depend on the others)."""

    def __init__(self, cl: F64, model: F64, sx: float, sy: float, tool: Tool,
                 threads: int | None, cell_bound: bool) -> None:
        self.cl = np.ascontiguousarray(cl, dtype=np.float64)
        self.sx, self.sy, self.threads = sx, sy, threads
        small = cell_bound and takes_cell_bound(tool, sx, sy)
        #: the per-cell bound on the model as dropped (later passes lift their own copies)
        self.bound = CellBound(model.copy(), sx, sy, tool.radius) if small else None
        self.done = np.zeros(cl.shape, dtype=bool) if small else None

    def at(self, x: F64, y: F64) -> F64:
        """The CL grid, final on every node a bilinear read at ``(x, y)`` weighs."""
        if self.bound is not None and self.done is not None and x.size:
            need = read_nodes(x, y, self.sx, self.sy, self.cl.shape)
            need &= ~self.done
            if need.any():
                self.bound.apply(self.cl, threads=self.threads, where=need)
                self.done |= need
        return self.cl


def read_nodes(x: F64, y: F64, sx: float, sy: float, shape: tuple[int, int]
               ) -> NDArray[np.bool_]:
    """The nodes :func:`interpolate` reads at ``(x, y)`` (a cell's four corners, clamped as
    it clamps)."""
    my, mx = shape
    c0 = np.clip(np.floor(x / sx).astype(np.intp), 0, max(mx - 2, 0))
    r0 = np.clip(np.floor(y / sy).astype(np.intp), 0, max(my - 2, 0))
    out = np.zeros(shape, dtype=bool)
    for dr in (0, 1):
        for dc in (0, 1):
            out[np.minimum(r0 + dr, my - 1), np.minimum(c0 + dc, mx - 1)] = True
    return out
