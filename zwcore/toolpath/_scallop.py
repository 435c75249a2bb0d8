"""Extra scan lines where the simulated scallop of a finishing pass exceeds the tolerance.

The plan lays its lines by a closed-form scallop rule; on a wall steep *along* the lines the
ball's track is a tube tilted by that slope, whose cross-section in the vertical plane
across the lines is stretched by ``1 / cos(slope)``, so the rule underestimates there. Here
and between CL samples on such a wall the chord leaves material too. Here the pass's own
feed moves are swept exactly over the part's nodes (:func:`~zwcore.toolpath.sweep.sweep_moves`)
and compared with what the ball leaves at best (:func:`finishing_closing`); wherever the
difference exceeds the tolerance, the nearest line is cut again over the node's ``u`` plus
and minus the radius with tip heights from the node drop-cutter every quarter of a grid
step (:func:`fine_points`), and a line is added midway to the next line where the node lies
between lines.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray
from scipy import ndimage

from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.toolpath.sweep import GridFrame, sweep_moves

F64 = NDArray[np.float64]


def _ball_footprint(part: ZMap, tool: Tool) -> tuple[NDArray[np.bool_], F64, int, int]:
    """The nodes within reach of a node (a node exactly R away is a tie, as in the sweep)
    and the tool's lower profile over them: ``(foot, prof, my, mx)``."""
    r = tool.radius
    my, mx = math.ceil(r / part.dy), math.ceil(r / part.dx)
    yy, xx = np.mgrid[-my:my + 1, -mx:mx + 1]
    d2 = (xx * part.dx) ** 2 + (yy * part.dy) ** 2
    foot = d2 < r * r * (1.0 - 1e-10)
    prof = r - np.sqrt(np.maximum(r * r - d2, 0.0)) if tool.kind == "ball" else np.zeros(d2.shape)
    return foot, np.where(foot, prof, np.inf), my, mx


def finishing_closing(part: ZMap, tool: Tool, cl: F64) -> F64:
    """What the ball leaves on the part's nodes with its tip at ``cl`` over every node: the
    grey erosion of the CL surface by the ball's lower profile (``scipy.ndimage``, node
    semantics like the sweep), ``(ny, nx)``.

    Parameters
    ----------
    cl : (ny, nx) float64
        The pass's CL heights on the part's nodes (what its lines are sampled from): the
        comparison is with what that CL source allows, so a conservative CL does not
        call for lines that could not do better.
    """
    foot, prof, _, _ = _ball_footprint(part, tool)
    s = np.where(foot, -prof, 0.0)
    return ndimage.grey_erosion(cl, structure=s, footprint=foot, mode="constant", cval=np.inf)


@njit(cache=True, nogil=True)
def _argmin_kernel(cl: F64, prof: F64, my: int, mx: int, i: NDArray[np.intp],
                   k: NDArray[np.intp], ci: NDArray[np.intp], ck: NDArray[np.intp]) -> None:
    ny, nx = cl.shape
    for n in range(len(i)):
        best, bi, bk = math.inf, i[n], k[n]
        for a in range(-my, my + 1):
            for b in range(-mx, mx + 1):
                r, c = i[n] + a, k[n] + b
                if 0 <= r < ny and 0 <= c < nx:
                    v = cl[r, c] + prof[a + my, b + mx]
                    if v < best:
                        best, bi, bk = v, r, c
        ci[n], ck[n] = bi, bk


def _best_positions(part: ZMap, tool: Tool, cl: F64, i: NDArray[np.intp], k: NDArray[np.intp]
                    ) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """For nodes ``(i, k)``: the node whose CL position leaves the least over them (the
    erosion's argmin)."""
    _, prof, my, mx = _ball_footprint(part, tool)
    ci, ck = np.empty(len(i), np.intp), np.empty(len(i), np.intp)
    _argmin_kernel(np.ascontiguousarray(cl, np.float64), np.ascontiguousarray(prof), my, mx,
                   i.astype(np.intp), k.astype(np.intp), ci, ck)
    return ci, ck


@njit(cache=True, nogil=True)
def _drop_kernel(px: F64, py: F64, z: F64, x0: float, y0: float, dx: float, dy: float,
                 r: float, ball: bool, out: F64) -> None:
    ny, nx = z.shape
    reach2 = r * r * (1.0 - 1e-10)
    for n in range(len(px)):
        k0 = max(0, math.ceil((px[n] - r - x0) / dx))
        k1 = min(nx - 1, math.floor((px[n] + r - x0) / dx))
        i0 = max(0, math.ceil((py[n] - r - y0) / dy))
        i1 = min(ny - 1, math.floor((py[n] + r - y0) / dy))
        best = -math.inf
        for i in range(i0, i1 + 1):
            wy = y0 + i * dy - py[n]
            for k in range(k0, k1 + 1):
                wx = x0 + k * dx - px[n]
                d2 = wx * wx + wy * wy
                if d2 < reach2:
                    h = z[i, k] - (r - math.sqrt(r * r - d2) if ball else 0.0)
                    best = max(best, h)
        out[n] = best


