"""Polyline helpers of the tool paths: one-sided chordal thinning, then lifting out of the part.

:func:`follow_part` is the whole step a scan-line path goes through: thin the CL polyline
first (a chord never passes below a dropped point, and at most ``chord`` above it), sweep
only the kept chords exactly against the part's nodes, give a chord that gouges by more
than the refine tolerance its dropped points back (then halve what still gouges), and raise
every vertex by the larger gouge of its two segments. Sweeping the few long chords instead
of every raw segment is what makes it cheap: the node visits of a move are its length times
the tool's width plus a disc at its end, and the discs dominate short moves.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.toolpath import sweep as sweep_mod
from zwcore.toolpath.sweep import BlockBounds, GridFrame, block_size, sweep_moves

F64 = NDArray[np.float64]
BOOL = NDArray[np.bool_]


@njit(cache=True, nogil=True)
def _thin_kernel(u: F64, z: F64, fixed: BOOL, below: float, above: float, keep: BOOL) -> None:
    """Greedy band thinning: from each kept vertex the longest chord whose slope lies in
    every dropped point's window ``[(z_j - below - z_a)/du_j, (z_j + above - z_a)/du_j]``."""
    n = len(u)
    keep[0] = True
    keep[n - 1] = True
    a = 0
    while a < n - 1:
        lo, hi = -np.inf, np.inf
        best = a + 1
        j = a + 1
        while j < n:
            du = u[j] - u[a]
            if du <= 0.0:  # not monotone: stop the chord before it
                break
            s = (z[j] - z[a]) / du
            if j > a + 1 and not (lo <= s <= hi):
                break
            best = j
            if fixed[j]:
                break
            lo = max(lo, (z[j] - below - z[a]) / du)
            hi = min(hi, (z[j] + above - z[a]) / du)
            j += 1
        keep[best] = True
        a = best


def thin(u: F64, z: F64, fixed: BOOL, above: float, below: float = 0.0) -> BOOL:
    """Vertices to keep so that every dropped point lies between ``below`` under and
    ``above`` over the chord that replaces it.

    Parameters
    ----------
    u, z : (n,) float64
        Position along the path (increasing between fixed vertices) and height.
    fixed : (n,) bool
        Vertices that stay (line ends, links); the first and last always stay.
    above, below : float
        How far the chord may pass over / under a dropped point, mm (``below = 0``: the
        chords never pass below it).

    Returns
    -------
    keep : (n,) bool
    """
    keep = np.zeros(len(u), bool)
    if len(u):
        _thin_kernel(np.ascontiguousarray(u, np.float64), np.ascontiguousarray(z, np.float64),
                     np.ascontiguousarray(fixed, np.bool_), float(below), float(above), keep)
    return keep


