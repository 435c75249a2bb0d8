"""A tighter bilinear drop-cutter bound for balls: the ball's curvature under each cell.

The profiles of :mod:`zwcore.sim._profiles` bound the ball under a cell ``Q`` by one plane
``T <= h``; ``z - T`` is bilinear and peaks at a corner. The plane's gap to the ball is
about ``(dx² + dy²) / 8R`` inside the cell (a Ø8 ball at 0.39 mm: 0.0095 mm; a Ø1 at
0.1 mm: 0.005), so on grids coarse against the ball the CL stands that much too high and
a plan that holds a 0.007 mm share of its tolerance finishes nothing with it.

The ball's lower surface ``h(p) = R - sqrt(R² - |p|²)`` has Hessian eigenvalues
``1 / sqrt(R² - r²)`` (around the axis) and ``R² / (R² - r²)^1.5`` (radially), both at
least ``m = 1 / sqrt(R² - r_min²)`` on ``Q ∩ disc`` (``r_min``: the cell's least distance
from the axis). So for any ``p1`` in the convex ``Q ∩ disc``

    h(p) >= h(p1) + ∇h(p1).(p - p1) + m/2 |p - p1|²        on Q ∩ disc,

and ``max over Q of z(p) - [that]`` bounds the cell's share of the CL from above (the max
over all of ``Q`` covers ``Q ∩ disc``). With ``z`` bilinear, ``z - [that]`` is a quadratic
in the cell's coordinates ``(s, t)``: its maximum over the unit square is the interior
stationary point when the quadratic is concave and the point lies inside, else on an edge,
where it is a concave parabola (closed form). ``p1`` is the cell's centre for cells inside
the disc and the cell's point nearest the axis for cells the rim crosses.

The kernel takes the max over every cell of the grid within the radius (cells beyond the
grid carry no surface), skipping tiles of cells whose crude bound (highest node less the
ball's lowest point over them) and then cells whose plane or crude bound cannot beat the
best so far, and stops at the other method's value (it returns the least of the two: both
bound the true CL from above). Rounded once in float64, then raised by a bound of that rounding.
"""

from __future__ import annotations

import functools
import math
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from numba import njit
from numpy.typing import NDArray
from scipy import ndimage

from zwcore.sim._drop_bb import THREADS

__all__ = ["TIGHT_MAX_CELLS", "CellBound", "cells_within", "tighten"]

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

#: Balls whose disc covers more cells than this keep the plane bound: their gap is at most
#: about ``cell / 110`` (a Ø6 at 0.1 mm: 0.0008 mm) and the per-cell work grows with them.
TIGHT_MAX_CELLS = 1000
#: Cells a side of a tile (the first look skips whole tiles).
TILE = 4
#: A cell whose nearest point lies this close to the rim (share of R) takes its crude
#: bound (highest corner less ``h(r_min)``): the ball's slope there would make the
#: quadratic's terms large enough for rounding to matter.
_RIM_GUARD = 1e-6


def cells_within(radius: float, dx: float, dy: float) -> int:
    """About the cells a ball's disc meets: its area in cells plus its rim's."""
    return math.ceil(math.pi * (radius / dx + 1.0) * (radius / dy + 1.0))


