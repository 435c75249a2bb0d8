"""The line sweep or the per-position kernels for a pass's positions, whichever costs
less (:mod:`zwcore.scanline._stock`): positions sorted by line for
:mod:`zwcore.scanline._stock_sweep`, and the drop-cutter against nodes either way."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from zwcore.scanline import _stock_kernels as _k
from zwcore.scanline import _stock_sweep as _sw
from zwcore.scanline._stock_state import BLOCK, Positions

__all__ = ["SWEEP_RUN_SHARE", "SWEEP_SHARE", "LineSweep", "drop_nodes"]

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
        return cls(order, us, vs, starts, along_x, r, du, dv)

    def cut(self, stock: F64, cl: F64, touched: NDArray[np.bool_],
            skip: NDArray[np.bool_]) -> None:
        """:func:`_stock_kernels.cut` at the positions with CL ``cl`` (their order)."""
        s, t, k = (stock, touched, skip) if self.along_x else (stock.T, touched.T, skip.T)
        _sw.cut_lines(s, self.u, self.v, np.ascontiguousarray(cl[self.order]),
                      self.starts, self.r, self.du, self.dv, BLOCK, t, k)

    def drop(self, z: F64, cl0: F64) -> F64:
        """:func:`_stock_kernels.cl_part` at the positions (their order)."""
        zz = z if self.along_x else np.ascontiguousarray(z.T)
        out = np.empty(self.order.size)
        out[self.order] = _sw.cl_lines(zz, self.u, self.v,
                                       np.ascontiguousarray(cl0[self.order]), self.starts,
                                       self.r, self.du, self.dv)
        return out


def drop_nodes(z: F64, zmax: F64, pos: Positions, cl0: F64, r: float, dx: float,
               dy: float) -> F64:
    """``max(cl0, max over nodes q within r of z[q] - h(|q - c|))`` at the positions (the
    line sweep or the per-position kernel, whichever is cheaper: the same values)."""
    sweep = LineSweep.of(pos.x, pos.y, pos.along, r, dx, dy)
    if sweep is not None:
        return sweep.drop(z, cl0)
    return _k.cl_part(z, zmax, BLOCK, pos.x, pos.y, cl0, r, dx, dy)
