"""The drop-cutter dilation of large tools by branch and bound over tiles of offsets.

:func:`zwcore.sim.drop_cutter` visits every offset of the tool's element at every node:
``(2R/dx)²`` of them, about 43,000 for a Ø20 ball at 0.1 mm (a vector pass each, 10-20 s
on a 1025² grid). Near where the tool touches, only a few offsets decide the maximum. This
module computes the same ``CL[p] = min over v of max over offsets o of z[p + o] + s[v, o]``
(the same structuring functions :func:`~zwcore.sim._profiles.drop_profile`) exactly, in
float64, but skips tiles of offsets that cannot hold the maximum.

**The tile bound.** Offsets are cut into square tiles (``T1`` offsets a side, each cut into
sub-tiles of ``T2``). Per tile ``T`` (centre ``o_c``, half extents ``h``) a plane slope
``g_T`` (the ball profile's gradient at ``o_c``) and ``err[v, T] = max over o in T of
s[v, o] - g_T.(o - o_c)``. Per window of ``T x T`` nodes of the surface (every position
``w``, centre ``q_c``) a plane slope ``G_w`` and ``top[w] = max over its nodes q of
z[q] - G_w.(q - q_c)``. For a node ``p`` and the window at ``p + T`` (``q - q_c = o - o_c``)

    z[p + o] + s[v, o] <= top[w] + err[v, T] + (G_w + g_T).(o - o_c)
                      <= top[w] + err[v, T] + |G_wx + g_Tx| h_x + |G_wy + g_Ty| h_y.

Where the tool touches, the surface's slope and the profile's (mirrored) agree, so the
bound is tight to the profile's and the surface's curvature over a tile; far from the
contact the profile drops away and whole tiles go. Per node and function: a first lower
bound from the offsets around where the node before touched (coherence along a row), then
every tile whose bound exceeds the best value so far has its sub-tiles bounded, and only
sub-tiles that could exceed it are summed exactly. A function after the first stops as
soon as it reaches the least maximum found (it cannot lower the minimum).

The result is the exact maximum in float64 (sums rounded once) raised by a rounding bound:
never below the exact value of the same structuring functions, so never below the true
drop-cutter height over the continuous surface (the profiles' guarantee); it differs from
:func:`~zwcore.sim._morph.dilate`'s float32 run by that run's rounding (at most about
2e-5 mm, which rounds *up*). Rows run in bands on threads (the kernel releases the GIL).
"""

from __future__ import annotations

import math
import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from numba import njit
from numpy.typing import NDArray

from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.sim._profiles import drop_profile

__all__ = ["drop_cutter_pruned"]

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

#: Tile and sub-tile sizes (offsets a side).
T1, T2 = 32, 8
#: Threads (bands of rows).
THREADS = max(1, min(4, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity")
                     else (os.cpu_count() or 1)))


@njit(cache=True, nogil=True)
def _windows(zp: F64, t: int, dx: float, dy: float, w: F64) -> None:
    """Per window of ``t x t`` nodes of ``zp`` (anchored at its first row and column),
    ``w[i, k] = (top, gx, gy, zmax)``: a plane slope from its corner nodes (0 if one is off
    the surface), the max of ``z - plane`` over its finite nodes (``-inf``: none) and the
    max of ``z``."""
    ny, nx = w.shape[0], w.shape[1]
    half = 0.5 * (t - 1)
    for i in range(ny):
        for k in range(nx):
            c00, c01 = zp[i, k], zp[i, k + t - 1]
            c10, c11 = zp[i + t - 1, k], zp[i + t - 1, k + t - 1]
            sx = sy = 0.0
            if t > 1 and (math.isfinite(c00) and math.isfinite(c01) and math.isfinite(c10)
                          and math.isfinite(c11)):
                sx = 0.5 * ((c01 - c00) + (c11 - c10)) / ((t - 1) * dx)
                sy = 0.5 * ((c10 - c00) + (c11 - c01)) / ((t - 1) * dy)
            best = high = -math.inf
            for a in range(t):
                ly = sy * (a - half) * dy
                for b in range(t):
                    v = zp[i + a, k + b]
                    if v > -math.inf:
                        best = max(best, v - ly - sx * (b - half) * dx)
                        high = max(high, v)
            w[i, k, 0], w[i, k, 1], w[i, k, 2], w[i, k, 3] = best, sx, sy, high


