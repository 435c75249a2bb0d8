"""Exact lower envelope of a ball or flat end mill swept along straight moves, on grid nodes.

A ball end mill of radius ``R`` whose tip moves linearly from ``p0`` to ``p1`` sweeps a
capsule (the ball's centre runs ``R`` above the tip; the shank above the ball adds nothing
below the capsule's lower surface). Over a grid node ``q`` the lowest point it reaches is

    min over t in [0, 1] with d(t) <= R of  tip_z(t) + R - sqrt(R^2 - d(t)^2)

with ``d(t)`` the xy distance from ``q`` to the tip. ``d(t)^2`` is a convex quadratic in
``t``, so the objective is convex on the interval where ``d <= R`` and its minimiser is the
clamp of the stationary point (closed form, :mod:`~zwcore.toolpath._sweep_kernel`): the
envelope is exact on the nodes, not sampled. A flat end mill's envelope is the tip height
at the end of that interval the move descends towards. Arcs are swept as chords with the
radius grown by the chord's sagitta (a superset of the true swept volume: conservative for
removal).

The kernels are compiled with numba; moves are processed in order, so a simulation sees the
stock as every earlier move left it. Without ``bounds`` (the plain kernel,
:mod:`~zwcore.toolpath._sweep_plain`) a move's nodes within R of its shadow are gathered,
then evaluated in one flat loop. With ``bounds`` the nodes of the blocks it cannot skip are
read in place, a contiguous stretch of a row at a time, the envelope and the stock compare
in vectorised loops (about 4 ns per node visited on the 1025² plan's Ø20 pass, block tests
and bound upkeep included; 7 ns before the compare loop vectorised).

**Blocks a move leaves alone** (``bounds``, :class:`BlockBounds`). A sweep only matters
where the tool comes below ``U = max(stock, ref)``: there it lowers the stock and its
figures are positive; every other node keeps its stock and gives a value ``<= 0``. Per
block of ``b x b`` nodes we keep a plane slope ``P`` (``U``'s, from the block's corners,
measured again as moves cut), ``e = max_q U(q) - P.(q - c)`` (``c`` the block's centre)
and ``m = max U``; a block is skipped when

- ``m`` lies under the move's lowest tip height (any tool), or its centre is further than
  ``R`` plus the block's half diagonal from the move's xy *segment* (no node reached: a
  node is reached only closer than ``R``, so blocks beyond the move's ends go too), or
- (a ball: the rim bound) ``m`` lies under ``z_low + R - sqrt(R² - d²)``, ``d`` the
  block's distance from the segment (at least its centre's less its half diagonal): every
  point of the ball over a node at least ``d`` from the segment is that high (the ball's
  sides, where the tangent plane below is not used), or
- (a ball, a move that is not vertical) ``e - env(c) + |P_x - g_x| h_x + |P_y - g_y| h_y``
  is below ``-MARGIN``, where ``env(c)`` and ``g`` are the envelope and its gradient
  ``(c - tip_xy(t*)) / sqrt(R² - d*²)`` at the centre (``t*`` the minimiser). This bounds
  ``U - env`` over the block because the envelope is **convex** on the move's footprint:
  ``f(q, t) = tip_z(t) + R - sqrt(R² - |q - tip_xy(t)|²)`` is jointly convex in ``(q, t)``
  (a convex increasing function of a convex quadratic, plus a linear term) on a convex
  domain, and a partial minimum of a jointly convex function is convex, so its tangent
  plane at ``c`` lies under it (the envelope theorem gives the gradient; where the ball
  meets ``c`` near its rim the plane is not used).

Skipped blocks would keep their stock and give negative figures, so the stock is the one
without ``bounds`` and ``over_stock`` / ``over_ref`` are the same wherever they are ``> 0``
(elsewhere ``<= 0`` or ``-inf``); a test compares both on random moves. After a move that
cut, the blocks it lowered get ``P``, ``e`` and ``m`` measured again (the stock only goes
down: a stale bound stays valid). With ``U``'s own slope as ``P``, near contact the
envelope's and the surface's slopes agree and the bound is tight to the envelope's
curvature over a block: a Ø20 ball's finishing chords visit a fraction of the nodes of its
disc. Blocks are grouped
``f x f`` into coarse blocks, tested first (their ``e`` bounded from their blocks':
``U(q) - P.(q - c) <= e_j + |P_j - P|.h_j - P.(c_j - c)`` for a node of block ``j``).
"""

from __future__ import annotations

import itertools
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from zwcore.toolpath._sweep_kernel import measure_all, sweep_kernel
from zwcore.toolpath._sweep_plain import plain_kernel

__all__ = ["BlockBounds", "GridFrame", "arc_chords", "block_size", "sweep_moves",
           "trailing_cuts"]

#: Threads of a sweep (the kernel releases the GIL): bands of rows for moves that cut,
#: chunks of moves for measurements only.
SWEEP_THREADS = max(1, min(4, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity")
                           else (os.cpu_count() or 1)))
