"""Numba kernels of :mod:`zwcore.toolpath.sweep`: the closed-form envelope of a ball or flat
end mill over a node during one straight move, the test that skips a block of nodes a move
provably leaves alone, and the sweep of moves in order over a band of rows
(:func:`sweep_kernel`; the plain sweep it is tested against is
:mod:`zwcore.toolpath._sweep_plain`).

The reasoning (exactness, the convexity bound) is in :mod:`zwcore.toolpath.sweep`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, uint64
from numpy.typing import NDArray

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

#: A node is within a move's reach when its squared distance from the move is at most
#: ``R² TIE_REACH``: a node exactly R away (a tie, common where positions and nodes share a
#: spacing) is cut to the tool's equator, as the plan's simulated stock
#: (:data:`zwcore.scanline._stock_kernels.RIM`) and :func:`zwcore.sim.envelope` count it;
#: a retract from the same position meets it at that height, which is no material.
TIE_REACH = 1.0 + 1e-12

#: A block is skipped only when its bound is below minus this (mm): float rounding of the
#: bound is orders of magnitude smaller.
MARGIN = 1e-9
#: Nodes this far (mm) ahead of a move's trailing line are still swept (the line's own
#: rounding is orders of magnitude smaller).
TRAIL_MARGIN = 1e-9
#: The tangent plane is not used where the ball meets the block centre this close to its
#: rim (``sqrt(R² - d²) < RIM * R``: a steep, badly conditioned gradient).
RIM = 1e-3
#: Nodes a row run's envelope is computed in multiples of (the widest vector of doubles,
#: AVX-512; a multiple of narrower ones).
VECTOR = 8
#: Times the square of a move's coordinates' scale (``|s_x| + |s_y| + |a_x| + |a_y| + 2R``),
#: added under the rim bound's root: a node's computed ``d²`` rounds by some ``1e-15`` of
#: that, and the bound gives up its root at most (0.1 µm at a 100 mm scale).
RIM_SLACK = 1e-12


@njit(cache=True, nogil=True, fastmath={"contract", "arcp", "reassoc"})
def node_envelope(qx: float, qy: float, x0: float, y0: float, z0: float, ax: float,
                  ay: float, vz: float, r: float, ball: bool) -> float:
    """Lowest tool height over node ``(qx, qy)`` during one move; ``inf`` if not reached."""
    wx, wy = x0 - qx, y0 - qy
    a = ax * ax + ay * ay
    c = wx * wx + wy * wy
    # a node exactly R away (a tie) counts as reached, at the tool's equator (:data:`TIE_REACH`)
    reach2 = r * r * TIE_REACH
    if a <= 1e-18:  # vertical (or no) move
        if c >= reach2:
            return math.inf
        low = z0 + min(vz, 0.0)
        return low + r - math.sqrt(r * r - c) if ball else low
    b = ax * wx + ay * wy
    t0 = -b / a
    dmin2 = max(c - b * b / a, 0.0)
    w2 = reach2 - dmin2
    if w2 <= 0.0:
        return math.inf
    half = math.sqrt(w2 / a)
    lo, hi = max(0.0, t0 - half), min(1.0, t0 + half)
    if lo > hi:
        return math.inf
    if ball:
        ts = t0 - vz * math.sqrt(w2) / math.sqrt(a * (a + vz * vz))
        ts = min(max(ts, lo), hi)
        d2 = a * (ts - t0) ** 2 + dmin2
        return z0 + vz * ts + r - math.sqrt(max(r * r - d2, 0.0))
    return z0 + vz * (lo if vz >= 0.0 else hi)


@njit(cache=True, nogil=True, inline="always")
def measure_block(x0: float, y0: float, dx: float, dy: float, b: int, stock: F64, ref: F64,
                  cx: F64, cy: F64, st: F64, bi: int, bk: int) -> None:
    """``st[bi, bk] = (P_x, P_y, e, m)`` of block ``(bi, bk)`` over ``U = max(stock, ref)``:
    the plane slope from the block's corner nodes (any plane is valid; one along ``U`` is
    tight, and it follows the stock as moves cut it)."""
    ny, nx = stock.shape
    i0, i1 = bi * b, min(bi * b + b, ny) - 1
    k0, k1 = bk * b, min(bk * b + b, nx) - 1
    pxb = pyb = 0.0
    if k1 > k0:
        pxb = 0.5 * ((max(stock[i0, k1], ref[i0, k1]) - max(stock[i0, k0], ref[i0, k0]))
                     + (max(stock[i1, k1], ref[i1, k1]) - max(stock[i1, k0], ref[i1, k0]))
                     ) / ((k1 - k0) * dx)
    if i1 > i0:
        pyb = 0.5 * ((max(stock[i1, k0], ref[i1, k0]) - max(stock[i0, k0], ref[i0, k0]))
                     + (max(stock[i1, k1], ref[i1, k1]) - max(stock[i0, k1], ref[i0, k1]))
                     ) / ((i1 - i0) * dy)
    if not (math.isfinite(pxb) and math.isfinite(pyb)):
        pxb = pyb = 0.0
    best_e, best_m = -math.inf, -math.inf
    for i in range(i0, i1 + 1):
        ly = pyb * (y0 + i * dy - cy[bi])
        for k in range(k0, k1 + 1):
            u = max(stock[i, k], ref[i, k])
            best_m = max(best_m, u)
            best_e = max(best_e, u - ly - pxb * (x0 + k * dx - cx[bk]))
    st[bi, bk, 0], st[bi, bk, 1], st[bi, bk, 2], st[bi, bk, 3] = pxb, pyb, best_e, best_m


@njit(cache=True, nogil=True)
def coarse_block(f: int, cx: F64, cy: F64, hx: F64, hy: F64, st: F64, ccx: F64, ccy: F64,
                 cst: F64, ci: int, ck: int) -> None:
    """``cst[ci, ck]`` of the coarse block over ``f x f`` fine blocks from theirs: the mean
    slope ``P`` and, for a node ``q`` of fine block ``j`` (centre ``c_j``, half extents
    ``h_j``), ``U(q) - P.(q - c) <= e_j + |P_j - P|.h_j - P.(c_j - c)`` (``m``: the max)."""
    nby, nbx = st.shape[0], st.shape[1]
    sx = sy = 0.0
    n = 0
    for bi in range(ci * f, min(ci * f + f, nby)):
        for bk in range(ck * f, min(ck * f + f, nbx)):
            sx += st[bi, bk, 0]
            sy += st[bi, bk, 1]
            n += 1
    sx /= n
    sy /= n
    best_e = best_m = -math.inf
    for bi in range(ci * f, min(ci * f + f, nby)):
        for bk in range(ck * f, min(ck * f + f, nbx)):
            best_e = max(best_e, st[bi, bk, 2] + abs(st[bi, bk, 0] - sx) * hx[bk]
                         + abs(st[bi, bk, 1] - sy) * hy[bi]
                         - sx * (cx[bk] - ccx[ck]) - sy * (cy[bi] - ccy[ci]))
            best_m = max(best_m, st[bi, bk, 3])
    cst[ci, ck, 0], cst[ci, ck, 1], cst[ci, ck, 2], cst[ci, ck, 3] = sx, sy, best_e, best_m


@njit(cache=True, nogil=True)
def measure_all(x0: float, y0: float, dx: float, dy: float, b: int, f: int, stock: F64,
                ref: F64, cx: F64, cy: F64, hx: F64, hy: F64, st: F64, ccx: F64, ccy: F64,
                cst: F64) -> None:
    """:func:`measure_block` of every block, then :func:`coarse_block` of every coarse one."""
    for bi in range(st.shape[0]):
        for bk in range(st.shape[1]):
            measure_block(x0, y0, dx, dy, b, stock, ref, cx, cy, st, bi, bk)
    for ci in range(cst.shape[0]):
        for ck in range(cst.shape[1]):
            coarse_block(f, cx, cy, hx, hy, st, ccx, ccy, cst, ci, ck)


@njit(cache=True, nogil=True, fastmath={"contract", "arcp", "reassoc"})
def move_constants(sx: float, sy: float, sz: float, ax: float, ay: float, vz: float,
                   r: float) -> tuple[float, float, float, float, float, float, float]:
    """A move's constants, once per move: ``a = |v_xy|²``, ``inv_a = 1 / a``, ``inv_sa =
    sqrt(inv_a)``, ``kz = 1 / sqrt(a (a + v_z²))``, ``aa = 1 / inv_a`` (what the node
    formulas take for ``a``: the plain kernel's rounding; ``inv_a``, ``inv_sa``, ``kz``
    and ``aa`` are 0 for a vertical move, ``a <= 1e-18``), the lowest tip height and the
    rim bound's slack (:func:`skip_block`): ``RIM_SLACK`` times the square of the move's
    coordinates' scale, which bounds the rounding of a node's computed ``d²``."""
    a = ax * ax + ay * ay
    zlow = min(sz, sz + vz)
    slack = RIM_SLACK * (abs(sx) + abs(sy) + abs(ax) + abs(ay) + 2.0 * r) ** 2
    if a <= 1e-18:
        return a, 0.0, 0.0, 0.0, 0.0, zlow, slack
    inv_a = 1.0 / a
    return (a, inv_a, math.sqrt(inv_a), 1.0 / math.sqrt(a * (a + vz * vz)), 1.0 / inv_a, zlow,
            slack)


@njit(cache=True, nogil=True, fastmath={"contract", "arcp", "reassoc"}, inline="always")
def skip_block(bx: float, by: float, hx: float, hy: float, pxb: float, pyb: float,
               e: float, m: float, sx: float, sy: float, sz: float, ax: float, ay: float,
               vz: float, r: float, ball: bool, a: float, inv_a: float, kz: float,
               zlow: float, slack: float, hd: float) -> bool:
    """True when no node of the block (centre ``bx, by``, half extents ``hx, hy``, plane
    slope ``pxb, pyb``, ``e`` and ``m`` of ``U = max(stock, ref)``) can have
    ``U - env > -MARGIN`` for the move from ``(sx, sy, sz)`` by ``(ax, ay, vz)``
    (``a``, ``inv_a``, ``kz``, ``zlow``, ``slack``: :func:`move_constants`; ``hd``: at
    least the block's half diagonal, the same for all blocks of a level: no root per
    block).

    In order: the block's top under the lowest tip height (any tool); the block beyond
    ``R`` from the move's xy segment (no node reached: a node is reached only closer than
    ``R``); for a ball, the rim bound (a node at least ``d`` from the segment sees the
    ball no lower than ``zlow + R - sqrt(R² - d²)``, with ``d`` the block's distance); and,
    a move that is not vertical, the tangent plane at the block's centre (module docstring
    of :mod:`~zwcore.toolpath.sweep`)."""
    if m < zlow - MARGIN:  # the tip never comes down to the block's top
        return True
    # the block's distance from the segment, at least: its centre's, less its half diagonal
    dc2 = segment_distance2(bx, by, sx, sy, ax, ay, a, inv_a)
    if dc2 > ((r + hd) * (1.0 + 1e-12)) ** 2:  # the footprint misses the block: no node
        return True
    if not ball:
        return False
    if m < zlow + r - MARGIN and dc2 > hd * hd:  # (else the rim bound cannot skip it)
        # the rim bound; the slack under the root covers the rounding of a node's d² (its
        # computed root may come out larger than the true one where the root is small)
        dblk = min(math.sqrt(dc2) - hd, r)
        if m < zlow + r - math.sqrt(max(r * r - dblk * dblk, 0.0) + slack) - MARGIN:
            return True
    if a <= 1e-18:
        return False
    return plane_bound(bx, by, hx, hy, pxb, pyb, e, sx, sy, sz, ax, ay, vz, r, a, inv_a,
                       kz) < -MARGIN


@njit(cache=True, nogil=True, fastmath={"contract", "arcp", "reassoc"}, inline="always")
def segment_distance2(bx: float, by: float, sx: float, sy: float, ax: float, ay: float,
                      a: float, inv_a: float) -> float:
    """Squared xy distance from ``(bx, by)`` to a move's segment from ``(sx, sy)`` by
    ``(ax, ay)`` (``a``, ``inv_a``: :func:`move_constants`)."""
    wx, wy = bx - sx, by - sy
    tc = 0.0
    if a > 1e-18:
        tc = min(max((wx * ax + wy * ay) * inv_a, 0.0), 1.0)
    ex, ey = wx - ax * tc, wy - ay * tc
    return ex * ex + ey * ey


@njit(cache=True, nogil=True, fastmath={"contract", "arcp", "reassoc"}, inline="always")
def plane_bound(bx: float, by: float, hx: float, hy: float, pxb: float, pyb: float,
                e: float, sx: float, sy: float, sz: float, ax: float, ay: float, vz: float,
                r: float, a: float, inv_a: float, kz: float) -> float:
    """The tangent-plane bound of ``U - env`` over a block for a ball's move that is not
    vertical (``a > 1e-18``): ``e - env(c) + |P_x - g_x| h_x + |P_y - g_y| h_y``, with
    ``env(c)`` and ``g`` the envelope and its gradient at the block's centre (module
    docstring of :mod:`~zwcore.toolpath.sweep`); ``inf`` where the ball does not meet the
    centre or meets it near its rim (the plane is not used)."""
    wx, wy = sx - bx, sy - by  # the move's start from the centre
    c = wx * wx + wy * wy
    bb = ax * wx + ay * wy
    t0 = -bb * inv_a
    dmin2 = max(c - bb * bb * inv_a, 0.0)
    w2 = r * r * TIE_REACH - dmin2
    if w2 <= 0.0:
        return math.inf
    half = math.sqrt(w2 * inv_a)
    lo, hi = max(0.0, t0 - half), min(1.0, t0 + half)
    if lo > hi:
        return math.inf
    ts = t0 - vz * math.sqrt(w2) * kz
    ts = min(max(ts, lo), hi)
    d2 = a * (ts - t0) ** 2 + dmin2
    root = math.sqrt(max(r * r - d2, 0.0))
    if root < RIM * r:
        return math.inf
    env = sz + vz * ts + r - root
    gx = (bx - (sx + ax * ts)) / root
    gy = (by - (sy + ay * ts)) / root
    return e - env + abs(pxb - gx) * hx + abs(pyb - gy) * hy


@njit(cache=True, nogil=True, fastmath={"contract", "arcp", "reassoc"})
def _move_box(x0: float, y0: float, dx: float, dy: float, nx: int, row_lo: int, row_hi: int,
              sx: float, sy: float, ax: float, ay: float, rr: float
              ) -> tuple[int, int, int, int]:
    """``k0, k1, i0, i1``: the columns and the rows (within ``row_lo..row_hi - 1``) of the
    nodes within ``rr`` of the move's xy box (empty when ``k1 < k0`` or ``i1 < i0``)."""
    k0 = max(0, math.ceil((min(sx, sx + ax) - rr - x0) / dx))
    k1 = min(nx - 1, math.floor((max(sx, sx + ax) + rr - x0) / dx))
    i0 = max(row_lo, math.ceil((min(sy, sy + ay) - rr - y0) / dy))
    i1 = min(row_hi - 1, math.floor((max(sy, sy + ay) + rr - y0) / dy))
    return k0, k1, i0, i1


