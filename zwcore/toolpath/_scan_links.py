"""Where a scan-line stage's stretches run, and how low a rapid may come down before one.

Two pieces of :mod:`zwcore.toolpath.scanline_paths`, in the frame where lines run along
``u`` at offsets ``v`` (mm from the grid's first node):

- :func:`region_stretches`: the stretches of lines inside a stage's region mask (at the
  stage's resolution);
- :func:`link_heights`: an upper bound of the stock after the stage's whole lines, from
  those lines' final paths alone (a ball whose tip passes over ``(u, v_line)`` at height
  ``z`` leaves nothing above ``z + R - sqrt(R^2 - d^2)`` at the node ``(u, v)``,
  ``d = |v - v_line| < R``; no sweep of the stock), and from it the lowest height a
  ball's tip may keep along a straight link between two points (or over one point) and
  meet no stock: the max over the nodes within its reach of the bound minus the ball's rise
  ``R - sqrt(R^2 - d^2)`` at the node's distance ``d`` from the link. Links between
  segments stay down above it, or lift only to above it, and entries come down to it.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

F64 = NDArray[np.float64]


def region_stretches(region: NDArray[np.bool_], offset: F64, start: F64, stop: F64,
                     su: float, sv: float) -> tuple[NDArray[np.int64], F64, F64]:
    """The stretches of lines inside a region.

    Parameters
    ----------
    region : (mv, mu) bool
        Where the stage cuts, on its model's nodes (rows across the lines).
    offset, start, stop : (n,) float64
        The lines (mm).
    su, sv : float
        The model's spacing along and across the lines, mm.

    Returns
    -------
    line : (m,) int64
        The line of each stretch (in order).
    start, stop : (m,) float64
        Stretches: a cell between two model nodes along a line is cut when any of the
        (up to four) model nodes around it lies in the region.
    """
    mv, mu = region.shape
    pos = offset / sv
    r0 = np.clip(np.floor(pos + 1e-9).astype(np.int64), 0, mv - 1)
    r1 = np.where(pos - r0 > 1e-9, np.minimum(r0 + 1, mv - 1), r0)
    node = region[r0] | region[r1]  # (n, mu)
    cell = node[:, :-1] | node[:, 1:]  # (n, mu - 1), cell c spans [c su, (c + 1) su]
    pad = np.zeros((len(offset), mu + 1), np.int8)
    pad[:, 1:-1] = cell
    edge = np.diff(pad, axis=1)
    li, c0 = np.nonzero(edge == 1)
    _, c1 = np.nonzero(edge == -1)  # same row order: one end per start
    a = np.maximum(c0 * su, start[li])
    b = np.minimum(c1 * su, stop[li])
    keep = b > a
    return li[keep], a[keep], b[keep]


def merge_stretches(offset: F64, start: F64, stop: F64) -> tuple[F64, F64, F64]:
    """Stretches on the same line that overlap or touch, merged (the plan may give one
    stretch several times), in serpentine order: by offset, and along every other offset's
    stretches backwards, so that consecutive stretches lie close.

    Parameters
    ----------
    offset, start, stop : (n,) float64

    Returns
    -------
    offset, start, stop : (m,) float64
        The union of the input stretches per offset, as disjoint stretches.
    """
    if not len(offset):
        return offset, start, stop
    order = np.lexsort((start, offset))
    o, a, b = offset[order], start[order], stop[order]
    new_line = np.ones(len(o), bool)
    new_line[1:] = o[1:] != o[:-1]
    # the furthest stop so far on each line (a running max that restarts at each line)
    line_id = np.cumsum(new_line) - 1
    shift = line_id * (float(b.max() - a.min()) + 1.0)
    reach = np.maximum.accumulate(b + shift) - shift
    new = new_line.copy()
    new[1:] |= a[1:] > reach[:-1]
    first = np.flatnonzero(new)
    last = np.append(first[1:], len(o)) - 1
    mo, ma, mb = o[first], a[first], reach[last]
    # every other line backwards (by the rank of its offset)
    rank = np.cumsum(np.r_[True, mo[1:] != mo[:-1]]) - 1
    key = np.where(rank % 2 == 1, -ma, ma)
    order = np.lexsort((key, rank))
    return mo[order], ma[order], mb[order]


#: Links up to this many tool radii (and at least 2 mm) long are bounded node by node with
#: the ball's rise; longer ones by blocks of about a radius (their max, no rise).
EXACT_RADII = 4.0


class StockBound:
    """An upper bound of the stock after a stage's whole lines, on the part's nodes, and
    the lowest tip height along straight links that meets none of it.

    Parameters
    ----------
    line_v : (nl,) float64
        Offsets of the stage's whole lines, increasing.
    line_paths : list of (k, 2) float64
        Each whole line's final path ``(u, z)``, ``u`` increasing.
    du, dv : float
        The part's spacing along and across the lines.
    shape_uv : (int, int)
        The part's nodes along and across the lines.
    radius : float
    stock_top : float
        The stock before the program (an upper bound everywhere).
    before : (n_v, n_u) float64, optional
        An upper bound of the stock before the stage (the stock only falls, so the bound
        after the stage is the lesser of it and the whole lines' own).
    """

    def __init__(self, line_v: F64, line_paths: list[F64], du: float, dv: float,
                 shape_uv: tuple[int, int], radius: float, stock_top: float,
                 before: F64 | None = None):
        n_u, n_v = shape_uv
        z_line = np.empty((len(line_paths), n_u))
        for j, path in enumerate(line_paths):
            _along(np.ascontiguousarray(path[:, 0]), np.ascontiguousarray(path[:, 1]), du,
                   z_line[j])
        #: ``(n_v, n_u)``: the bound on the nodes
        self.grid = np.empty((n_v, n_u))
        low = (np.zeros((0, 0)) if before is None
               else np.ascontiguousarray(before, np.float64))
        _bound_grid(np.ascontiguousarray(line_v, np.float64), z_line, float(dv),
                    float(radius), float(stock_top), low, self.grid)
        self.block = max(1, int(radius / max(du, dv)))
        self._coarse: F64 | None = None
        self.du, self.dv, self.radius = float(du), float(dv), float(radius)
        self.exact_length = max(2.0, EXACT_RADII * radius)

    @property
    def coarse(self) -> F64:
        """Maxima of the bound over blocks of :attr:`block` nodes a side (built on first
        use: only long links need it)."""
        if self._coarse is None:
            b = self.block
            n_v, n_u = self.grid.shape
            self._coarse = np.empty((-(-n_v // b), -(-n_u // b)))
            _block_max(self.grid, b, self._coarse)
        return self._coarse

    def heights(self, a: F64, b: F64) -> F64:
        """Lowest tip height along each straight link at which the ball meets no stock.

        Parameters
        ----------
        a, b : (m, 2) float64
            Links from ``a`` to ``b``, ``(u, v)``, mm (``a == b``: over one point).

        Returns
        -------
        (m,) float64
            For links up to ``exact_length``: the max over the nodes within ``radius`` of
            the link's xy segment of the bound there minus the ball's rise at the node's
            distance from the segment; longer links: the max of the bound over blocks
            holding every such node (higher). ``-inf`` when no node is that near. A move
            along the link whose tip stays at or above it removes nothing.
        """
        a = np.ascontiguousarray(a, np.float64).reshape(-1, 2)
        b = np.ascontiguousarray(b, np.float64).reshape(-1, 2)
        out = np.empty(len(a))
        short = np.hypot(*(b - a).T) <= self.exact_length
        for sel, blk in ((short, 1), (~short, self.block)):
            if sel.any():
                grid = self.grid if blk == 1 else self.coarse
                res = np.empty(int(sel.sum()))
                _capsule_max(np.ascontiguousarray(a[sel]), np.ascontiguousarray(b[sel]), grid,
                             blk, self.du, self.dv, self.radius, self.grid.shape[0],
                             self.grid.shape[1], res)
                out[sel] = res
        return out


def link_heights(a: F64, b: F64, line_v: F64, line_paths: list[F64], du: float, dv: float,
                 shape_uv: tuple[int, int], radius: float, stock_top: float) -> F64:
    """:meth:`StockBound.heights` of a :class:`StockBound` built from the other arguments."""
    return StockBound(line_v, line_paths, du, dv, shape_uv, radius, stock_top).heights(a, b)


@njit(cache=True, nogil=True)
def _along(u: F64, z: F64, du: float, out: F64) -> None:
    """``np.interp`` of the polyline ``(u, z)`` (``u`` increasing) at the nodes ``k du``,
    clamped at its ends, in one merge pass."""
    j = 0
    m = len(u)
    for k in range(len(out)):
        x = k * du
        if m == 1 or x <= u[0]:
            out[k] = z[0]
        elif x >= u[m - 1]:
            out[k] = z[m - 1]
        else:
            while u[j + 1] < x:
                j += 1
            t = (x - u[j]) / (u[j + 1] - u[j]) if u[j + 1] > u[j] else 0.0
            out[k] = z[j] + t * (z[j + 1] - z[j])


@njit(cache=True, nogil=True)
def _bound_grid(line_v: F64, z_line: F64, dv: float, radius: float, stock_top: float,
                before: F64, out: F64) -> None:
    """Per node, the least of the stock top, ``before`` (when it has rows) and each nearest
    whole line's tip height plus the ball's rise at the node's distance from that line
    (when within ``radius``). The rise depends on the row only: its square root is taken
    once per row and line (the sum in the same order, so the same values)."""
    nl = len(line_v)
    r2 = radius * radius
    lower = before.shape[0] > 0
    for i in range(out.shape[0]):
        v = i * dv
        below = int(np.searchsorted(line_v, v, side="right")) - 1
        j0, j1, s0, s1 = -1, -1, 0.0, 0.0
        if 0 <= below < nl and abs(line_v[below] - v) < radius:
            d = abs(line_v[below] - v)
            j0, s0 = below, math.sqrt(r2 - d * d)
        if 0 <= below + 1 < nl and abs(line_v[below + 1] - v) < radius:
            d = abs(line_v[below + 1] - v)
            j1, s1 = below + 1, math.sqrt(r2 - d * d)
        for k in range(out.shape[1]):
            bound = stock_top
            if j0 >= 0:
                bound = min(bound, z_line[j0, k] + radius - s0)
            if j1 >= 0:
                bound = min(bound, z_line[j1, k] + radius - s1)
            if lower:
                bound = min(bound, before[i, k])
            out[i, k] = bound


@njit(cache=True, nogil=True)
def _block_max(grid: F64, b: int, out: F64) -> None:
    """``out[I, K]``: the max of ``grid`` over the block of ``b x b`` nodes at ``(I, K)``
    (the last blocks cut at the grid's edge)."""
    n_v, n_u = grid.shape
    for bi in range(out.shape[0]):
        for bk in range(out.shape[1]):
            out[bi, bk] = -np.inf
        for i in range(bi * b, min(bi * b + b, n_v)):
            for bk in range(out.shape[1]):
                m = out[bi, bk]
                for k in range(bk * b, min(bk * b + b, n_u)):
                    m = max(m, grid[i, k])
                out[bi, bk] = m


#: A node is passed over when its bound lies this far (mm) under the best value so far
#: plus the least rise its row allows (the two rises' roundings differ by far less).
SKIP_MARGIN = 1e-6


@njit(cache=True, nogil=True)
def _capsule_max(a: F64, b: F64, grid: F64, blk: int, du: float, dv: float, radius: float,
                 n_v: int, n_u: int, out: F64) -> None:
    """Per link, over the nodes within ``radius`` of its segment: with ``blk == 1`` the max
    of ``grid`` minus the ball's rise at each node (each node tested exactly); else
    ``grid`` holds the maxima of blocks of ``blk x blk`` nodes and the max runs over the
    blocks holding any such node (no rise). Row (of blocks) by row over the u range of the
    capsule's slice: the segment's points within ``radius`` of the row's v range, widened
    by ``radius``. With ``blk == 1`` the row nearest the segment's middle goes first; in
    the others a node whose bound, less the least rise of its row (its v distance from
    the segment's v range), cannot exceed the best so far is passed over (the max is the
    same)."""
    for e in range(len(a)):
        ua, va, ub, vb = a[e, 0], a[e, 1], b[e, 0], b[e, 1]
        i0 = max(0, math.floor((min(va, vb) - radius) / dv))
        i1 = min(n_v - 1, math.ceil((max(va, vb) + radius) / dv))
        best = -math.inf
        mid = -1
        if blk == 1:
            mid = min(max(round(0.5 * (va + vb) / dv), i0), i1)
            best = _capsule_row(ua, va, ub, vb, mid, grid, 1, du, dv, radius, n_u, best)
        for bi in range(i0 // blk, i1 // blk + 1):
            if bi == mid:
                continue
            best = _capsule_row(ua, va, ub, vb, bi, grid, blk, du, dv, radius, n_u, best)
        out[e] = best


@njit(cache=True, nogil=True, inline="always")
def _capsule_row(ua: float, va: float, ub: float, vb: float, bi: int, grid: F64, blk: int,
                 du: float, dv: float, radius: float, n_u: int, best: float) -> float:
    """:func:`_capsule_max` over one row of ``grid`` (of blocks when ``blk > 1``)."""
    eu, ev = ub - ua, vb - va
    ll = eu * eu + ev * ev
    r2 = radius * radius
    lo = bi * blk * dv - va - radius  # the segment's v within reach of the rows
    hi = (bi * blk + blk - 1) * dv - va + radius
    if abs(ev) > 1e-300:
        t0 = max(0.0, min(lo / ev, hi / ev))
        t1 = min(1.0, max(lo / ev, hi / ev))
        if t0 > t1:
            return best
    else:
        if lo > 0.0 or hi < 0.0:
            return best
        t0, t1 = 0.0, 1.0
    k0 = max(0, math.floor((ua + min(t0 * eu, t1 * eu) - radius) / du))
    k1 = min(n_u - 1, math.ceil((ua + max(t0 * eu, t1 * eu) + radius) / du))
    if blk > 1:
        for bk in range(k0 // blk, k1 // blk + 1):
            best = max(best, grid[bi, bk])
        return best
    w = bi * dv - va
    gap = max(0.0, min(va, vb) - bi * dv, bi * dv - max(va, vb))
    least = radius - math.sqrt(max(r2 - gap * gap, 0.0))  # the row's least rise
    for k in range(k0, k1 + 1):
        if grid[bi, k] <= best + least - SKIP_MARGIN:  # no new max, whatever its rise
            continue
        pu = k * du - ua
        t = 0.0 if ll <= 0.0 else min(1.0, max(0.0, (pu * eu + w * ev) / ll))
        qu, qv = pu - t * eu, w - t * ev
        dd = qu * qu + qv * qv
        if dd <= r2:
            best = max(best, grid[bi, k] - (radius - math.sqrt(r2 - dd)))
    return best
