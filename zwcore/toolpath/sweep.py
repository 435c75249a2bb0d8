"""Exact lower envelope of a ball or flat end mill swept along straight moves, on grid nodes.

A ball end mill of radius ``R`` whose tip moves linearly from ``p0`` to ``p1`` sweeps a
capsule (the ball's centre runs ``R`` above the tip; the shank above the ball adds nothing
below the capsule's lower surface). Over a grid node ``q`` the lowest point it reaches is

    min over t in [0, 1] with d(t) <= R of  tip_z(t) + R - sqrt(R^2 - d(t)^2)

with ``d(t)`` the xy distance from ``q`` to the tip. ``d(t)^2`` is a convex quadratic in
``t``, so the objective is convex on the interval where ``d <= R`` and its minimiser is the
clamp of the stationary point (closed form below): the envelope is exact on the nodes, not
sampled. A flat end mill's envelope is the tip height at the end of that interval the move
descends towards. Arcs are swept as chords with the radius grown by the chord's sagitta
(a superset of the true swept volume: conservative for removal).

The kernel is compiled with numba (a loop over each move's box of nodes: no temporaries,
about 5 ns per node visited); moves are processed in order, so a simulation sees the stock
as every earlier move left it.
"""

from __future__ import annotations

import itertools
import math
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = ["GridFrame", "arc_chords", "sweep_moves"]

#: Threads of a sweep (the kernel releases the GIL): bands of rows for moves that cut,
#: chunks of moves for measurements only.
SWEEP_THREADS = max(1, min(4, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity")
                           else (os.cpu_count() or 1)))
#: Fewer moves than this per thread run on one thread (a thread's start is not free).
MIN_MOVES_PER_THREAD = 2_000

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]


@dataclass(frozen=True)
class GridFrame:
    """Where grid nodes sit: node ``(i, k)`` at ``(x0 + k*dx, y0 + i*dy)``; ``shape = (ny, nx)``."""

    x0: float
    y0: float
    dx: float
    dy: float
    shape: tuple[int, int]


@njit(cache=True, nogil=True, fastmath={"contract", "arcp", "reassoc"})
def _node_envelope(qx: float, qy: float, x0: float, y0: float, z0: float, ax: float,
                   ay: float, vz: float, r: float, ball: bool) -> float:
    """Lowest tool height over node ``(qx, qy)`` during one move; ``inf`` if not reached."""
    wx, wy = x0 - qx, y0 - qy
    a = ax * ax + ay * ay
    c = wx * wx + wy * wy
    # a node exactly R away only touches the tool's side (a tie): it counts as not reached,
    # the same way for every move, so a retract never "meets" a node its cut left alone
    reach2 = r * r * (1.0 - 1e-10)
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


@njit(cache=True, nogil=True, fastmath={"contract", "arcp", "reassoc", "nsz"})
def _flat_envelope(m: int, wxs: F64, wys: F64, sz: float, ax: float, ay: float, vz: float,
                   r: float, ball: bool, inv_a: float, inv_sa: float, kz: float, env: F64
                   ) -> None:
    """``env[j]`` over the ``m`` gathered nodes (offsets ``wxs, wys`` from the move's start)
    of one (not vertical) move: the closed form of :func:`_node_envelope` without branches
    (unreached nodes get ``inf``), one flat loop so that it vectorises."""
    a = 1.0 / inv_a
    reach2 = r * r * (1.0 - 1e-10)
    for j in range(m):
        wx, wy = wxs[j], wys[j]
        c = wx * wx + wy * wy
        b = ax * wx + ay * wy
        t0 = -b * inv_a
        dmin2 = max(c + b * t0, 0.0)
        w2 = reach2 - dmin2
        sw = math.sqrt(max(w2, 0.0))
        half = sw * inv_sa
        lo, hi = max(0.0, t0 - half), min(1.0, t0 + half)
        if ball:
            ts = min(max(t0 - vz * sw * kz, lo), hi)
            d2 = a * (ts - t0) ** 2 + dmin2
            e = sz + vz * ts + r - math.sqrt(max(r * r - d2, 0.0))
        else:
            e = sz + vz * (lo if vz >= 0.0 else hi)
        env[j] = e if (w2 > 0.0 and lo <= hi) else math.inf