@njit(cache=True, nogil=True, fastmath={"contract", "arcp", "reassoc"})
def _row_span(qy: float, x0: float, dx: float, ka0: int, kb1: int, sx: float, sy: float,
              ax: float, ay: float, ylo: float, yhi: float, rr: float) -> tuple[int, int]:
    """``ka, kb``: the columns (within ``ka0..kb1``) of the nodes of the row at ``qy`` within
    ``rr`` of the move's xy shadow (none when ``kb < ka``)."""
    # the part of the move within R of the row in y, widened by the disc's half-chord there
    dyo = max(0.0, ylo - qy, qy - yhi)
    if dyo > rr:
        return 0, -1
    # (clamped: with fused multiply-adds a row exactly R away can come out just below 0)
    w = math.sqrt(max(rr * rr - dyo * dyo, 0.0))
    ta, tb = 0.0, 1.0
    if abs(ay) > 1e-12:
        ta, tb = (qy - rr - sy) / ay, (qy + rr - sy) / ay
        ta, tb = max(0.0, min(ta, tb)), min(1.0, max(ta, tb))
    xa, xb = sx + ax * ta, sx + ax * tb
    ka = max(ka0, math.ceil((min(xa, xb) - w - x0) / dx))
    kb = min(kb1, math.floor((max(xa, xb) + w - x0) / dx))
    return ka, kb


