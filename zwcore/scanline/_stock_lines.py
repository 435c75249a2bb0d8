"""The line sweep or the per-position kernels for a pass's positions, whichever costs
less (:mod:`zwcore.scanline._stock`): positions sorted by line for
:mod:`zwcore.scanline._stock_sweep`, and the drop-cutter against nodes either way."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.scanline import _stock_kernels as _k
from zwcore.scanline import _stock_sweep as _sw
from zwcore.scanline._stock_state import BLOCK, Positions, block_max
from zwcore.scanline._threads import both, split, split_at_weight
from zwcore.sim import drop_cutter

__all__ = ["SWEEP_RUN_SHARE", "SWEEP_SHARE", "THREAD_WORK", "LineSweep", "drop_nodes",
           "drop_target",
           "per_position"]

F64 = NDArray[np.float64]


#: The line sweep (:mod:`zwcore.scanline._stock_sweep`) runs instead of the per-position
#: kernels (envelope and drop against nodes) when its node visits are at most this share
#: of the footprint visits theirs would make. Those skip whole blocks the ball cannot
#: change and come out about 20 times under the footprint on the bench part; the sweep
#: visits every node of its rows, about 20 ns each (measured: a thinned Ø3 pass at 1025²,
#: share 0.18, took twice as long swept; the Ø20 finishing pass on every node, share
#: 0.013, ten times less). The highest stock within ``R`` stays per position: its block
#: bound (a block no higher than the best so far) beat the sweep at every size measured.
SWEEP_SHARE = 0.05

#: The share up to which :meth:`LineSweep.of` actually runs the sweep. Above
#: :data:`SWEEP_SHARE`: the sparse passes the block skipping does not thin much, and since
#: the sweep skips rows and chunks its bounds settle (:mod:`zwcore.scanline._stock_sweep`)
#: the dense ones too (1025² bench part: the Ø20's 4 225-position facing pass, share 0.12,
#: 0.29 s per position and 0.03 s swept; the Ø3 rest pass of 146 004 positions, share
#: 0.22, envelope 0.28 and 0.13 s, drop 0.24 and 0.14 s). The plan's work estimate
#: (``_stock_thin.pass_work``) keeps :data:`SWEEP_SHARE`, so the passes and their thinning
#: are unchanged; the kernels' results are the same either way.
SWEEP_RUN_SHARE = 0.5

#: Sweep node visits from which a sweep is split between two threads
#: (:mod:`zwcore.scanline._threads`; about 20 ns each: below, the hand-off costs more
#: than the second core saves).
THREAD_WORK = 1 << 21


@dataclass(frozen=True, eq=False)
class LineSweep:
    """Positions on scan lines sorted for :mod:`zwcore.scanline._stock_sweep` (by line,
    then along it), with the arrays' axes swapped for lines along y. The sweep gives the
    per-position kernels' results bit for bit (tests), so the choice is by cost alone."""

    order: NDArray[np.intp]
    u: F64
    v: F64
    starts: NDArray[np.int64]
    along_x: bool
    r: float
    du: float
    dv: float
    #: per line, its sweep's node visits (``_stock_sweep.sweep_work``)
    line_work: F64

    @classmethod
    def of(cls, px: F64, py: F64, along: str | None, r: float, dx: float,
           dy: float) -> LineSweep | None:
        """The sweep when the positions lie on lines (``along``) and it is cheaper."""
        if along is None or px.size == 0:
            return None
        along_x = along == "x"
        u, v = (px, py) if along_x else (py, px)
        du, dv = (dx, dy) if along_x else (dy, dx)
        per_position = px.size * math.pi * (r / dx + 1.0) * (r / dy + 1.0)
        order = np.lexsort((u, v))
        us, vs = np.ascontiguousarray(u[order]), np.ascontiguousarray(v[order])
        starts = _sw.line_starts(vs)
        if _sw.sweep_work(us, starts, r, du, dv) > max(SWEEP_SHARE,
                                                       SWEEP_RUN_SHARE) * per_position:
            return None
        return cls(order, us, vs, starts, along_x, r, du, dv,
                   _sw.line_work(us, starts, r, du, dv))

    @property
    def threaded(self) -> bool:
        """Whether the sweep is worth two threads (:data:`THREAD_WORK`; never on one, where
        the halves would run in turn and the split's halo only add work)."""
        return (self.starts.size > 2 and float(self.line_work.sum()) >= THREAD_WORK
                and split())

    def cut(self, stock: F64, cl: F64, touched: NDArray[np.bool_],
            skip: NDArray[np.bool_]) -> None:
        """:func:`_stock_kernels.cut` at the positions with CL ``cl`` (their order).

        A large sweep runs on two threads, each over its band of node rows (split where
        the lines' work is halved, at a block boundary): the bands' nodes are disjoint,
        and so are their blocks of ``touched``."""
        s, t, k = (stock, touched, skip) if self.along_x else (stock.T, touched.T, skip.T)
        c = np.ascontiguousarray(cl[self.order])

        def band(lo: int, hi: int) -> None:
            _sw.cut_lines(s, self.u, self.v, c, self.starts, self.r, self.du, self.dv,
                          BLOCK, t, k, lo, hi)

        mid = self._row_split(s.shape[0]) if self.threaded else 0
        if mid <= 0 or mid >= s.shape[0]:
            band(0, -1)
            return
        both(lambda: band(0, mid), lambda: band(mid, -1))

    def _row_split(self, nv: int) -> int:
        """The first node row of the second thread's band: the rows about the line that
        halves the sweep's work, rounded to a multiple of :data:`BLOCK`."""
        m = split_at_weight(self.line_work)
        return round(float(self.v[self.starts[m]]) / self.dv / BLOCK) * BLOCK

    def drop(self, z: F64, cl0: F64) -> F64:
        """:func:`_stock_kernels.cl_part` at the positions (their order); a large sweep
        on two threads, each over its lines (a position's CL depends on its line
        alone)."""
        zz = z if self.along_x else np.ascontiguousarray(z.T)
        c0 = np.ascontiguousarray(cl0[self.order])

        def lines(a: int, b: int) -> F64:
            j0, j1 = self.starts[a], self.starts[b]
            got: F64 = _sw.cl_lines(zz, self.u[j0:j1], self.v[j0:j1], c0[j0:j1],
                                    self.starts[a:b + 1] - j0, self.r, self.du, self.dv)
            return got

        count = self.starts.size - 1
        out = np.empty(self.order.size)
        if self.threaded:
            m = split_at_weight(self.line_work)
            first, second = both(lambda: lines(0, m), lambda: lines(m, count))
            out[self.order] = np.concatenate((first, second))
        else:
            out[self.order] = lines(0, count)
        return out