@njit(cache=True, nogil=True)
def _windows_up(sub: F64, t: int, r: int, dx: float, dy: float, w: F64) -> None:
    """Windows of ``r t x r t`` nodes from the ``r x r`` windows of ``t`` inside each
    (``sub``, as :func:`_windows` gives): the plane slope is the sub-windows' mean, and for
    a node ``q`` of sub-window ``j`` (centre ``c_j``, half extents ``h``)
    ``z(q) - G.(q - c) <= top_j + |g_j - G|.h - G.(c_j - c)``: a bound of ``top`` (the max
    of ``zmax`` is exact)."""
    ny, nx = w.shape[0], w.shape[1]
    hx, hy = 0.5 * (t - 1) * dx, 0.5 * (t - 1) * dy
    mid = 0.5 * (r - 1) * t
    for i in range(ny):
        for k in range(nx):
            sx = sy = 0.0
            n = 0
            for a in range(r):
                for b in range(r):
                    if sub[i + a * t, k + b * t, 0] > -math.inf:
                        sx += sub[i + a * t, k + b * t, 1]
                        sy += sub[i + a * t, k + b * t, 2]
                        n += 1
            if n:
                sx /= n
                sy /= n
            best = high = -math.inf
            for a in range(r):
                ia = i + a * t
                for b in range(r):
                    kb = k + b * t
                    top = sub[ia, kb, 0]
                    if top > -math.inf:
                        best = max(best, top + abs(sub[ia, kb, 1] - sx) * hx
                                   + abs(sub[ia, kb, 2] - sy) * hy
                                   - sx * (b * t - mid) * dx - sy * (a * t - mid) * dy)
                        high = max(high, sub[ia, kb, 3])
            w[i, k, 0], w[i, k, 1], w[i, k, 2], w[i, k, 3] = best, sx, sy, high


@njit(cache=True, nogil=True, inline="always")
def _bound(w: F64, wa: int, wb: int, g: F64, err: F64, smax: F64, v: int, ua: int, ub: int,
           hx: float, hy: float) -> float:
    """The least of the plane bound and ``zmax + max s`` for tile ``(ua, ub)`` read
    through the window at ``(wa, wb)``."""
    return min(w[wa, wb, 0] + err[v, ua, ub] + abs(w[wa, wb, 1] + g[ua, ub, 0]) * hx
               + abs(w[wa, wb, 2] + g[ua, ub, 1]) * hy, w[wa, wb, 3] + smax[v, ua, ub])


@njit(cache=True, nogil=True)
def _exact(zp: F64, s: F64, v: int, pi: int, pk: int, a0: int, a1: int, b0: int, b1: int,
           best: float, arg: I64) -> float:
    """Max of ``zp[pi + a, pk + b] + s[v, a, b]`` over the offsets ``a0..a1 - 1, b0..b1 - 1``
    and ``best``; ``arg`` gets the offset of a new maximum."""
    for a in range(a0, a1):
        for b in range(b0, b1):
            sv = s[v, a, b]
            if sv > -math.inf:
                val = zp[pi + a, pk + b] + sv
                if val > best:
                    best = val
                    arg[0], arg[1] = a, b
    return best


