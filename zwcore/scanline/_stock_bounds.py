"""Block bounds that settle most of a dense pass of a large ball without its kernels
(:mod:`zwcore.scanline._stock`).

A large ball's kernels cost the ball's rows (or footprint) per position, whatever the
stock and the CL look like. On the stock a facing pass meets, or under a pass whose CL
is level over a ball's width, the answer follows from two block bounds that meet:

- **Highest stock within R** (:func:`top_bounded`): at most the largest block maximum
  of the blocks the ball can reach (:func:`zwcore.scanline._stock_state.grow_blocks`),
  at least the largest of the blocks lying wholly within ``R`` of the position
  (:func:`inner_max`: every node of such a block counts, and a block maximum is some
  node's value). Where the two agree, that is the answer, exactly.
- **Envelope** (:func:`settle`): a node that holds a position of the pass whose CL ``c``
  is the least of every position the ball can reach from that node's block gets
  ``min(stock, c)`` exactly (that position's own ball is ``c + h(0) = c`` there, every
  other one ``c' + h >= c``, also in floating point since rounding is monotone). A
  block all of whose nodes are settled is left out of the kernels (``skip``): they
  could only compute values at or above what it holds.

Everything else goes through the kernels as before: the results are the same bit for
bit (tests). Positions are ``(px, py)`` in mm from the grid's first node and are looked
up in the block of their nearest node (``b x b`` nodes per block).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray
from scipy import ndimage

from zwcore.scanline._stock_kernels import RIM

__all__ = ["block_at", "inner_max", "nearest_low", "settle", "top_bounded"]

F64 = NDArray[np.float64]


@njit(cache=True, nogil=True)
def block_at(grid: F64, b: int, px: F64, py: F64, idx: float, idy: float) -> F64:
    """Per position, ``grid`` (block values) at the block of its nearest node."""
    my, mx = grid.shape
    out = np.empty(px.size)
    for n in range(px.size):
        bi = min(max(round(py[n] * idy) // b, 0), my - 1)
        bk = min(max(round(px[n] * idx) // b, 0), mx - 1)
        out[n] = grid[bi, bk]
    return out


def _inner_footprint(r: float, dx: float, dy: float, b: int) -> NDArray[np.bool_]:
    """Block offsets ``(da, db)`` whose every node lies within ``r`` of every point a
    position looked up in block ``(0, 0)`` may take (its nearest node in that block: the
    block's node box grown by half a spacing), with a relative margin of 1e-9 (the
    kernels count ``d² <= r² RIM``, a superset)."""
    ra, rb = math.floor(r / (b * dy)), math.floor(r / (b * dx))
    da = np.abs(np.arange(-ra, ra + 1))[:, None]
    db = np.abs(np.arange(-rb, rb + 1))[None, :]
    fy = (da * b + b - 0.5) * dy  # farthest across: node box end to the far half spacing
    fx = (db * b + b - 0.5) * dx
    out: NDArray[np.bool_] = fx * fx + fy * fy <= r * r * (1.0 - 1e-9)
    return out


def inner_max(smax: F64, r: float, dx: float, dy: float, b: int) -> F64:
    """Per block, the largest block maximum of the blocks wholly within ``r`` of any
    position looked up in it (-inf: none)."""
    foot = _inner_footprint(r, dx, dy, b)
    if not foot.any():
        return np.full(smax.shape, -np.inf)
    out: F64 = ndimage.maximum_filter(smax, footprint=foot, mode="constant", cval=-np.inf)
    return out


def top_bounded(smax: F64, grown: F64, shape: tuple[int, int], px: F64, py: F64, r: float,
                dx: float, dy: float, b: int) -> tuple[F64, NDArray[np.intp]]:
    """Highest stock within ``r`` where the block bounds settle it.

    Parameters
    ----------
    smax : (my, mx) float64
        Block maxima of the stock.
    grown : (my, mx) float64
        ``grow_blocks(smax, r, dx, dy)``: an upper bound per position's block.
    shape : (ny, nx)
        The stock's.
    px, py : (n,) float64

    Returns
    -------
    top : (n,) float64
        The answer where settled (NaN elsewhere).
    rest : (m,) intp
        The positions left to the kernels.
    """
    hi = block_at(grown, b, px, py, 1.0 / dx, 1.0 / dy)
    lo = block_at(inner_max(smax, r, dx, dy, b), b, px, py, 1.0 / dx, 1.0 / dy)
    # a position whose nearest node lies off the grid is not where its block says
    ny, nx = shape
    inside = ((np.rint(px / dx) >= 0) & (np.rint(px / dx) < nx)
              & (np.rint(py / dy) >= 0) & (np.rint(py / dy) < ny))
    sure = (lo >= hi) & inside
    top = np.where(sure, hi, np.nan)
    return top, np.flatnonzero(~sure)


def settle(stock: F64, px: F64, py: F64, cl: F64, r: float, dx: float, dy: float, b: int,
           touched: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """Lower (in place) the nodes whose own position's CL is the least within reach to
    that CL; returns the blocks whose every node is settled so (the kernels skip them).

    ``touched`` ((my, mx) bool) is set where a node was lowered.
    """
    cmin = _block_min(px, py, cl, touched.shape[0], touched.shape[1], b, 1.0 / dx,
                      1.0 / dy)
    reach = r + max(dx, dy)  # positions lie within half a spacing of their block's node
    ga, gb = math.ceil(reach / (b * dy)), math.ceil(reach / (b * dx))
    least = ndimage.minimum_filter(cmin, size=(2 * ga + 1, 2 * gb + 1), mode="constant",
                                   cval=np.inf)
    return _settle(stock, px, py, cl, least, b, 1.0 / dx, 1.0 / dy, touched)


@njit(cache=True, nogil=True)
def _block_min(px: F64, py: F64, cl: F64, my: int, mx: int, b: int, idx: float,
               idy: float) -> F64:
    """Least CL of the positions looked up in each block (+inf: none)."""
    out = np.full((my, mx), np.inf)
    for n in range(px.size):
        bi = min(max(round(py[n] * idy) // b, 0), my - 1)
        bk = min(max(round(px[n] * idx) // b, 0), mx - 1)
        out[bi, bk] = min(out[bi, bk], cl[n])
    return out


@njit(cache=True, nogil=True)
def _settle(s: F64, px: F64, py: F64, cl: F64, least: F64, b: int, idx: float,
            idy: float, touched: NDArray[np.bool_]) -> NDArray[np.bool_]:
    ny, nx = s.shape
    my, mx = least.shape
    count = np.zeros((my, mx), dtype=np.int64)
    done = np.zeros((ny, nx), dtype=np.bool_)
    for n in range(px.size):
        fx, fy = px[n] * idx, py[n] * idy
        k, i = round(fx), round(fy)
        if abs(fx - k) > 1e-9 or abs(fy - i) > 1e-9 or not (0 <= i < ny and 0 <= k < nx):
            continue
        bi, bk = i // b, k // b
        c = cl[n]
        if least[bi, bk] < c:
            continue
        if c < s[i, k]:
            s[i, k] = c
            touched[bi, bk] = True
        if not done[i, k]:
            done[i, k] = True
            count[bi, bk] += 1
    easy = np.zeros((my, mx), dtype=np.bool_)
    for bi in range(my):
        for bk in range(mx):
            full = (min(bi * b + b, ny) - bi * b) * (min(bk * b + b, nx) - bk * b)
            easy[bi, bk] = count[bi, bk] == full
    return easy


@njit(cache=True, nogil=True)
def nearest_low(z: F64, sx: float, sy: float, px: F64, py: F64, r: float) -> F64:
    """A lower bound of the drop-cutter on the nodes ``z`` (spacing ``sx, sy``) at
    each position: the ball resting on its nearest node, ``z[q] - h(|q - c|)`` by the
    kernels' own expression (-inf when that node lies beyond ``r``)."""
    my, mx = z.shape
    r2, rin = r * r, r * r * RIM
    out = np.empty(px.size)
    for n in range(px.size):
        k = min(max(round(px[n] / sx), 0), mx - 1)
        i = min(max(round(py[n] / sy), 0), my - 1)
        ex, ey = k * sx - px[n], i * sy - py[n]
        d2 = ex * ex + ey * ey
        out[n] = z[i, k] - (r - math.sqrt(max(r2 - d2, 0.0))) if d2 <= rin else -np.inf
    return out