@functools.lru_cache(maxsize=64)
def _cells(radius: float, dx: float, dy: float) -> tuple[I64, I64, F64, F64]:
    """Cells within reach as lower-left node offsets ``(a, b)`` (rows, columns), each
    cell's constants ``(s1, t1, h1, gx, gy, alpha, beta, hmin, plane at the corners 00,
    10, 01, 11)`` and its tile; sorted by tile, tiles by their least ``hmin``.

    Returns ``(a, b, consts (n, 12), tiles (k, 5): first cell, end, least a, least b,
    least hmin)``.
    """
    r = radius
    A, B = math.ceil(r / dy) + 1, math.ceil(r / dx) + 1
    aa, bb = np.mgrid[-A:A, -B:B]
    aa, bb = aa.ravel(), bb.ravel()
    y0, x0 = aa * dy, bb * dx
    y1, x1 = y0 + dy, x0 + dx
    ny_ = np.clip(0.0, y0, y1)  # the cell's point nearest the axis
    nx_ = np.clip(0.0, x0, x1)
    rmin = np.hypot(nx_, ny_)
    fy, fx = np.maximum(np.abs(y0), np.abs(y1)), np.maximum(np.abs(x0), np.abs(x1))
    rmax = np.hypot(fx, fy)
    keep = rmin < r
    aa, bb, y0, x0, rmin, rmax, nx_, ny_ = (v[keep] for v in (aa, bb, y0, x0, rmin, rmax,
                                                            nx_, ny_))
    crude = rmin >= r * (1.0 - _RIM_GUARD)
    rq = np.where(crude, 0.0, rmin)  # (the crude cells' constants are not used)
    inside = rmax < r * (1.0 - _RIM_GUARD)
    px = np.where(inside, x0 + 0.5 * dx, np.where(crude, 0.0, nx_))
    py = np.where(inside, y0 + 0.5 * dy, np.where(crude, 0.0, ny_))
    r1 = np.hypot(px, py)
    root = np.sqrt(r * r - r1 * r1)
    h1 = r - root
    gx, gy = px / root, py / root
    m = 1.0 / np.sqrt(r * r - rq * rq)
    hmin = r - np.sqrt(np.maximum(r * r - rmin * rmin, 0.0))
    s1, t1 = (px - x0) / dx, (py - y0) / dy
    # the tangent plane at p1 at the four corners (00, 10, 01, 11): the cell's plane bound
    # (a corner value less the plane), the first look before the quadratic
    planes = [h1 + gx * dx * (sc - s1) + gy * dy * (tc - t1)
              for sc, tc in ((0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0))]
    # a crude cell's "plane" is the ball's lowest point over it (the bound top - hmin)
    planes = [np.where(crude, hmin, pl) for pl in planes]
    consts = np.stack([s1, t1, h1, gx * dx, gy * dy, np.where(crude, -1.0, m * dx * dx),
                       m * dy * dy, hmin, *planes], axis=1)
    # tiles of TILE x TILE cells, each tile's cells together, tiles by least hmin
    tid = (np.floor_divide(aa, TILE) * (2 * B + TILE)) + np.floor_divide(bb, TILE)
    order = np.lexsort((hmin, tid))
    aa, bb, consts, tid = aa[order], bb[order], consts[order], tid[order]
    starts = np.flatnonzero(np.r_[True, tid[1:] != tid[:-1]])
    ends = np.r_[starts[1:], tid.size]
    tmin = np.minimum.reduceat(consts[:, 7], starts)
    # each tile's nodes: its cells' corner offsets span [amin, amax + 1] x [bmin, bmax + 1]
    amin = np.minimum.reduceat(aa, starts)
    bmin = np.minimum.reduceat(bb, starts)
    by = np.argsort(tmin, kind="stable")
    tiles = np.stack([starts[by], ends[by], amin[by], bmin[by]], axis=1).astype(np.int64)
    return (aa.astype(np.int64), bb.astype(np.int64), consts,
            np.c_[tiles.astype(np.float64), tmin[by]])


@njit(cache=True, nogil=True)
def _cell_max(z00: float, z10: float, z01: float, z11: float, c: F64) -> float:
    """``max over the unit square of z(s, t) - [h(p1) + ∇h(p1).(p - p1) + m/2 |p - p1|²]``
    (``c``: one row of :func:`_cells`' constants)."""
    s1, t1, h1, gx, gy, al, be = c[0], c[1], c[2], c[3], c[4], c[5], c[6]
    B = z10 - z00
    C = z01 - z00
    D = z00 - z10 - z01 + z11
    # phi = K + b s + c t + D s t - al/2 (s - s1)² - be/2 (t - t1)²
    K = z00 - h1 + gx * s1 + gy * t1
    b = B - gx
    cc = C - gy
    best = -math.inf
    det = al * be - D * D
    if det > 0.0:
        u = b + al * s1
        v = cc + be * t1
        s = (u * be + D * v) / det
        t = (al * v + D * u) / det
        if 0.0 <= s <= 1.0 and 0.0 <= t <= 1.0:
            ds, dt = s - s1, t - t1
            return K + b * s + cc * t + D * s * t - 0.5 * (al * ds * ds + be * dt * dt)
    for e in range(4):
        if e < 2:  # s fixed at 0 or 1: a parabola in t
            s = float(e)
            t = t1 + (cc + D * s) / be
            t = min(1.0, max(0.0, t))
        else:  # t fixed
            t = float(e - 2)
            s = s1 + (b + D * t) / al
            s = min(1.0, max(0.0, s))
        ds, dt = s - s1, t - t1
        v = K + b * s + cc * t + D * s * t - 0.5 * (al * ds * ds + be * dt * dt)
        if v > best:
            best = v
    return best


