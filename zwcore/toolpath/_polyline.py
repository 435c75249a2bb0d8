"""Polyline helpers of the tool paths: one-sided chordal thinning, lifting out of gouges."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.toolpath.sweep import GridFrame, sweep_moves

F64 = NDArray[np.float64]

#: Rounds of the thinning (each removes up to half of the removable vertices).
THIN_ROUNDS = 12


def _removable(u: F64, z: F64, kept: NDArray[np.int64], tol: float) -> NDArray[np.bool_]:
    """For each interior kept vertex: may it go (every original point between its
    neighbours lies on or below the new chord, by at most ``tol``)?"""
    a, b = kept[:-2], kept[2:]
    span = b - a + 1
    owner = np.repeat(np.arange(len(a)), span)
    first = np.repeat(np.cumsum(span) - span, span)
    j = a[owner] + (np.arange(len(owner)) - first)
    du = u[b] - u[a]
    t = (u[j] - u[a[owner]]) / np.where(du[owner] != 0, du[owner], 1.0)
    chord = z[a[owner]] + t * (z[b[owner]] - z[a[owner]])
    gap = chord - z[j]
    starts = np.cumsum(span) - span
    lo = np.minimum.reduceat(gap, starts)
    hi = np.maximum.reduceat(gap, starts)
    return (lo >= 0.0) & (hi <= tol)


def thin(u: F64, z: F64, fixed: NDArray[np.bool_], tol: float) -> NDArray[np.bool_]:
    """Vertices to keep so that the chords stay on or above every dropped point, by at most ``tol``.

    Parameters
    ----------
    u, z : (n,) float64
        Position along the path (monotone between fixed vertices) and height.
    fixed : (n,) bool
        Vertices that stay (line ends, links); the first and last are always fixed.
    tol : float
        Chordal tolerance, mm.

    Returns
    -------
    keep : (n,) bool
    """
    n = len(u)
    fixed = fixed.copy()
    fixed[0] = fixed[-1] = True
    kept = np.arange(n)
    for rnd in range(THIN_ROUNDS):
        if len(kept) < 3:
            break
        ok = _removable(u, z, kept, tol) & ~fixed[kept[1:-1]]
        if not ok.any():
            break
        # an independent set: a candidate goes unless its left neighbour goes too
        pos = np.flatnonzero(ok)
        parity = (pos + rnd) % 2 == 0
        drop = pos[parity | ~np.isin(pos - 1, pos)]
        drop = drop[~np.isin(drop - 1, drop)]
        mask = np.ones(len(kept), bool)
        mask[drop + 1] = False
        kept = kept[mask]
    keep = np.zeros(n, bool)
    keep[kept] = True
    return keep


def lift_out_of_part(points: F64, part: ZMap, tool: Tool, lift_eps: float = 1e-6,
                     decimals: int = 4) -> tuple[F64, float]:
    """Raise polyline vertices so that no segment's sweep reaches below the part's nodes.

    Each segment is swept exactly (:func:`~zwcore.toolpath.sweep.sweep_moves`); its
    deepest gouge ``g`` is added to both its ends (a vertex takes the larger of its two
    segments' lifts). Raising ends never lowers a sweep, so one pass clears every segment.
    Heights are then rounded up to ``decimals`` (what the program will say).

    Parameters
    ----------
    points : (n, 3) float64
        Tip positions (xy already at the output precision).

    Returns
    -------
    points : (n, 3) float64
    max_lift : float
        Largest lift applied, mm.
    """
    out = points.copy()
    if len(points) < 2:
        return out, 0.0
    gouge = segment_gouge(points, part, tool)
    lift = np.where(gouge > 0.0, gouge + lift_eps, 0.0)
    vert = np.zeros(len(points))
    vert[:-1] = lift
    vert[1:] = np.maximum(vert[1:], lift)
    out[:, 2] += vert
    scale = 10.0 ** decimals
    out[:, 2] = np.ceil(out[:, 2] * scale - 1e-6) / scale
    # the rounding may not go below what was lifted
    low = out[:, 2] < points[:, 2] + vert
    out[low, 2] += 1.0 / scale
    return out, float(vert.max())


def segment_gouge(points: F64, part: ZMap, tool: Tool) -> F64:
    """Deepest part node below the sweep of each segment of a polyline (``-inf``: reaches
    none), mm."""
    if len(points) < 2:
        return np.zeros(0)
    return _pair_gouge(points[:-1], points[1:], part, tool)


def refine_against_part(points: F64, u: F64, fixed: NDArray[np.bool_], breaks: NDArray[np.bool_],
                        part: ZMap, tool: Tool, tol: float, min_len: float, rounds: int = 8
                        ) -> tuple[F64, F64, NDArray[np.bool_]]:
    """Split segments that gouge the part by more than ``tol`` at their midpoints, then lift.

    The inserted vertex starts on the chord, so every segment's gouge is measured with its
    final end points before any lift; at the end each vertex rises by the larger gouge of
    its two segments, which clears both (raising ends never lowers a sweep). The path thus
    follows the part's drop-cutter surface locally instead of rising by a long segment's
    worst gouge. ``breaks[i]``: segment ``i`` (a link) is not split. Only new halves are
    swept again in later rounds.

    Returns
    -------
    points, u, fixed
        With the inserted vertices; every segment clear of the part's nodes.
    """
    gouge = segment_gouge(points, part, tool)
    for _ in range(rounds):
        seg_len = np.hypot(*(points[1:, :2] - points[:-1, :2]).T)
        split = np.flatnonzero((gouge > tol) & (seg_len > min_len) & ~breaks)
        if not len(split):
            break
        at = split + 1
        mid = 0.5 * (points[at - 1] + points[at])
        # halves: (p[s], mid) and (mid, p[s+1]); measure them as a 2-vertex batch each
        halves0 = np.stack([points[split], mid], axis=1).reshape(-1, 3)
        halves1 = np.stack([mid, points[at]], axis=1).reshape(-1, 3)
        g_new = _pair_gouge(halves0, halves1, part, tool).reshape(-1, 2)
        points = np.insert(points, at, mid, axis=0)
        u = np.insert(u, at, 0.5 * (u[at - 1] + u[at]))
        fixed = np.insert(fixed, at, False)
        breaks = np.insert(breaks, split, False)
        gouge = np.insert(gouge, split, 0.0)
        pos = split + np.arange(len(split))  # first half's index after insertion
        gouge[pos] = g_new[:, 0]
        gouge[pos + 1] = g_new[:, 1]
    lift = np.where(gouge > 0.0, gouge, 0.0)
    vert = np.zeros(len(points))
    vert[:-1] = lift
    vert[1:] = np.maximum(vert[1:], lift)
    points = points.copy()
    points[:, 2] += vert
    return points, u, fixed


def _pair_gouge(p0: F64, p1: F64, part: ZMap, tool: Tool) -> F64:
    """Deepest gouge of each move ``p0[i] -> p1[i]`` (``-inf``: reaches no node)."""
    frame = GridFrame(part.x0, part.y0, part.dx, part.dy, part.shape)
    _, gouge = sweep_moves(frame, p0, p1, tool.radius, tool.kind == "ball", part.z,
                           ref=part.z, apply=False)
    return gouge
