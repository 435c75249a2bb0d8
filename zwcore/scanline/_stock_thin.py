"""Thinning of a pass too large to simulate at every position (:mod:`zwcore.scanline._stock`):
every ``k``-th line and point, within a gap the flute rule's lift covers."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.scanline import _stock_kernels as _k
from zwcore.scanline import _stock_lines as _ls
from zwcore.scanline._stock_grid import GRID_MODE_RADIUS
from zwcore.scanline._stock_state import Positions
from zwcore.scanline.results import ScanLines

__all__ = ["Thinning", "pass_work"]

F64 = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class Thinning:
    """A pass too large to simulate at every position: lines on grid lines at most ``k``
    grid lines apart (every ``k``-th where there is one on every grid line; and the
    last), every ``k``-th point along them, extra lines dropped, ``k`` no larger than
    keeps every node within the ball's radius of a simulated position. The stock it
    leaves is higher than the full pass's (safe for the next pass's flute rule). The rule
    holds at the simulated positions; every model node within the gap of a binding one
    is raised to its height (:meth:`lift`), so the positions left out stand at least
    that high, which bounds but does not prove their depth (reading the stock a gap
    further out proved it, but then counted walls of the part no lift can clear, and
    stages stalled)."""

    lines: ScanLines
    k: int
    gap: float  # the largest distance from a position left out to a simulated one, bound

    @classmethod
    def build(cls, lines: ScanLines, part: ZMap, stride: int, tool: Tool,
              spacing: tuple[float, float], cusp: float | None, max_work: float,
              enabled: bool, cusp_rule: bool) -> Thinning:
        """The thinning of a pass on ``lines`` (``stride`` input nodes between positions):
        ``k`` doubled while the work is over ``max_work`` (:func:`pass_work`) and the gap
        within ``0.7 R`` (and, with ``cusp`` and ``cusp_rule``, within the cusp rule);
        ``enabled`` False: never thinned."""
        along = part.dx if lines.direction == "x" else part.dy
        across = spacing[1] if lines.direction == "x" else spacing[0]
        # The lines on grid lines (segments sorted by offset): on every one, or every few
        # where a finishing pass's scallop allows (zwcore.scanline._passes). Thinning keeps
        # lines at most k grid lines apart among those present (on every grid line: those
        # with index divisible by k, as ever), and its work counts what it keeps. Keeping
        # grid lines by index alone kept every lcm-th of a coarse pass's lines: 28 mm apart
        # for a Ø20 ball at 2049², and the next ball met the uncut ridges between them.
        idx = lines.offset / across
        on_grid = np.flatnonzero(np.abs(idx - np.rint(idx)) <= 1e-9)
        grid_idx = np.rint(idx[on_grid]).astype(np.int64)
        last = lines.offset >= lines.offset.max()
        # Every node stays within the radius of a simulated position (gap <= 0.7 R), so the
        # simulated positions still cut all the stock the lift reads; with ``cusp`` the
        # gap also keeps the cusp between simulated positions, gap² / (8R), under it.
        limit = 0.7 * tool.radius
        if cusp is not None and cusp_rule:
            limit = min(limit, math.sqrt(8.0 * tool.radius * cusp))
        unit = max(across, stride * along)
        k, kept = 1, lines
        small = tool.radius <= GRID_MODE_RADIUS * min(part.dx, part.dy)  # grid mode copes
        while (enabled and not small and pass_work(kept, part, stride, tool, k)
               > max_work and 2 * k * unit <= limit):
            k *= 2
            keep = np.zeros(lines.offset.size, dtype=bool)
            keep[on_grid] = np.isin(grid_idx, grid_idx[_within(grid_idx, k)])
            keep |= last
            kept = ScanLines(lines.direction, lines.offset[keep], lines.start[keep],
                             lines.stop[keep])
        if k == 1:
            return cls(lines, 1, 0.0)
        return cls(kept, k, k * unit)

    def lift(self, model: F64, spacing: tuple[float, float], pos: Positions, need: F64) -> int:
        return int(_k.raise_box(model, spacing[0], spacing[1], pos.x, pos.y,
                                np.ascontiguousarray(need), self.gap))


def _within(grid_idx: NDArray[np.int64], k: int) -> NDArray[np.intp]:
    """Lines to keep (indices into ``grid_idx``, the sorted grid-line indices of the lines
    present) so that kept ones are at most ``k`` grid lines apart where the lines allow:
    the first, then each time the furthest within ``k`` of the last kept (a step longer
    than ``k`` keeps both its ends). On every grid line from 0: those divisible by ``k``."""
    out = []
    i, n = 0, grid_idx.size
    while i < n:
        out.append(i)
        j = int(np.searchsorted(grid_idx, grid_idx[i] + k, side="right")) - 1
        i = j if j > i else i + 1
    return np.asarray(out, dtype=np.intp)


def pass_work(kept: ScanLines, part: ZMap, stride: int, tool: Tool, k: int) -> float:
    """Node visits of a pass thinned by ``k`` (``kept``: the lines it keeps; every
    ``k``-th point along them), in units of the per-position kernels' footprint
    (positions times the nodes within ``R``): the line sweep's visits over
    :data:`_stock_lines.SWEEP_SHARE` where it is the cheaper
    (:class:`_stock_lines.LineSweep`), as the kernels are chosen."""
    along_x = kept.direction == "x"
    du, dv = (part.dx, part.dy) if along_x else (part.dy, part.dx)
    r = tool.radius
    count = max(float(kept.offset.size), 1.0)
    points = kept.length / (k * stride * du) + kept.offset.size
    footprint = points * math.pi * (r / part.dx + 1.0) * (r / part.dy + 1.0)
    # per line and row within R: its positions and the nodes its balls span
    span = kept.length / count / du + 2.0 * r / du
    sweep = (points + count * span) * (2.0 * r / dv + 1.0)
    share = _ls.SWEEP_SHARE
    return min(footprint, sweep / share) if share > 0.0 else footprint