#: Fewer moves than this per thread run on one thread (a thread's start is not free).
MIN_MOVES_PER_THREAD = 2_000
#: Bands of rows (moves that cut) or chunks of moves (measurements only) per thread, taken
#: by the threads as they come free: a
#: part's detail is rarely spread evenly over its rows (1025² Ø20 finishing: two halves
#: 3.5 and 2.2 s; eight bands of 0.2 to 2.0 s keep two threads within 2 % of even).
BANDS_PER_THREAD = 4

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


#: Tools narrower than this many nodes of radius sweep without block bounds, with the plain
#: kernel (their disc is a few blocks: on Mount Rushmore's Ø1 stages at 0.1 mm the tests
#: cost more than they save, 10.5 s of paths against 8.8 s).
MIN_BLOCK_RADIUS = 8.0


def block_size(radius: float, spacing: float) -> int:
    """Nodes a side of the skip blocks for a tool: about a twelfth of its radius, 4 to 16
    (small enough that the envelope's curvature over a block is small, large enough that a
    block's test is cheap against its nodes; a Ø20 ball at 0.1 mm: 8, the fastest of 5, 8
    and 13 measured)."""
    return int(min(16, max(4, round(radius / spacing / 12.0))))


class BlockBounds:
    """Per block of ``b x b`` nodes, and per coarse block of ``f x f`` blocks: centre, half
    extents and ``(P_x, P_y, e, m)`` of ``max(stock, ref)`` (module docstring);
    :func:`sweep_moves` keeps them up to date.

    Parameters
    ----------
    frame : GridFrame
    stock, ref : (ny, nx) float64
        The surfaces the sweeps compare with (``ref`` may be ``stock``).
    block : int
        Nodes a side of a block.
    coarse : int
        Blocks a side of a coarse block (tested first: a move's footprint spans some
        hundred blocks, most of them skipped a coarse block at a time).
    """

    def __init__(self, frame: GridFrame, stock: F64, ref: F64, block: int = 8,
                 coarse: int = 4):
        self.block, self.coarse = max(1, int(block)), max(1, int(coarse))
        b, f = self.block, self.coarse
        self.cx, self.cy, self.hx, self.hy = _centres(frame, b)
        self.ccx, self.ccy, self.chx, self.chy = _centres(frame, b * f)
        self.st = np.empty((len(self.cy), len(self.cx), 4))
        self.cst = np.empty((len(self.ccy), len(self.ccx), 4))
        measure_all(frame.x0, frame.y0, frame.dx, frame.dy, b, f, np.ascontiguousarray(stock),
                    np.ascontiguousarray(ref), self.cx, self.cy, self.hx, self.hy, self.st,
                    self.ccx, self.ccy, self.cst)
        self.remeasure, self.test = True, True

    @classmethod
    def none(cls, frame: GridFrame) -> BlockBounds:
        """One block over the whole grid, never tested: the block kernel without skipping
        (what the tests compare the skipping with, bit for bit: the same machine code)."""
        out = cls.__new__(cls)
        out.block, out.coarse = max(frame.shape), 1
        out.cx, out.cy = np.full(1, frame.x0), np.full(1, frame.y0)
        out.hx, out.hy = np.full(1, np.inf), np.full(1, np.inf)
        out.st = np.full((1, 1, 4), np.inf)
        out.ccx, out.ccy, out.chx, out.chy, out.cst = out.cx, out.cy, out.hx, out.hy, out.st
        out.remeasure, out.test = False, False
        return out