@njit(cache=True, nogil=True, fastmath={"contract", "arcp", "reassoc"})
def _sweep_kernel(x0: float, y0: float, dx: float, dy: float, p0: F64, p1: F64, r: F64,
                  ball: bool, apply: NDArray[np.bool_], stock: F64, ref: F64,
                  over_stock: F64, over_ref: F64, row_lo: int, row_hi: int) -> None:
    """Moves in order over the rows ``row_lo..row_hi - 1`` (a band: bands are independent).

    Per move: gather the nodes within R of its xy shadow (row by row), evaluate the
    envelope over all of them in one flat loop, then compare with and lower the stock."""
    nx = stock.shape[1]
    sflat = stock.reshape(-1)
    rflat = ref.reshape(-1)
    cap = 1024
    wxs, wys, env = np.empty(cap), np.empty(cap), np.empty(cap)
    idx = np.empty(cap, np.int64)
    for s in range(p0.shape[0]):
        sx, sy, sz = p0[s, 0], p0[s, 1], p0[s, 2]
        ax, ay, vz = p1[s, 0] - sx, p1[s, 1] - sy, p1[s, 2] - sz
        rr = r[s]
        k0 = max(0, math.ceil((min(sx, sx + ax) - rr - x0) / dx))
        k1 = min(nx - 1, math.floor((max(sx, sx + ax) + rr - x0) / dx))
        i0 = max(row_lo, math.ceil((min(sy, sy + ay) - rr - y0) / dy))
        i1 = min(row_hi - 1, math.floor((max(sy, sy + ay) + rr - y0) / dy))
        over_stock[s] = over_ref[s] = -math.inf
        if k1 < k0 or i1 < i0:
            continue
        box = (k1 - k0 + 1) * (i1 - i0 + 1)
        if box > cap:
            cap = 2 * box
            wxs, wys, env = np.empty(cap), np.empty(cap), np.empty(cap)
            idx = np.empty(cap, np.int64)
        ylo, yhi = min(sy, sy + ay), max(sy, sy + ay)
        a = ax * ax + ay * ay
        vertical = a <= 1e-18
        m = 0
        for i in range(i0, i1 + 1):
            qy = y0 + i * dy
            # the nodes of this row within R of the move's xy shadow: the part of the move
            # within R of the row in y, widened by the disc's half-chord at the row
            dyo = max(0.0, ylo - qy, qy - yhi)
            if dyo > rr:
                continue
            # (clamped: with fused multiply-adds a row exactly R away can come out just below 0)
            w = math.sqrt(max(rr * rr - dyo * dyo, 0.0))
            ta, tb = 0.0, 1.0
            if abs(ay) > 1e-12:
                ta, tb = (qy - rr - sy) / ay, (qy + rr - sy) / ay
                ta, tb = max(0.0, min(ta, tb)), min(1.0, max(ta, tb))
            xa, xb = sx + ax * ta, sx + ax * tb
            ka = max(k0, math.ceil((min(xa, xb) - w - x0) / dx))
            kb = min(k1, math.floor((max(xa, xb) + w - x0) / dx))
            if kb < ka:  # never a range from a huge negative bound (it would wrap around)
                continue
            for k in range(ka, kb + 1):
                wxs[m] = sx - (x0 + k * dx)
                wys[m] = sy - qy
                idx[m] = i * nx + k
                m += 1
        if vertical:
            for j in range(m):
                env[j] = _node_envelope(sx - wxs[j], sy - wys[j], sx, sy, sz, ax, ay, vz, rr,
                                        ball)
        else:
            inv_a = 1.0 / a
            _flat_envelope(m, wxs, wys, sz, ax, ay, vz, rr, ball, inv_a, math.sqrt(inv_a),
                           1.0 / math.sqrt(a * (a + vz * vz)), env)
        best_s, best_r = -math.inf, -math.inf
        if apply[s]:
            for j in range(m):
                q, e = idx[j], env[j]
                best_s = max(best_s, sflat[q] - e)
                best_r = max(best_r, rflat[q] - e)
                sflat[q] = min(sflat[q], e)
        else:
            for j in range(m):
                q, e = idx[j], env[j]
                best_s = max(best_s, sflat[q] - e)
                best_r = max(best_r, rflat[q] - e)
        over_stock[s] = best_s
        over_ref[s] = best_r