def drop_nodes(z: F64, zmax: F64, pos: Positions, cl0: F64, r: float, dx: float,
               dy: float) -> F64:
    """``max(cl0, max over nodes q within r of z[q] - h(|q - c|))`` at the positions (the
    line sweep or the per-position kernel, whichever is cheaper: the same values)."""
    sweep = LineSweep.of(pos.x, pos.y, pos.along, r, dx, dy)
    if sweep is not None:
        return sweep.drop(z, cl0)
    px, py = pos.x, pos.y
    return per_position(lambda a, b: _k.cl_part(z, zmax, BLOCK, px[a:b], py[a:b], cl0[a:b],
                                                 r, dx, dy), px.size, r, dx, dy)


def drop_target(model: F64, pos: Positions, tool: Tool, sx: float, sy: float) -> F64:
    """The drop-cutter CL on ``model`` (spacing ``sx, sy``) at the positions, where the
    whole model is not dropped: against its nodes (:func:`drop_nodes`), raised to the
    bilinear drop-cutter (:func:`zwcore.sim.drop_cutter`, pruned, on the rows around the
    positions only: a pass's lines use a few) interpolated at the positions, as the tool
    paths take it.

    The nodes alone let a ball sink below the surface between them where a steep wall
    stands at its rim (a Ø20 ball on the 513² bench part: 1.2 mm below the bilinear
    surface's CL; a Ø3 between nodes on the 1025² part: 1.9 mm below the paths' CL), and
    the program then left up to 5 mm where the plan said it finished.
    """
    cl = drop_nodes(model, block_max(model), pos, np.full(pos.size, -np.inf), tool.radius,
                    sx, sy)
    if tool.kind != "ball" or pos.size == 0:
        return cl
    px, py, su, sv, grid = pos.x, pos.y, sx, sy, model
    if pos.along == "y":  # lines along y: the transposed model's rows are its columns
        px, py, su, sv, grid = pos.y, pos.x, sy, sx, model.T
    nv = grid.shape[0]
    # the rows :func:`_k.interpolate` gives a weight (its own arithmetic: the lower row
    # clamped to the last but one); the others are never read with a weight, and are 0
    isv = 1.0 / sv
    fy = py * isv
    r0 = np.clip(np.floor(fy).astype(np.intp), 0, max(nv - 2, 0))
    ty = np.clip(fy - r0, 0.0, 1.0)
    rows = np.unique(np.concatenate([r0[ty < 1.0], np.minimum(r0 + 1, nv - 1)[ty > 0.0]]))
    grid = np.ascontiguousarray(grid)
    # one thread: the plan's passes already run on the plan's threads
    bil = drop_cutter(ZMap(grid, dx=su, dy=sv), tool, "bilinear", method="pruned", rows=rows,
                      threads=1)
    bil[np.isnan(bil)] = 0.0
    return np.maximum(cl, _k.interpolate(bil, 1.0 / su, isv, px, py))


#: The per-position kernels' block skipping leaves about this share of the nodes within
#: the radius to visit (:data:`SWEEP_SHARE`'s measure): for :func:`per_position`'s
#: estimate of their work.
BLOCK_VISIT_SHARE = 0.05


def per_position(kernel: Callable[[int, int], F64], n: int, r: float, dx: float,
                 dy: float) -> F64:
    """``kernel(0, n)`` for a per-position kernel (its output for positions ``a..b-1``
    depends on those alone), split between two threads at ``n / 2`` when its estimated
    node visits reach :data:`THREAD_WORK`: the same values."""
    work = n * math.pi * (r / dx + 1.0) * (r / dy + 1.0) * BLOCK_VISIT_SHARE
    if n < 2 or work < THREAD_WORK or not split():
        return kernel(0, n)
    h = n // 2
    first, second = both(lambda: kernel(0, h), lambda: kernel(h, n))
    return np.concatenate((first, second))