def _centres(frame: GridFrame, b: int) -> tuple[F64, F64, F64, F64]:
    """Centres ``x`` (per block column), ``y`` (per block row) and half extents of the
    blocks of ``b x b`` nodes (the last ones cut at the grid's edge), mm."""
    ny, nx = frame.shape
    i_first = np.arange(-(-ny // b)) * b
    i_last = np.minimum(i_first + b - 1, ny - 1)
    k_first = np.arange(-(-nx // b)) * b
    k_last = np.minimum(k_first + b - 1, nx - 1)
    cx = frame.x0 + 0.5 * (k_first + k_last).astype(np.float64) * frame.dx
    cy = frame.y0 + 0.5 * (i_first + i_last).astype(np.float64) * frame.dy
    return (cx, cy, 0.5 * (k_last - k_first).astype(np.float64) * frame.dx,
            0.5 * (i_last - i_first).astype(np.float64) * frame.dy)


def sweep_moves(frame: GridFrame, p0: F64, p1: F64, radius: F64 | float, ball: bool,
                stock: F64, ref: F64 | None = None, apply: NDArray[np.bool_] | bool = True,
                bounds: BlockBounds | None = None, trail: bool = False,
                before: tuple[F64, F64, float, bool] | None = None) -> tuple[F64, F64]:
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
    bounds : BlockBounds, optional
        Built on ``stock`` and ``ref`` as they are now (updated in place): blocks a move
        leaves alone are skipped (module docstring). Without it every node within reach
        is swept.
    trail : bool
        With ``bounds`` and a ball: leave out, of a move that continues the one before it
        (:func:`trailing_cuts`), the nodes its start's sphere alone reaches (the move
        before already cut them at least as low). The stock is the same to float rounding
        (the same sphere computed from either move); ``over_stock`` and ``over_ref`` are
        exact where ``> 0`` except that such a node's value is counted with the move
        before only.
    before : (p0, p1, radius, apply) of the move swept before these, optional
        For ``trail``: the first move may continue it (moves swept in pieces trail as they
        do swept at once).

    Returns
    -------
    over_stock : (n,) float64
        Per move, the largest stock height above its envelope *before* the move
        (> 0: it met material); ``-inf`` where it reaches no node. With ``bounds``, exact
        where ``> 0``, else a value ``<= 0`` or ``-inf``.
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
    tail: tuple[Any, ...] = ()
    kernel: Any = plain_kernel  # without bounds: no block bookkeeping (small tools' moves)
    unit = 1
    if bounds is not None:
        bb = bounds
        kernel, unit = sweep_kernel, bb.block * bb.coarse  # bands of whole coarse blocks
        cuts = np.full(n, -1.0)
        if trail and ball and before is None:
            cuts = trailing_cuts(p0, p1, r, app)
        elif trail and ball and before is not None:
            b0, b1, br, bapp = before
            cuts = trailing_cuts(np.vstack([b0, p0]), np.vstack([b1, p1]), np.r_[br, r],
                                 np.r_[bapp, app])[1:]
        tail = (int(bb.block), int(bb.coarse), bb.cx, bb.cy, bb.hx, bb.hy, bb.st, bb.ccx,
                bb.ccy, bb.chx, bb.chy, bb.cst, bool(bb.remeasure), bool(bb.test), cuts)
    rows = -(-ny // unit)
    threads = min(SWEEP_THREADS, max(1, n // MIN_MOVES_PER_THREAD), rows)
    if threads == 1:
        kernel(*args, p0, p1, r, ball, app, stock, refg, over_s, over_r, 0, ny, *tail)
        return over_s, over_r
    if not app.any():  # nothing changes: the moves split into independent chunks
        cut = np.linspace(0, n, min(n, threads * BANDS_PER_THREAD) + 1).astype(np.int64)
        jobs = [(p0[a:c], p1[a:c], r[a:c], app[a:c], over_s[a:c], over_r[a:c], 0, ny)
                for a, c in itertools.pairwise(cut)]
    else:  # every band of rows sees all the moves in order; per move, the max over bands
        bands = min(rows, threads * BANDS_PER_THREAD)
        cut = np.minimum(np.linspace(0, rows, bands + 1).astype(np.int64) * unit, ny)
        outs = np.full((bands, 2, n), -np.inf)
        jobs = [(p0, p1, r, app, outs[t, 0], outs[t, 1], int(a), int(c))
                for t, (a, c) in enumerate(itertools.pairwise(cut))]
    with ThreadPoolExecutor(threads) as pool:  # the kernel releases the GIL
        list(pool.map(lambda j: kernel(*args, j[0], j[1], j[2], ball, j[3], stock, refg,
                                       j[4], j[5], j[6], j[7], *tail), jobs))
    if app.any():
        over_s, over_r = outs[:, 0].max(axis=0), outs[:, 1].max(axis=0)
    return over_s, over_r


def trailing_cuts(p0: F64, p1: F64, radius: F64, apply: NDArray[np.bool_]) -> F64:
    """Per ball move, how far behind its start its trailing line lies (mm; -1: none).

    A move ``k`` that removes material and starts exactly where move ``k - 1`` ended, with
    the same radius, after that move removed material too, reaches a node ``q`` whose
    projection on its xy direction ``u`` is ``(q - p0).u <= -R |sin(slope)|`` only with
    its start's sphere: the clamped minimiser is ``t* <= t0 + |v_z| R / (|a| sqrt(|a|² +
    v_z²)) <= 0`` there (``t0`` the projection in move units; the radical under the
    reach is at most ``R``), or it does not reach ``q`` at all (its nearest point is the
    start). Move ``k - 1``'s envelope is at most its end's sphere, the same sphere, and the
    stock after it is at most its envelope: move ``k`` cannot lower such a node. On a
    finishing line the trailing half of each disc is that region.

    Parameters
    ----------
    p0, p1 : (n, 3) float64
    radius : (n,) float64
    apply : (n,) bool

    Returns
    -------
    (n,) float64
        ``R |v_z| / sqrt(|a|² + v_z²)`` where it applies, else -1.
    """
    out = np.full(len(p0), -1.0)
    if len(p0) < 2:
        return out
    d = p1 - p0
    a2 = d[:, 0] ** 2 + d[:, 1] ** 2
    ok = np.zeros(len(p0), bool)
    ok[1:] = ((p1[:-1] == p0[1:]).all(axis=1) & (radius[:-1] == radius[1:]) & apply[:-1]
              & apply[1:] & (a2[1:] > 1e-18))
    i = np.flatnonzero(ok)
    out[i] = radius[i] * np.abs(d[i, 2]) / np.sqrt(a2[i] + d[i, 2] ** 2)
    return out


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