@njit(cache=True, nogil=True, fastmath={"contract", "arcp", "reassoc"})
def _trail_span(qy: float, x0: float, dx: float, ka: int, kb: int, sx: float, sy: float,
                ux: float, uy: float, lim: float) -> tuple[int, int]:
    """``ka..kb`` cut to the nodes of the row at ``qy`` with ``(q - s).u > lim`` (one column
    kept on the far side of the line: rounding never drops a node ahead of it)."""
    rest = lim - (qy - sy) * uy  # (qx - sx) ux > rest
    if abs(ux) <= 1e-12:
        return (ka, kb) if rest < 0.0 else (0, -1)
    if ux > 0.0:
        return max(ka, math.floor((sx + rest / ux - x0) / dx)), kb
    return ka, min(kb, math.ceil((sx + rest / ux - x0) / dx))


@njit(cache=True, nogil=True, fastmath={"contract", "arcp", "reassoc"})
def _behind(bx: float, by: float, hx: float, hy: float, sx: float, sy: float, ux: float,
            uy: float, lim: float) -> bool:
    """True when every point of the block (centre ``bx, by``, half extents ``hx, hy``) lies
    on or behind the trailing line: ``(q - s).u <= lim``."""
    return (bx - sx) * ux + (by - sy) * uy + abs(ux) * hx + abs(uy) * hy <= lim