def sweep_moves(frame: GridFrame, p0: F64, p1: F64, radius: F64 | float, ball: bool,
                stock: F64, ref: F64 | None = None, apply: NDArray[np.bool_] | bool = True
                ) -> tuple[F64, F64]:
    """Sweep a tool along straight moves, in order, over a stock grid.

    Parameters
    ----------
    frame : GridFrame
    p0, p1 : (n, 3) float64
        Tip positions at the start and the end of each move, mm.
    radius : float or (n,) float64
        Tool radius per move (arcs swept as chords pass their grown radius).
    ball : bool
        Ball end mill (else flat).
    stock : (ny, nx) float64
        Lowered in place by the moves with ``apply`` (to the swept envelope).
    ref : (ny, nx) float64, optional
        A reference surface (the part) to measure each move against.
    apply : bool or (n,) bool
        Which moves remove material (feeds); the others are only measured (rapids).

    Returns
    -------
    over_stock : (n,) float64
        Per move, the largest stock height above its envelope *before* the move
        (> 0: it met material); ``-inf`` where it reaches no node.
    over_ref : (n,) float64
        The same against ``ref`` (> 0: it cuts below the part).
    """
    p0 = np.ascontiguousarray(p0, dtype=np.float64).reshape(-1, 3)
    p1 = np.ascontiguousarray(p1, dtype=np.float64).reshape(-1, 3)
    n = len(p0)
    # fresh writable copies (a broadcast view of one element would be read-only: another
    # numba signature)
    r = np.array(np.broadcast_to(np.asarray(radius, np.float64), (n,)), dtype=np.float64)
    app = np.array(np.broadcast_to(np.asarray(apply, bool), (n,)), dtype=np.bool_)
    if stock.shape != frame.shape or not stock.flags.c_contiguous:
        raise ValueError("stock must be a C-contiguous grid of the frame's shape")
    refg = stock if ref is None else np.ascontiguousarray(ref, dtype=np.float64)
    over_s = np.full(n, -np.inf)
    over_r = np.full(n, -np.inf)
    if not n:
        return over_s, over_r
    ny = frame.shape[0]
    # one signature for every caller: numba's disk cache is shared by processes (xdist
    # workers, service workers), and two processes adding different signatures at once
    # can leave an index pointing at the other's machine code
    args = (float(frame.x0), float(frame.y0), float(frame.dx), float(frame.dy))
    ball = bool(ball)
    threads = min(SWEEP_THREADS, max(1, n // MIN_MOVES_PER_THREAD), ny)
    if threads == 1:
        _sweep_kernel(*args, p0, p1, r, ball, app, stock, refg, over_s, over_r, 0, ny)
        return over_s, over_r
    if not app.any():  # nothing changes: the moves split into independent chunks
        cut = np.linspace(0, n, threads + 1).astype(np.int64)
        jobs = [(p0[a:b], p1[a:b], r[a:b], app[a:b], over_s[a:b], over_r[a:b], 0, ny)
                for a, b in itertools.pairwise(cut)]
    else:  # every band of rows sees all the moves in order; per move, the max over bands
        cut = np.linspace(0, ny, threads + 1).astype(np.int64)
        outs = np.full((threads, 2, n), -np.inf)
        jobs = [(p0, p1, r, app, outs[t, 0], outs[t, 1], int(a), int(b))
                for t, (a, b) in enumerate(itertools.pairwise(cut))]
    with ThreadPoolExecutor(threads) as pool:  # the kernel releases the GIL
        list(pool.map(lambda j: _sweep_kernel(*args, j[0], j[1], j[2], ball, j[3], stock, refg,
                                              j[4], j[5], j[6], j[7]), jobs))
    if app.any():
        over_s, over_r = outs[:, 0].max(axis=0), outs[:, 1].max(axis=0)
    return over_s, over_r


def arc_chords(start: F64, end: F64, center: F64, ccw: NDArray[np.bool_], sagitta: float
               ) -> tuple[F64, F64, F64, I64]:
    """Arcs (helical when the ends differ in z) as chords whose sagitta is at most ``sagitta``.

    Parameters
    ----------
    start, end : (n, 3) float64
    center : (n, 2) float64
    ccw : (n,) bool
    sagitta : float
        Largest distance between an arc and its chord, mm (> 0).

    Returns
    -------
    c0, c1 : (m, 3) float64
        Chord ends (z linear in the angle, as the control moves it).
    grow : (m,) float64
        The sagitta each chord really has (add it to the tool radius to cover the arc).
    owner : (m,) int64
        The arc each chord belongs to.
    """
    rad = np.hypot(start[:, 0] - center[:, 0], start[:, 1] - center[:, 1])
    a0 = np.arctan2(start[:, 1] - center[:, 1], start[:, 0] - center[:, 0])
    a1 = np.arctan2(end[:, 1] - center[:, 1], end[:, 0] - center[:, 0])
    sweep = np.where(ccw, np.mod(a1 - a0, 2 * np.pi), -np.mod(a0 - a1, 2 * np.pi))
    full = np.abs(sweep) < 1e-12  # start == end: a full circle
    sweep = np.where(full, np.where(ccw, 2 * np.pi, -2 * np.pi), sweep)
    # chord of angle phi has sagitta r (1 - cos(phi/2))
    phi_max = 2.0 * np.arccos(np.clip(1.0 - sagitta / np.maximum(rad, 1e-12), -1.0, 1.0))
    count = np.maximum(1, np.ceil(np.abs(sweep) / np.maximum(phi_max, 1e-6))).astype(np.int64)
    owner = np.repeat(np.arange(len(start)), count)
    first = np.repeat(np.cumsum(count) - count, count)
    j = (np.arange(len(owner)) - first).astype(np.float64)
    n = count[owner].astype(np.float64)
    ang0 = a0[owner] + sweep[owner] * j / n
    ang1 = a0[owner] + sweep[owner] * (j + 1) / n
    ro = rad[owner]
    cx, cy = center[owner, 0], center[owner, 1]
    z0, z1 = start[owner, 2], end[owner, 2]
    c0 = np.column_stack([cx + ro * np.cos(ang0), cy + ro * np.sin(ang0), z0 + (z1 - z0) * j / n])
    c1 = np.column_stack([cx + ro * np.cos(ang1), cy + ro * np.sin(ang1),
                          z0 + (z1 - z0) * (j + 1) / n])
    phi = np.abs(sweep[owner]) / n
    # the arc point at a parameter is within the sagitta (radially) plus a third-order
    # tangential term of the chord point at the same parameter (same z): (1 + phi) covers both
    grow = ro * (1.0 - np.cos(phi / 2.0)) * (1.0 + phi)
    # the first and last chord ends are the arc's own end points (no drift from cos/sin)
    c0[first == np.arange(len(owner))] = start[owner[first == np.arange(len(owner))]]
    last = (j + 1) == n
    c1[last] = end[owner[last]]
    return c0, c1, grow * (1.0 + 1e-9) + 1e-12, owner


def chord_count_bound(radius: float, sweep: float, sagitta: float) -> int:
    """Chords :func:`arc_chords` uses for one arc (for limits)."""
    phi = 2.0 * math.acos(max(-1.0, 1.0 - sagitta / max(radius, 1e-12)))
    return max(1, math.ceil(abs(sweep) / max(phi, 1e-6)))
