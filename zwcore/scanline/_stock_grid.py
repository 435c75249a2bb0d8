"""Grid mode of the simulated stock (:mod:`zwcore.scanline._stock`): a pass whose
positions are most of the input nodes, done as whole-grid operations."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.scanline import _stock_kernels as _k
from zwcore.sim import envelope

__all__ = ["GRID_MODE_RADIUS", "GRID_MODE_SHARE", "GridMode"]

F64 = NDArray[np.float64]

#: Grid mode (below) for balls up to this many input spacings in radius.
GRID_MODE_RADIUS = 12

#: ... and when at least this share of the input nodes are positions of the pass.
GRID_MODE_SHARE = 0.25


class GridMode:
    """A pass whose positions are most of the input nodes (a ball at the input's own
    level): the stock within ``R`` and the envelope as whole-grid operations (a flat-disc
    dilation by row spans, :func:`zwcore.sim.envelope`), the kernels only for the
    positions off the nodes (ends of extra segments, lines between grid lines).

    Positions are ``px, py`` (n,) in mm from the grid's first node; ``b`` is the block
    size of the stock's block maxima ``smax``.
    """

    def __init__(self, on: NDArray[np.bool_], rows: NDArray[np.intp],
                 cols: NDArray[np.intp], b: int) -> None:
        self.on, self.rows, self.cols, self.b = on, rows, cols, b

    @classmethod
    def of(cls, px: F64, py: F64, part: ZMap, tool: Tool, b: int) -> GridMode | None:
        """Grid mode for a small ball when most input nodes are positions, else ``None``."""
        if (tool.radius > GRID_MODE_RADIUS * min(part.dx, part.dy)
                or px.size < GRID_MODE_SHARE * part.z.size):
            return None
        on, rows, cols = _k.node_index(px, py, 1.0 / part.dx, 1.0 / part.dy)
        if rows.size < GRID_MODE_SHARE * part.z.size:
            return None
        return cls(on, rows, cols, b)

    def top(self, stock: F64, smax: F64, part: ZMap, px: F64, py: F64, tool: Tool) -> F64:
        """Highest stock node within ``R`` of each position, (n,)."""
        out = np.empty(px.size)
        whole = _k.disc_max(stock, _half_widths(tool.radius, part.dx, part.dy))
        out[self.on] = whole[self.rows, self.cols]
        off = ~self.on
        if off.any():
            out[off] = _k.top(stock, smax, self.b, px[off], py[off], tool.radius,
                              part.dx, part.dy)
        return out

    def cut(self, stock: F64, smax: F64, part: ZMap, px: F64, py: F64, cl: F64,
            tool: Tool, touched: NDArray[np.bool_]) -> None:
        """Lower ``stock`` (in place) by the envelope of the positions; ``touched``
        ((ceil(ny/b), ceil(nx/b)) bool) is set on every block where a node was lowered."""
        off = ~self.on
        high = float(stock.max())  # a tip there cuts nothing
        grid = np.full(part.shape, high)
        grid[self.rows, self.cols] = np.minimum(cl[self.on], high)
        env = envelope(grid, tool, part.dx, part.dy, "bilinear")
        if off.any():
            _k.cut(stock, smax, self.b, px[off], py[off], np.ascontiguousarray(cl[off]),
                   tool.radius, part.dx, part.dy, touched, np.zeros_like(touched))
        _k.lower(stock, env, self.b, touched)


def _half_widths(r: float, dx: float, dy: float) -> NDArray[np.int64]:
    """Per row offset ``a = 0..A``: the largest ``b`` with ``(a dy)² + (b dx)² <= r²``."""
    a = np.arange(math.floor(r / dy + 1e-9) + 1)
    rest = np.maximum(r * r - (a * dy) ** 2, 0.0)
    out: NDArray[np.int64] = np.floor(np.sqrt(rest) / dx + 1e-9).astype(np.int64)
    # the same test as the kernels' d² <= r² RIM, node by node
    for n in range(a.size):
        while out[n] >= 0 and (a[n] * dy) ** 2 + (out[n] * dx) ** 2 > r * r * _k.RIM:
            out[n] -= 1
        while (a[n] * dy) ** 2 + ((out[n] + 1) * dx) ** 2 <= r * r * _k.RIM:
            out[n] += 1
    return out