@njit(cache=True, nogil=True, fastmath={"contract", "arcp", "reassoc"})
def _spans(x0: float, y0: float, dx: float, dy: float, i0: int, i1: int, base: int,
           k0: int, k1: int, sx: float, sy: float, ax: float, ay: float, rr: float, ux: float,
           uy: float, lim: float, rka: I64, rkb: I64, rsw: F64) -> None:
    """Per row ``i0..i1`` of a move's box (at ``i - base``, ``base`` its first row): the
    columns ``rka..rkb`` of the nodes within ``rr`` of the move's xy shadow and ahead of its
    trailing line (``(q - s).u > lim``; ``lim = -inf``: none), and ``rsw``
    (:func:`_row_node`); once per move, not per block, over the rows of the blocks it
    kept."""
    ylo, yhi = min(sy, sy + ay), max(sy, sy + ay)
    for i in range(i0, i1 + 1):
        qy = y0 + i * dy
        ka, kb = _row_span(qy, x0, dx, k0, k1, sx, sy, ax, ay, ylo, yhi, rr)
        if lim > -math.inf:
            ka, kb = _trail_span(qy, x0, dx, ka, kb, sx, sy, ux, uy, lim)
        wy = sy - qy
        rka[i - base], rkb[i - base] = ka, kb
        rsw[i - base] = math.sqrt(max(rr * rr * TIE_REACH - wy * wy, 0.0))