@njit(cache=True, nogil=True)
def _rows(zp: F64, s: F64, w1: F64, w2: F64, g1: F64, err1: F64, max1: F64, g2: F64,
          err2: F64, max2: F64, h1: tuple[float, float], h2: tuple[float, float],
          which: I64, row_lo: int, row_hi: int, nx: int, out: F64) -> None:
    """Rows ``which[row_lo..row_hi - 1]`` of the pruned dilation into ``out``.

    ``zp``: the surface padded with -inf (offset ``(a, b)`` of node ``(i, k)`` is
    ``zp[i + a, k + b]``, ``a, b`` from 0); ``s`` padded to whole tiles; ``w1, w2``: the
    windows of tiles and sub-tiles (:func:`_windows`); ``g, err, max`` per tile and per
    sub-tile (:func:`_tile_planes`)."""
    nv = s.shape[0]
    n1a, n1b = err1.shape[1], err1.shape[2]
    r = T1 // T2
    arg = np.zeros(2, np.int64)
    bounds = np.empty(n1a * n1b)
    last = np.zeros((nv, 2), np.int64)
    for n in range(row_lo, row_hi):
        i = which[n]
        for v in range(nv):  # start at the element's centre
            last[v, 0], last[v, 1] = (s.shape[1] - 1) // 2, (s.shape[2] - 1) // 2
        for k in range(nx):
            least = math.inf
            for v in range(nv):
                # a first lower bound around where the node before touched (the same
                # contact point is one column further left in offsets)
                ca = last[v, 0]
                cb = min(max(last[v, 1] - 1, 0), s.shape[2] - 1)
                arg[0], arg[1] = ca, cb
                best = _exact(zp, s, v, i, k, max(0, ca - 2), min(s.shape[1], ca + 3),
                              max(0, cb - 2), min(s.shape[2], cb + 3), -math.inf, arg)
                if best < least:
                    for ta in range(n1a):
                        for tb in range(n1b):
                            bounds[ta * n1b + tb] = _bound(w1, i + ta * T1, k + tb * T1, g1,
                                                           err1, max1, v, ta, tb, h1[0], h1[1])
                    for ta in range(n1a):
                        for tb in range(n1b):
                            if bounds[ta * n1b + tb] <= best:
                                continue
                            for sa in range(r):
                                for sb in range(r):
                                    a0, b0 = ta * T1 + sa * T2, tb * T1 + sb * T2
                                    if _bound(w2, i + a0, k + b0, g2, err2, max2, v,
                                              ta * r + sa, tb * r + sb, h2[0], h2[1]) > best:
                                        best = _exact(zp, s, v, i, k, a0, a0 + T2, b0, b0 + T2,
                                                      best, arg)
                            if best >= least:  # this function cannot lower the minimum
                                break
                        if best >= least:
                            break
                last[v, 0], last[v, 1] = arg[0], arg[1]
                least = min(least, best)
            out[i, k] = least


def _tile_planes(s: F64, t: int, dx: float, dy: float, radius: float
                 ) -> tuple[F64, F64, F64]:
    """Per tile of ``t x t`` offsets of ``s`` (V, na, nb), padded to whole tiles: the plane
    slope ``g`` (nt_a, nt_b, 2: x, y per mm, the ball's gradient at the tile's centre),
    ``err`` (V, nt_a, nt_b), the max of ``s - g.(o - o_c)`` over the tile (-inf: empty),
    and the max of ``s`` over it."""
    nv, na, nb = s.shape
    A, B = (na - 1) // 2, (nb - 1) // 2  # the centre before padding (padding is at the end)
    nta, ntb = na // t, nb // t
    a_c = (np.arange(nta) * t + 0.5 * (t - 1) - A) * dy
    b_c = (np.arange(ntb) * t + 0.5 * (t - 1) - B) * dx
    yy, xx = np.meshgrid(a_c, b_c, indexing="ij")
    root = np.sqrt(np.maximum(radius**2 - xx**2 - yy**2, (0.05 * radius) ** 2))
    g = np.stack([-xx / root, -yy / root], axis=-1)
    oy = (np.arange(t) - 0.5 * (t - 1)) * dy
    ox = (np.arange(t) - 0.5 * (t - 1)) * dx
    plane = (g[:, :, None, None, 0] * ox[None, None, None, :]
             + g[:, :, None, None, 1] * oy[None, None, :, None])  # (nta, ntb, t, t)
    tiles = s.reshape(nv, nta, t, ntb, t).transpose(0, 1, 3, 2, 4)
    with np.errstate(invalid="ignore"):
        err = (tiles - plane[None]).max(axis=(3, 4))
    return (np.ascontiguousarray(g), np.ascontiguousarray(err),
            np.ascontiguousarray(tiles.max(axis=(3, 4))))