@njit(cache=True, nogil=True)
def _first_look(z00: float, z10: float, z01: float, z11: float, c: F64) -> float:
    """The least of a cell's plane bound (a corner less the tangent plane at ``p1``) and
    its crude bound (the highest corner less ``h(r_min)``)."""
    return min(max(max(z00 - c[8], z10 - c[9]), max(z01 - c[10], z11 - c[11])),
               max(max(z00, z10), max(z01, z11)) - c[7])


@njit(cache=True, nogil=True)
def _cell_value(z00: float, z10: float, z01: float, z11: float, c: F64) -> float:
    """A cell's share of the CL bound: the least of its plane, crude and quadratic bounds."""
    v = _first_look(z00, z10, z01, z11, c)
    if c[5] > 0.0:  # (else a crude cell: its plane is hmin)
        v = min(v, _cell_max(z00, z10, z01, z11, c))
    return v


@njit(cache=True, nogil=True)
def _rows(z: F64, wmax: F64, pad: int, a: I64, b: I64, consts: F64, tiles: F64,
          rows: I64, r0: int, r1: int, loose: F64, margin: float, where: NDArray[np.bool_],
          masked: bool, out: F64) -> None:
    ny, nx = z.shape
    for j in range(r0, r1):
        i = rows[j]
        last = -1
        for k in range(nx):
            if masked and not where[i, k]:
                continue  # (out holds the loose value)
            win = last
            cap = loose[i, k]
            best = -math.inf
            done = False
            # the cell that decided the node before (coherence along a row) first: a
            # good first value lets the plane bounds skip most cells
            if last >= 0:
                ii = i + a[last]
                kk = k + b[last]
                if 0 <= ii and 0 <= kk and ii + 1 < ny and kk + 1 < nx:
                    best = _cell_value(z[ii, kk], z[ii, kk + 1], z[ii + 1, kk],
                                       z[ii + 1, kk + 1], consts[last])
            for q in range(tiles.shape[0]):
                ta = i + int(tiles[q, 2])
                tb = k + int(tiles[q, 3])
                if wmax[ta + pad, tb + pad] - tiles[q, 4] <= best:
                    continue
                for n in range(int(tiles[q, 0]), int(tiles[q, 1])):
                    ii = i + a[n]
                    kk = k + b[n]
                    if ii < 0 or kk < 0 or ii + 1 >= ny or kk + 1 >= nx:
                        continue
                    z00 = z[ii, kk]
                    z10 = z[ii, kk + 1]
                    z01 = z[ii + 1, kk]
                    z11 = z[ii + 1, kk + 1]
                    # a cell's value is the least of its three bounds, each >= its share
                    # of the true CL: so each first look (the tile's, the cell's) bounds
                    # it, and the max is the same whatever the order of the looks
                    v = _first_look(z00, z10, z01, z11, consts[n])
                    if v <= best:
                        continue
                    if consts[n, 5] > 0.0:  # (else a crude cell: its plane is hmin)
                        v = min(v, _cell_max(z00, z10, z01, z11, consts[n]))
                    if v > best:
                        best = v
                        win = n
                        if best + margin >= cap:
                            done = True
                            break
                if done:
                    break
            if not done and best > -math.inf:
                out[i, k] = min(cap, best + margin)
            else:
                out[i, k] = cap
            last = win