class PartGouge:
    """Deepest gouge of moves against the part's nodes, with an optional coarse first look.

    With ``block > 1`` the part is also held as the maxima of ``block x block`` node blocks,
    one coarse node at each block's centre. Every node of a block lies within
    ``rho`` (half the block's diagonal) of its centre, so a ball of radius ``R + rho`` whose
    tip runs ``rho`` lower stays under the ball of radius ``R`` over every node of the
    block (the larger sphere, same centre, holds the smaller one moved by up to ``rho``; a
    flat end mill needs no lowering). A move whose coarse measure is ``<= 0`` cannot gouge
    any node; only the others are swept over the part's own nodes. The values that decide a
    lift or a split (``> 0``) are always the exact ones, so the path is the same as with
    ``block = 1``, at a cost that scales with the coarse grid for moves clear of the part.
    """

    def __init__(self, part: ZMap, tool: Tool, block: int = 1):
        self.part, self.tool, self.block = part, tool, max(1, int(block))
        self.ball = tool.kind == "ball"
        self.frame = GridFrame(part.x0, part.y0, part.dx, part.dy, part.shape)
        self._bounds: BlockBounds | None = None
        if self.block > 1:
            b = self.block
            ny, nx = part.shape
            my, mx = -(-ny // b), -(-nx // b)
            pad = np.full((my * b, mx * b), -np.inf)
            pad[:ny, :nx] = part.z
            self.coarse = np.ascontiguousarray(pad.reshape(my * b, mx, b).max(axis=2)
                                               .reshape(my, b, mx).max(axis=1))
            half = 0.5 * (b - 1)
            self.coarse_frame = GridFrame(part.x0 + half * part.dx, part.y0 + half * part.dy,
                                          b * part.dx, b * part.dy, (my, mx))
            self.rho = half * float(np.hypot(part.dx, part.dy)) * (1.0 + 1e-9) + 1e-12

    def __call__(self, p0: F64, p1: F64) -> F64:
        """Gouge of each move ``p0[i] -> p1[i]`` (exact where ``> 0``; ``-inf``: reaches
        no node), mm."""
        if self.block == 1 or not len(p0):
            return self._fine(p0, p1)
        drop = np.array([0.0, 0.0, self.rho if self.ball else 0.0])
        _, bound = sweep_moves(self.coarse_frame, p0 - drop, p1 - drop,
                               self.tool.radius + self.rho, self.ball, self.coarse,
                               ref=self.coarse, apply=False)
        out = bound.copy()
        near = np.flatnonzero(bound > 0.0)
        if len(near):
            out[near] = self._fine(p0[near], p1[near])
        return out

    def _fine(self, p0: F64, p1: F64) -> F64:
        if self._bounds is None and self.tool.radius >= sweep_mod.MIN_BLOCK_RADIUS * min(
                self.part.dx, self.part.dy):
            # the exact sweep skips blocks of nodes the move clears (the part is fixed: its
            # bounds are measured once, when first needed)
            self._bounds = BlockBounds(self.frame, self.part.z, self.part.z,
                                       block_size(self.tool.radius,
                                                  min(self.part.dx, self.part.dy)))
        _, gouge = sweep_moves(self.frame, p0, p1, self.tool.radius, self.ball,
                               self.part.z, ref=self.part.z, apply=False, bounds=self._bounds)
        return gouge


def _split(points: F64, u: F64, gouge: F64, breaks: BOOL, measure: PartGouge, tol: float,
           min_len: float, decimals: int, rounds: int) -> tuple[F64, F64, F64]:
    """Halve segments that gouge by more than ``tol`` (midpoint xy at the output precision,
    z on the chord, so each half is measured as it will be written); only new halves are
    swept again."""
    for _ in range(rounds):
        seg_len = np.hypot(*(points[1:, :2] - points[:-1, :2]).T)
        split = np.flatnonzero((gouge > tol) & (seg_len > min_len) & ~breaks)
        if not len(split):
            break
        at = split + 1
        mid = 0.5 * (points[at - 1] + points[at])
        mid[:, :2] = np.round(mid[:, :2], decimals)
        g_new = measure(np.stack([points[split], mid], axis=1).reshape(-1, 3),
                        np.stack([mid, points[at]], axis=1).reshape(-1, 3)).reshape(-1, 2)
        points = np.insert(points, at, mid, axis=0)
        u = np.insert(u, at, 0.5 * (u[at - 1] + u[at]))
        breaks = np.insert(breaks, split, False)
        gouge = np.insert(gouge, split, 0.0)
        pos = split + np.arange(len(split))  # first half's index after insertion
        gouge[pos] = g_new[:, 0]
        gouge[pos + 1] = g_new[:, 1]
    return points, u, gouge


def follow_part(points: F64, u: F64, fixed: BOOL, breaks: BOOL, measure: PartGouge, *,
                chord: float, refine: float, min_len: float, decimals: int = 4,
                rounds: int = 8) -> tuple[F64, F64, float]:
    """Thin a CL polyline, then lift it so that no segment's sweep reaches below the part.

    Parameters
    ----------
    points : (n, 3) float64
        Tip positions, xy at the output precision.
    u : (n,) float64
        Parameter along the path (increasing between fixed vertices).
    fixed : (n,) bool
        Vertices that stay (line ends, link ends).
    breaks : (n - 1,) bool
        Segments that are links (never split; their ends are fixed).
    measure : PartGouge
        The gouge of moves against the part's nodes (the tool and the part).
    chord : float
        One-sided chordal tolerance of the thinning, mm.
    refine : float
        A segment that gouges by more than this gets its dropped points back, then is
        halved (down to ``min_len``), so the path follows the part's drop-cutter surface
        instead of rising by a long segment's worst gouge.
    decimals : int
        Heights are rounded up to this many decimals (what the program says).

    Returns
    -------
    points : (m, 3) float64
        Every segment clear of the part's nodes (raising a segment's ends never lowers its
        sweep, and rounding z up only raises it).
    u : (m,) float64
    max_lift : float
        Largest lift applied, mm.
    """
    if len(points) < 2:
        return points.copy(), u.copy(), 0.0
    # a band of chord/2 each way: a chord under the CL polyline gouges by about as much and is
    # lifted by its exact gouge below, so the path ends within ``chord`` above the CL polyline
    keep = thin(u, points[:, 2], fixed, 0.5 * chord, 0.5 * chord)
    idx = np.flatnonzero(keep)
    gouge = measure(points[idx[:-1]], points[idx[1:]])
    bad = np.flatnonzero((gouge > refine) & ~breaks[idx[:-1]] & (idx[1:] - idx[:-1] > 1))
    if len(bad):  # the dropped points of gouging chords come back
        back = np.zeros(len(points) + 1, np.int64)
        np.add.at(back, idx[bad] + 1, 1)
        np.add.at(back, idx[bad + 1], -1)
        keep |= np.cumsum(back)[:-1] > 0
        new = np.flatnonzero(keep)
        known = np.isin(new[:-1], idx[:-1]) & np.isin(new[1:], idx[1:])
        g = np.empty(len(new) - 1)
        # an unchanged chord keeps its measure; the pieces of returned ones are swept
        g[known] = gouge[np.searchsorted(idx, new[:-1][known])]
        fresh = np.flatnonzero(~known)
        g[fresh] = measure(points[new[fresh]], points[new[fresh + 1]])
        idx, gouge = new, g
    seg_breaks = breaks[idx[:-1]]
    pts, uu, gouge = _split(points[idx], u[idx], gouge, seg_breaks, measure, refine,
                            min_len, decimals, rounds)
    lift = np.where(gouge > 0.0, gouge, 0.0)
    vert = np.zeros(len(pts))
    vert[:-1] = lift
    vert[1:] = np.maximum(vert[1:], lift)
    out = pts.copy()
    want = pts[:, 2] + vert
    scale = 10.0 ** decimals
    out[:, 2] = np.ceil(want * scale - 1e-6) / scale
    out[out[:, 2] < want, 2] += 1.0 / scale  # the rounding may not go below the lift
    return out, uu, float(vert.max())