@njit(cache=True, nogil=True, fastmath={"contract", "arcp", "reassoc"}, inline="always")
def _node_height(t0: float, dmin2: float, sw: float, sz: float, vz: float, r: float,
                 ball: bool, inv_sa: float, kz: float, a: float) -> tuple[float, float, float]:
    """The tool's lowest height over a node at squared distance ``dmin2`` from the move's
    line (closest at ``t0``, half-width ``sw`` of its reach along it), and the reached
    stretch ``lo, hi`` of the move: the tail :func:`_row_node` and :func:`_flat_node`
    share."""
    half = sw * inv_sa
    lo, hi = max(0.0, t0 - half), min(1.0, t0 + half)
    if ball:
        ts = min(max(t0 - vz * sw * kz, lo), hi)
        d2 = a * (ts - t0) ** 2 + dmin2
        e = sz + vz * ts + r - math.sqrt(max(r * r - d2, 0.0))
    else:
        e = sz + vz * (lo if vz >= 0.0 else hi)
    return e, lo, hi


@njit(cache=True, nogil=True, fastmath={"contract", "arcp", "reassoc"}, inline="always")
def _row_node(wx: float, wy: float, sw: float, sz: float, ax: float, vz: float, r: float,
              ball: bool, inv_a: float, inv_sa: float, kz: float, a: float, reach2: float
              ) -> float:
    """The envelope over one node of a move along x (``ay = 0``): a node's distance from
    the move's line is ``|w_y|``, and ``sw = sqrt(R² TIE_REACH - w_y²)`` (clamped at 0)
    comes once per row, so one root per node is left. The operations of
    :func:`~zwcore.toolpath._sweep_plain.row_envelope`, in the same order."""
    t0 = -ax * wx * inv_a
    dmin2 = wy * wy
    e, lo, hi = _node_height(t0, dmin2, sw, sz, vz, r, ball, inv_sa, kz, a)
    return e if (dmin2 < reach2 and lo <= hi) else math.inf


@njit(cache=True, nogil=True, fastmath={"contract", "arcp", "reassoc"}, inline="always")
def _flat_node(wx: float, wy: float, sz: float, ax: float, ay: float, vz: float, r: float,
               ball: bool, inv_a: float, inv_sa: float, kz: float, a: float, reach2: float
               ) -> float:
    """The closed form of :func:`node_envelope` over one node of a move that is not vertical,
    without branches (``inf`` where not reached). The operations of
    :func:`~zwcore.toolpath._sweep_plain.flat_envelope`, in the same order."""
    c = wx * wx + wy * wy
    b = ax * wx + ay * wy
    t0 = -b * inv_a
    dmin2 = max(c + b * t0, 0.0)
    w2 = reach2 - dmin2
    sw = math.sqrt(max(w2, 0.0))
    e, lo, hi = _node_height(t0, dmin2, sw, sz, vz, r, ball, inv_sa, kz, a)
    return e if (w2 > 0.0 and lo <= hi) else math.inf


@njit(cache=True, nogil=True, inline="always")
def _any_reset(flags: NDArray[np.bool_], a: int, c: int) -> bool:
    """Whether any of ``flags[a:c]`` is set; clears them."""
    out = False
    for k in range(a, c):
        out |= flags[k]
        flags[k] = False
    return out