def node_drop_cutter(part: ZMap, tool: Tool, x: F64, y: F64) -> F64:
    """Lowest tip height at each point ``(x, y)`` whose tool clears every part node
    (``-inf`` where it reaches none), ``(n,)``."""
    out = np.empty(len(x))
    _drop_kernel(np.ascontiguousarray(x, np.float64), np.ascontiguousarray(y, np.float64),
                 np.ascontiguousarray(part.z, np.float64), float(part.x0), float(part.y0),
                 float(part.dx), float(part.dy), float(tool.radius), tool.kind == "ball", out)
    return out


def fine_points(part: ZMap, tool: Tool, offset: F64, start: F64, stop: F64, along_x: bool,
                step: float) -> tuple[F64, F64, F64, NDArray[np.int64]]:
    """Points of line segments every ``step`` (and their ends), heights from the node
    drop-cutter (:func:`node_drop_cutter`): ``u, v, z`` and the points per segment."""
    sizes = np.maximum(np.ceil((stop - start) / step).astype(np.int64), 1) + 1
    first = np.cumsum(sizes) - sizes
    owner = np.repeat(np.arange(len(offset)), sizes)
    j = np.arange(int(sizes.sum())) - first[owner]
    u = np.minimum(start[owner] + j * step, stop[owner])
    v = offset[owner]
    x, y = (u, v) if along_x else (v, u)
    z = node_drop_cutter(part, tool, part.x0 + x, part.y0 + y)
    z = np.where(np.isfinite(z), z, part.z.min())  # reaches no node: any height is clear
    return u, v, z, sizes


def scallop_segments(part: ZMap, tool: Tool, env: F64, p0: F64, p1: F64, best: F64, cl: F64,
                     tolerance: float, along_x: bool) -> tuple[F64, F64, F64]:
    """Line segments (in the frame of the lines) to cut again where a pass leaves too much.

    Parameters
    ----------
    part : ZMap
    tool : Tool
        The pass's ball.
    env : (ny, nx) float64
        What the pass's moves so far leave (``inf`` before any); lowered in place by
        ``p0 -> p1``. Nodes it leaves at ``inf`` (not cut) are not looked at.
    p0, p1 : (n, 3) float64
        The pass's feed moves not yet in ``env`` (absolute coordinates).
    best, cl : (ny, nx) float64
        What the ball leaves at best (:func:`finishing_closing`) and the CL heights it
        comes from.
    tolerance : float
    along_x : bool

    Returns
    -------
    offset, start, stop : (k,) float64
        For each node left above ``best + tolerance``: through the node drop-cutter position
        that leaves the least over it, along the lines, plus and minus the radius (merged
        per offset: the positions are nodes, so offsets repeat).
    """
    frame = GridFrame(part.x0, part.y0, part.dx, part.dy, part.shape)
    sweep_moves(frame, p0, p1, tool.radius, tool.kind == "ball", env)
    i, k = np.nonzero(np.isfinite(env) & (env - best > tolerance))
    empty = np.zeros(0)
    if not len(i):
        return empty, empty, empty
    # a segment through the CL position that leaves the least over each such node,
    # along the lines: the ball passes where the closing says it reaches the node
    ci, ck = _best_positions(part, tool, cl, i, k)
    u, mid = (ck * part.dx, ci * part.dy) if along_x else (ci * part.dy, ck * part.dx)
    extent = (part.shape[1] - 1) * part.dx if along_x else (part.shape[0] - 1) * part.dy
    a = np.maximum(u - tool.radius, 0.0)
    b = np.minimum(u + tool.radius, extent)
    order = np.lexsort((a, mid))
    mid, a, b = mid[order], a[order], b[order]
    # merge overlapping spans on the same offset: a new run where the offset changes or the
    # span starts after every earlier span of the offset has ended (a running max of the
    # ends within each offset: ends shifted by the offset's rank stay apart)
    same = np.r_[False, mid[1:] == mid[:-1]]
    rank = np.cumsum(~same) * (extent + 2.0 * tool.radius + 1.0)
    reach = np.maximum.accumulate(b + rank) - rank
    new = ~same | (a > np.r_[-np.inf, reach[:-1]])
    run = np.cumsum(new) - 1
    n = int(run[-1]) + 1
    out_a = np.full(n, np.inf)
    out_b = np.full(n, -np.inf)
    np.minimum.at(out_a, run, a)
    np.maximum.at(out_b, run, b)
    out_off = np.zeros(n)
    out_off[run] = mid
    return out_off, out_a, out_b