def drop_cutter_pruned(part: ZMap, tool: Tool, rows: NDArray[np.integer] | None = None,
                       threads: int | None = None) -> F64:
    """Bilinear drop-cutter CL of a (large) tool by branch and bound (module docstring).

    Parameters
    ----------
    part : ZMap
        ``(ny, nx)`` nodes.
    tool : Tool
    rows : (m,) int, optional
        Only these rows (each node's value depends on the surface alone, not on other
        rows: they are the same numbers as in the whole grid); default all.

    Returns
    -------
    cl : (ny, nx) float64
        Never below the exact dilation by :func:`~zwcore.sim._profiles.drop_profile`'s
        ``bilinear`` functions (so never below the true drop-cutter height over the
        continuous surface); above it by at most a float64 rounding bound. With ``rows``,
        the other rows are NaN.
    threads : int, optional
        Threads for the rows (default :data:`THREADS`); a caller that runs on several
        threads already asks for one.
    """
    s0 = np.asarray(drop_profile(tool, part.dx, part.dy, "bilinear"), np.float64)
    s0 = s0[None] if s0.ndim == 2 else s0
    nv, na, nb = s0.shape
    A, B = (na - 1) // 2, (nb - 1) // 2
    pa, pb = -(-na // T1) * T1, -(-nb // T1) * T1
    s = np.full((nv, pa, pb), -np.inf)
    s[:, :na, :nb] = s0
    ny, nx = part.shape
    z = np.asarray(part.z, np.float64)
    # offset (a, b) of node (i, k) reads zp[i + a, k + b]: A rows / B columns of -inf
    # before the surface, enough after it for every window of every tile
    zp = np.full((ny + pa + T1, nx + pb + T1), -np.inf)
    zp[A:A + ny, B:B + nx] = z
    # windows of sub-tiles from the nodes, of tiles from those (a bound, 16 reads each)
    w2 = np.empty((ny + pa + T1 - T2, nx + pb + T1 - T2, 4))
    _windows(zp, T2, part.dx, part.dy, w2)
    w1 = np.empty((ny + pa, nx + pb, 4))
    _windows_up(w2, T2, T1 // T2, part.dx, part.dy, w1)
    tile_g, tile_err, tile_max = _tile_planes(s, T1, part.dx, part.dy, tool.radius)
    sub_g, sub_err, sub_max = _tile_planes(s, T2, part.dx, part.dy, tool.radius)
    h1 = (0.5 * (T1 - 1) * part.dx, 0.5 * (T1 - 1) * part.dy)
    h2 = (0.5 * (T2 - 1) * part.dx, 0.5 * (T2 - 1) * part.dy)
    which = (np.arange(ny, dtype=np.int64) if rows is None
             else np.unique(np.asarray(rows, np.int64)))
    if len(which) and (which[0] < 0 or which[-1] >= ny):
        raise ValueError(f"rows must lie in 0..{ny - 1}")
    out = np.empty((ny, nx)) if rows is None else np.full((ny, nx), np.nan)
    n_threads = THREADS if threads is None else max(1, int(threads))
    cut = np.linspace(0, len(which), max(1, min(n_threads, len(which))) + 1).astype(np.int64)

    def band(j: int) -> None:
        _rows(zp, s, w1, w2, tile_g, tile_err, tile_max, sub_g, sub_err, sub_max,
              h1, h2, which, int(cut[j]), int(cut[j + 1]), nx, out)

    with ThreadPoolExecutor(len(cut) - 1) as pool:
        list(pool.map(band, range(len(cut) - 1)))
    # sums rounded once in float64: raise by a bound of that rounding
    scale = float(np.abs(z).max()) + float(np.abs(s0[np.isfinite(s0)]).max(initial=0.0)) + 1.0
    return out + 8.0 * float(np.finfo(np.float64).eps) * scale