@njit(cache=True, nogil=True, fastmath={"contract", "arcp", "reassoc"})
def _row_run(n: int, ka: int, sx: float, x0: float, dx: float, wy: float, sw: float,
             sz: float, ax: float, ay: float, vz: float, r: float, ball: bool, env: F64,
             inv_a: float, inv_sa: float, kz: float, aa: float, reach2: float) -> None:
    """``env[j]`` over ``n`` contiguous nodes of a row (columns ``ka + j``, offsets
    ``sx - (x0 + (ka + j) dx), wy`` from the move's start: a node's offset does not depend
    on where its run starts) for a move that is not vertical: :func:`_row_node` along x
    (``sw`` its per-row root), else :func:`_flat_node`; one flat loop, so that it
    vectorises. ``inv_a, inv_sa, kz, aa`` (:func:`move_constants`) and ``reach2 = R² TIE_REACH``
    come once per move."""
    if ay == 0.0:
        for j in range(n):
            env[j] = _row_node(sx - (x0 + (ka + j) * dx), wy, sw, sz, ax, vz, r, ball, inv_a,
                               inv_sa, kz, aa, reach2)
    else:
        for j in range(n):
            env[j] = _flat_node(sx - (x0 + (ka + j) * dx), wy, sz, ax, ay, vz, r, ball, inv_a,
                                inv_sa, kz, aa, reach2)

@njit(cache=True, nogil=True, fastmath={"contract", "arcp", "reassoc"}, inline="always")
def run_envelope(n: int, ka: int, vertical: bool, sx: float, sy: float, x0: float, dx: float,
                 wy: float, sw: float, sz: float, ax: float, ay: float, vz: float, r: float,
                 ball: bool, env: F64, inv_a: float, inv_sa: float, kz: float, aa: float,
                 reach2: float) -> None:
    """``env[j]`` over the ``n`` nodes of a row's run from column ``ka`` (``wy``: the row's
    offset from the move's start, ``sw`` its per-row root): :func:`node_envelope` per node
    for a vertical move, else :func:`_row_run` over a whole number of vector widths (no
    node of the run goes through the loop's scalar remainder: runs are short, a third of
    their nodes did; the nodes past the run are computed and not used). Every kernel that
    reads runs calls this, so that a node gets the same value whichever reads it."""
    if vertical:
        for j in range(n):
            env[j] = node_envelope(sx - (sx - (x0 + (ka + j) * dx)), sy - wy, sx, sy, sz, ax,
                                   ay, vz, r, ball)
    else:
        _row_run((n + VECTOR - 1) // VECTOR * VECTOR, ka, sx, x0, dx, wy, sw, sz, ax, ay,
                 vz, r, ball, env, inv_a, inv_sa, kz, aa, reach2)