class CellBound:
    """The per-cell bound of a ball of ``radius`` on one surface: the cells' constants and
    the tiles' node maxima built once, for any number of :meth:`apply` calls (a plan reads
    a target's CL a few positions at a time)."""

    def __init__(self, z: F64, dx: float, dy: float, radius: float) -> None:
        self.z = np.ascontiguousarray(z, np.float64)
        self.a, self.b, self.consts, self.tiles = _cells(radius, dx, dy)
        ny, nx = self.z.shape
        self.pad = int(max(np.abs(self.a).max(initial=0), np.abs(self.b).max(initial=0))) \
            + TILE + 2
        self._wmax: F64 | None = None
        # the sums are rounded in float64; the quadratic's terms stay within about 1e3
        # times the heights (the ball's slope at the rim guard): 1e-10 of the scale
        self.margin = 1e-10 * (float(np.abs(self.z).max(initial=0.0)) + radius + 1.0)
        self.empty = ny < 2 or nx < 2 or self.a.size == 0

    @property
    def wmax(self) -> F64:
        """The max over each tile's nodes, any tile anywhere: windows of ``TILE + 1``
        nodes over the surface padded with -inf beyond the grid."""
        if self._wmax is None:
            ny, nx, pad = *self.z.shape, self.pad
            zp = np.full((ny + 2 * pad, nx + 2 * pad), -np.inf)
            zp[pad:pad + ny, pad:pad + nx] = self.z
            self._wmax = ndimage.maximum_filter(zp, size=TILE + 1, mode="constant",
                                                cval=-np.inf, origin=-(TILE // 2))
        return self._wmax

    def apply(self, cl: F64, rows: NDArray[np.integer] | None = None,
              threads: int | None = None, where: NDArray[np.bool_] | None = None) -> None:
        """Lower ``cl`` (float64, C-contiguous, a CL never below the true one) in place
        to the per-cell bound on ``rows`` and ``where``."""
        ny = self.z.shape[0]
        which = (np.arange(ny, dtype=np.int64) if rows is None
                 else np.unique(np.asarray(rows, np.int64)))
        mask = (np.ones((1, 1), dtype=np.bool_) if where is None
                else np.ascontiguousarray(where, dtype=np.bool_))
        if where is not None:
            which = which[mask[which].any(axis=1)]
        if self.empty or which.size == 0:
            return
        n_threads = THREADS if threads is None else max(1, int(threads))
        cut = np.linspace(0, len(which), max(1, min(n_threads, len(which))) + 1
                          ).astype(np.int64)
        wmax = self.wmax

        def band(j: int) -> None:
            _rows(self.z, wmax, self.pad, self.a, self.b, self.consts, self.tiles, which,
                  int(cut[j]), int(cut[j + 1]), cl, self.margin, mask, where is not None, cl)

        if len(cut) == 2:
            band(0)
        else:
            with ThreadPoolExecutor(len(cut) - 1) as pool:
                list(pool.map(band, range(len(cut) - 1)))


def tighten(z: F64, dx: float, dy: float, radius: float, loose: F64,
            rows: NDArray[np.integer] | None = None, threads: int | None = None,
            where: NDArray[np.bool_] | None = None) -> F64:
    """The least of ``loose`` (a bilinear drop-cutter CL of a ball of ``radius``) and the
    per-cell bound (module docstring), on ``rows`` (default all) and ``where`` (default
    everywhere); elsewhere ``loose`` as given.

    Parameters
    ----------
    z : (ny, nx) float64
        The surface's nodes.
    loose : (ny, nx) float64
        A CL never below the true one (:func:`zwcore.sim.drop_cutter`'s plane bound).

    Returns
    -------
    cl : (ny, nx) float64
        Never below the true drop-cutter height over the bilinear surface, never above
        ``loose``.
    """
    out = np.array(loose, dtype=np.float64, copy=True)
    CellBound(z, dx, dy, radius).apply(out, rows, threads, where)
    return out