@njit(cache=True, nogil=True, fastmath={"contract", "arcp", "reassoc"})
def _runs(x0: float, y0: float, dx: float, dy: float, b: int, i0: int, i1: int, k0: int,
          k1: int, rka: I64, rkb: I64, rsw: F64, sx: float, sy: float, sz: float, ax: float,
          ay: float, vz: float, rr: float, ball: bool, cut: bool, sflat: F64, rflat: F64,
          nx: int, keep: NDArray[np.bool_], lowflat: NDArray[np.bool_], env: F64,
          inv_a: float, inv_sa: float, kz: float, aa: float, ds: F64, dr: F64
          ) -> tuple[float, float]:
    """One move over the nodes of the blocks marked in ``keep``, row by row: per row, each
    run of consecutive kept blocks is one contiguous stretch of nodes (within the row's
    span, :func:`_spans`), its envelope computed into ``env`` (no gathered copies), then
    the stock compared and, with ``cut``, lowered (``lowflat[bi * nx + k]`` set where it
    was). Returns the maxima of stock minus envelope and ``ref`` minus envelope (``inv_a``,
    ``inv_sa``, ``kz``, ``aa``: :func:`move_constants`).

    The differences go to ``ds`` and ``dr`` (room for every node of the move's box, and
    one more) and their maxima are taken once per move (:func:`_max_of`): a running
    maximum per node kept the compare loop scalar; without it, and indexed unsigned (no
    negative-index wrap-around), it vectorises."""
    pos = 0
    vertical = ax * ax + ay * ay <= 1e-18
    reach2 = rr * rr * TIE_REACH
    for bi in range(i0 // b, i1 // b + 1):
        bk = k0 // b
        while bk <= k1 // b:
            if not keep[bi, bk]:
                bk += 1
                continue
            bk_end = bk
            while bk_end + 1 <= k1 // b and keep[bi, bk_end + 1]:
                bk_end += 1
            for i in range(max(i0, bi * b), min(i1, bi * b + b - 1) + 1):
                ka, kb = max(bk * b, rka[i - i0]), min(bk_end * b + b - 1, rkb[i - i0])
                if kb < ka:  # never a range from a huge negative bound (it would wrap)
                    continue
                n = kb - ka + 1
                wy = sy - (y0 + i * dy)
                run_envelope(n, ka, vertical, sx, sy, x0, dx, wy, rsw[i - i0], sz, ax, ay,
                             vz, rr, ball, env, inv_a, inv_sa, kz, aa, reach2)
                row = i * nx + ka
                lrow = bi * nx + ka
                if cut:
                    for j in range(n):
                        q = uint64(row + j)
                        s, ev = sflat[q], env[j]
                        low = ev < s
                        lowflat[uint64(lrow + j)] |= low
                        sflat[q] = ev if low else s
                        ds[uint64(pos + j)] = s - ev
                        dr[uint64(pos + j)] = rflat[q] - ev
                else:
                    for j in range(n):
                        q = uint64(row + j)
                        ev = env[j]
                        ds[uint64(pos + j)] = sflat[q] - ev
                        dr[uint64(pos + j)] = rflat[q] - ev
                pos += n
            bk = bk_end + 1
    return _max_of(ds, pos), _max_of(dr, pos)


@njit(cache=True, nogil=True)
def _max_of(d: F64, n: int) -> float:
    """``max(d[:n])`` (``-inf`` when ``n = 0``; ``d`` has room for ``n + 1``), over the
    doubles' bits as integers: ``b ^ ((b >> 63) & 0x7FF...F)`` orders them as the doubles
    (negatives reversed), and an integer maximum vectorises where a float one did not (a
    ``-0.0`` and a ``0.0`` come out as ``0.0``; no NaN reaches it)."""
    bits = d.view(np.int64)
    mask = np.int64(0x7FFFFFFFFFFFFFFF)
    best = np.int64(-0x7FFFFFFFFFFFFFFF - 1)  # below every double's key
    for j in range(n):
        k = bits[j] ^ ((bits[j] >> 63) & mask)
        best = k if k > best else best
    if n == 0:
        return -math.inf
    bits[n] = best ^ ((best >> 63) & mask)  # the double back, through memory
    return d[n]


@njit(cache=True, nogil=True, fastmath={"contract", "arcp", "reassoc"})
def sweep_kernel(x0: float, y0: float, dx: float, dy: float, p0: F64, p1: F64, r: F64,
                 ball: bool, apply: NDArray[np.bool_], stock: F64, ref: F64,
                 over_stock: F64, over_ref: F64, row_lo: int, row_hi: int, b: int, f: int,
                 cx: F64, cy: F64, hx: F64, hy: F64, st: F64, ccx: F64, ccy: F64, chx: F64,
                 chy: F64, cst: F64, remeasure: bool, test: bool, trail: F64) -> None:
    """Moves in order over the rows ``row_lo..row_hi - 1`` (a band of whole coarse blocks:
    bands are independent).

    Per move: the coarse blocks (``f x f`` blocks) in its box that :func:`skip_block`
    cannot rule out, in them the blocks of ``b x b`` nodes it cannot rule out (marked in
    ``keep``); then, row by row, each run of kept blocks side by side is one contiguous
    stretch of nodes within R of the move's xy shadow (:func:`_runs`: the envelope over it
    in one flat loop, the stock compared and lowered where it is read, no gathered copies of
    the nodes, a quarter less time than gathering them); with ``remeasure`` the blocks
    the move lowered, and their coarse blocks, are measured again. Without ``test`` no
    block is tested (one block over the whole grid: the plain sweep). Where ``trail[s] >=
    0`` the nodes at or behind ``(q - p0).u = -trail[s] - TRAIL_MARGIN`` (``u`` the move's
    unit xy direction) are left out (:func:`~zwcore.toolpath.sweep.trailing_cuts`)."""
    nx = stock.shape[1]
    sflat = stock.reshape(-1)
    rflat = ref.reshape(-1)
    touched = np.empty((st.shape[0] * st.shape[1], 2), np.int64)
    keep = np.zeros((st.shape[0], st.shape[1]), np.bool_)
    lowcol = np.zeros((st.shape[0], nx), np.bool_)  # per block row, per column: lowered
    env = np.empty(nx + VECTOR)
    lowflat = lowcol.reshape(-1)
    ds, dr = np.empty(1024), np.empty(1024)  # per move, grown to its box (:func:`_runs`)
    lowered = np.zeros(st.shape[0] * st.shape[1], np.bool_)
    rka, rkb = np.empty(stock.shape[0], np.int64), np.empty(stock.shape[0], np.int64)
    rsw = np.empty(stock.shape[0])
    dirty = np.zeros((cst.shape[0], cst.shape[1]), np.bool_)
    big = b * f
    # the largest half diagonal of a block and of a coarse block (the last ones are cut)
    hdf = math.sqrt(np.max(hx) ** 2 + np.max(hy) ** 2)
    hdc = math.sqrt(np.max(chx) ** 2 + np.max(chy) ** 2)
    for s in range(p0.shape[0]):
        sx, sy, sz = p0[s, 0], p0[s, 1], p0[s, 2]
        ax, ay, vz = p1[s, 0] - sx, p1[s, 1] - sy, p1[s, 2] - sz
        rr = r[s]
        k0, k1, i0, i1 = _move_box(x0, y0, dx, dy, nx, row_lo, row_hi, sx, sy, ax, ay, rr)
        over_stock[s] = over_ref[s] = -math.inf
        if k1 < k0 or i1 < i0:
            continue
        a, inv_a, inv_sa, kz, aa, zlow, slack = move_constants(sx, sy, sz, ax, ay, vz, rr)
        lim, ux, uy = -math.inf, 0.0, 0.0
        if trail[s] >= 0.0:
            norm = math.sqrt(ax * ax + ay * ay)
            ux, uy, lim = ax / norm, ay / norm, -trail[s] - TRAIL_MARGIN
        nt = 0
        bmin, bmax = st.shape[0], -1  # the block rows of the blocks kept
        cut = apply[s]
        best_s, best_r = -math.inf, -math.inf
        for ci in range(i0 // big, i1 // big + 1):
            for ck in range(k0 // big, k1 // big + 1):
                if lim > -math.inf and _behind(ccx[ck], ccy[ci], chx[ck], chy[ci], sx, sy,
                                               ux, uy, lim):
                    continue
                if test and skip_block(ccx[ck], ccy[ci], chx[ck], chy[ci], cst[ci, ck, 0],
                                       cst[ci, ck, 1], cst[ci, ck, 2], cst[ci, ck, 3], sx, sy,
                                       sz, ax, ay, vz, rr, ball, a, inv_a, kz, zlow, slack,
                                       hdc):
                    continue
                for bi in range(max(i0 // b, ci * f), min(i1 // b, ci * f + f - 1) + 1):
                    for bk in range(max(k0 // b, ck * f), min(k1 // b, ck * f + f - 1) + 1):
                        if lim > -math.inf and _behind(cx[bk], cy[bi], hx[bk], hy[bi], sx,
                                                       sy, ux, uy, lim):
                            continue
                        if test and skip_block(cx[bk], cy[bi], hx[bk], hy[bi],
                                               st[bi, bk, 0], st[bi, bk, 1], st[bi, bk, 2],
                                               st[bi, bk, 3], sx, sy, sz, ax, ay, vz, rr,
                                               ball, a, inv_a, kz, zlow, slack, hdf):
                            continue
                        touched[nt, 0], touched[nt, 1] = bi, bk
                        keep[bi, bk] = True
                        nt += 1
                        bmin, bmax = min(bmin, bi), max(bmax, bi)
        if nt == 0:  # no node to sweep
            continue
        _spans(x0, y0, dx, dy, max(i0, bmin * b), min(i1, bmax * b + b - 1), i0, k0, k1, sx,
               sy, ax, ay, rr, ux, uy, lim, rka, rkb, rsw)
        if (k1 - k0 + 2) * (i1 - i0 + 1) > len(ds):  # room for every node of the box, + 1
            ds = np.empty(2 * (k1 - k0 + 2) * (i1 - i0 + 1))
            dr = np.empty(len(ds))
        best_s, best_r = _runs(x0, y0, dx, dy, b, i0, i1, k0, k1, rka, rkb, rsw, sx, sy, sz,
                               ax, ay, vz, rr, ball, cut, sflat, rflat, nx, keep, lowflat,
                               env, inv_a, inv_sa, kz, aa, ds, dr)
        for t in range(nt):
            bi, bk = touched[t, 0], touched[t, 1]
            keep[bi, bk] = False
            if cut:
                lowered[t] = _any_reset(lowflat, bi * nx + bk * b, bi * nx + min(bk * b + b, nx))
        if cut:
            for t in range(nt):  # only the blocks the move lowered
                if lowered[t]:
                    lowered[t] = False
                    if remeasure:
                        measure_block(x0, y0, dx, dy, b, stock, ref, cx, cy, st,
                                      touched[t, 0], touched[t, 1])
                        dirty[touched[t, 0] // f, touched[t, 1] // f] = True
            if remeasure:
                for t in range(nt):
                    ci, ck = touched[t, 0] // f, touched[t, 1] // f
                    if dirty[ci, ck]:
                        dirty[ci, ck] = False
                        coarse_block(f, cx, cy, hx, hy, st, ccx, ccy, cst, ci, ck)
        over_stock[s] = best_s
        over_ref[s] = best_r
