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
from zwcore.toolpath._measure_kernel import measure_moves, measure_moves_bounded
from zwcore.toolpath._scan_links import _block_max
from zwcore.toolpath.sweep import BlockBounds, GridFrame, block_size, sweep_moves

F64 = NDArray[np.float64]
BOOL = NDArray[np.bool_]

#: The coarser first look's blocks, in blocks of the finer one.
LOOK_FACTOR = 4
#: Smallest skip block (nodes a side) of the exact measure against the part: its moves
#: only read (no block is measured again after a cut), so larger blocks than the sweep's
#: pay (1025² part, the measure's moves, CPU: Ø8 blocks of 4, the sweep's, 1.88 s; of 8,
#: 1.39 s; of 12, 1.57 s; Ø20 the same within noise for 8 to 12 (its sweep's: 9)).
MEASURE_BLOCK_MIN = 8
#: The exact measure of tools with block bounds: chained chords bounded in groups, each
#: chord's blocks read best first (:func:`~zwcore.toolpath._measure_kernel.
#: measure_bounded`; 1025² Ø20 finishing and Ø8 rest chords, one thread, CPU: 0.54 ->
#: 0.35 s and 0.50 -> 0.40 s against the sweep kernel of session 10); ``False``: the sweep
#: kernel over every block it cannot skip (the same values wherever they are positive:
#: the same paths; tests compare both).
BEST_FIRST = True
#: A lower bound must exceed a threshold by this much (mm) to stand for the exact gouge
#: (the subset's nodes are placed by another product of the spacing: ulps apart).
LOWER_MARGIN = 1e-6


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


def measure_block(radius: float, spacing: float) -> int:
    """Nodes a side of the skip blocks of the exact gouge measure for a tool of ``radius``
    on a part of node ``spacing`` (mm): the sweep's
    :func:`~zwcore.toolpath.sweep.block_size`, at least :data:`MEASURE_BLOCK_MIN`. The
    measure's positive values are exact whatever the blocks (a skipped block only ever
    holds values below zero)."""
    return max(MEASURE_BLOCK_MIN, block_size(radius, spacing))


class PartBounds:
    """Bounds of one part shared by every stage's gouge measure: the maxima of its node
    blocks (:class:`PartGouge`'s coarse look) and the exact sweep's skip blocks, each built
    once per block size (the part is fixed: a plan's stages measure against the same nodes,
    and building them is a pass over the whole part, a stage model's path's largest cost).

    Parameters
    ----------
    part : ZMap
    """

    def __init__(self, part: ZMap):
        self.part = part
        self.frame = GridFrame(part.x0, part.y0, part.dx, part.dy, part.shape)
        self._maxima: dict[int, F64] = {}
        self._skip: dict[int, BlockBounds] = {}
        self._every: dict[int, F64] = {}

    def block_maxima(self, b: int) -> F64:
        """``(ceil(ny / b), ceil(nx / b))``: the maximum of each block of ``b x b`` nodes
        (the last ones cut at the grid's edge)."""
        if b not in self._maxima:
            ny, nx = self.part.shape
            self._maxima[b] = np.empty((-(-ny // b), -(-nx // b)))
            _block_max(np.ascontiguousarray(self.part.z, np.float64), b, self._maxima[b])
        return self._maxima[b]

    def every(self, b: int) -> F64:
        """``(ceil(ny / b), ceil(nx / b))``: the part's nodes on every ``b``-th row and
        column (a subset of its nodes: a gouge against them is at most the whole part's)."""
        if b not in self._every:
            self._every[b] = np.ascontiguousarray(self.part.z[::b, ::b])
        return self._every[b]

    def skip_blocks(self, b: int) -> BlockBounds:
        """:class:`~zwcore.toolpath.sweep.BlockBounds` of the part against itself, blocks of
        ``b`` nodes a side (only measured against: no move changes them)."""
        if b not in self._skip:
            self._skip[b] = BlockBounds(self.frame, self.part.z, self.part.z, b)
        return self._skip[b]


class PartGouge:
    """Deepest gouge of moves against the part's nodes, with optional coarse first looks.

    With ``block > 1`` the part is also held as the maxima of ``B x B`` node blocks, one
    coarse node at each block's centre, for ``B = block`` and ``B = LOOK_FACTOR * block``.
    Every node of a block lies within ``rho`` (half the block's diagonal) of its centre, so
    a ball of radius ``R + rho`` whose tip runs ``rho`` lower stays under the ball of radius
    ``R`` over every node of the block (the larger sphere, same centre, holds the smaller
    one moved by up to ``rho``; a flat end mill needs no lowering). A move whose coarse
    measure is ``<= 0`` cannot gouge any node; the coarser look goes first, the finer one
    takes the moves it cannot clear, and only the rest are swept over the part's own nodes.
    The values that decide a lift or a split (``> 0``) are the exact ones, so the path is
    the same as with ``block = 1``, at a cost that scales with the coarse grids for moves
    clear of the part. ``bounds``: the part's block maxima and skip blocks, shared with
    other measures of the same part (default: built for this one).
    """

    def __init__(self, part: ZMap, tool: Tool, block: int = 1,
                 bounds: PartBounds | None = None):
        self.part, self.tool, self.block = part, tool, max(1, int(block))
        self.ball = tool.kind == "ball"
        if bounds is None or bounds.part is not part:
            bounds = PartBounds(part)
        self.bounds = bounds
        self.frame = bounds.frame
        #: ``(frame, block maxima, rho)`` per coarse look, the coarsest first
        self.looks: list[tuple[GridFrame, F64, float]] = []
        if self.block > 1:
            for b in (LOOK_FACTOR * self.block, self.block):
                coarse = bounds.block_maxima(b)
                half = 0.5 * (b - 1)
                self.looks.append((
                    GridFrame(part.x0 + half * part.dx, part.y0 + half * part.dy,
                              b * part.dx, b * part.dy, coarse.shape), coarse,
                    half * float(np.hypot(part.dx, part.dy)) * (1.0 + 1e-9) + 1e-12))

    def __call__(self, p0: F64, p1: F64, above: F64 | None = None) -> F64:
        """Gouge of each move ``p0[i] -> p1[i]``, mm: exact where ``> 0`` (``-inf``:
        reaches no node), except that with ``above`` (per move, a threshold; ``inf``:
        none), a move may get a lower bound of its gouge above its threshold instead of the
        exact value (a caller that only needs to know it lies above): with coarse looks,
        its gouge against every ``block``-th node row and column; with block bounds
        (:data:`BEST_FIRST`), the largest value of the first block read."""
        if not self.looks:  # every move swept over the part's nodes: no index shuffling
            return self._fine(p0, p1, above) if len(p0) else np.full(0, -np.inf)
        out = np.full(len(p0), -np.inf)
        todo = np.arange(len(p0))
        for frame, coarse, rho in self.looks:
            if not len(todo):
                return out
            drop = np.array([0.0, 0.0, rho if self.ball else 0.0])
            _, bound = sweep_moves(frame, p0[todo] - drop, p1[todo] - drop,
                                   self.tool.radius + rho, self.ball, coarse, ref=coarse,
                                   apply=False)
            out[todo] = bound
            todo = todo[bound > 0.0]
        if above is not None and self.looks and len(todo):
            out[todo] = self._every(p0[todo], p1[todo])
            todo = todo[~(out[todo] - LOWER_MARGIN > above[todo])]
        if len(todo):
            out[todo] = self._fine(p0[todo], p1[todo],
                                   None if above is None else above[todo])
        return out

    def _every(self, p0: F64, p1: F64) -> F64:
        """Gouge against the nodes on every ``block``-th row and column (a lower bound)."""
        b = self.block
        sub = self.bounds.every(b)
        frame = GridFrame(self.part.x0, self.part.y0, b * self.part.dx, b * self.part.dy,
                          sub.shape)
        _, low = sweep_moves(frame, p0, p1, self.tool.radius, self.ball, sub, ref=sub,
                             apply=False)
        return low

    def _fine(self, p0: F64, p1: F64, above: F64 | None = None) -> F64:
        """Gouge against every node of the part: exact where ``> 0``, except above
        ``above`` (a lower bound over it, as :meth:`__call__` allows)."""
        spacing = min(self.part.dx, self.part.dy)
        if self.tool.radius < sweep_mod.MIN_BLOCK_RADIUS * spacing:
            # too narrow for skip blocks: the measure-only plain sweep (the plain kernel's
            # values bit for bit, without the stock and the gathered indices)
            return measure_moves(self.part.x0, self.part.y0, self.part.dx, self.part.dy,
                                 p0, p1, self.tool.radius, self.ball, self.part.z)
        # the exact sweep skips blocks of nodes the move clears
        skip = self.bounds.skip_blocks(measure_block(self.tool.radius, spacing))
        if BEST_FIRST:  # the blocks best first, no further than the largest value found
            return measure_moves_bounded(self.frame, p0, p1, self.tool.radius, self.ball,
                                         self.part.z, skip, above)
        _, gouge = sweep_moves(self.frame, p0, p1, self.tool.radius, self.ball,
                               self.part.z, ref=self.part.z, apply=False, bounds=skip)
        return gouge


def _above(p0: F64, p1: F64, tol: float, min_len: float, again: BOOL | bool) -> F64:
    """Per move, the threshold above which its gouge need not be known exactly: ``tol``
    where it is halved (longer than ``min_len``, and ``again``: a later round or step
    halves it), else ``inf``; the same length test as :func:`_split`'s."""
    seg_len = np.hypot(*(p1[:, :2] - p0[:, :2]).T)
    return np.where((seg_len > min_len) & again, tol, np.inf)


def _measure_moves(measure: PartGouge, p0: F64, p1: F64, above: F64, link: BOOL,
                   moves_at_breaks: bool) -> F64:
    """``measure(p0, p1, above)``, the links' exact (never halved: no threshold); without
    ``moves_at_breaks`` the links get ``-inf`` (no move: no gouge, no lift) and are not
    swept."""
    above = np.where(link, np.inf, above)
    if moves_at_breaks:
        return measure(p0, p1, above)
    out = np.full(len(p0), -np.inf)
    real = np.flatnonzero(~link)
    out[real] = measure(p0[real], p1[real], above[real])
    return out


def _split(points: F64, u: F64, gouge: F64, breaks: BOOL, measure: PartGouge, tol: float,
           min_len: float, decimals: int, rounds: int) -> tuple[F64, F64, F64]:
    """Halve segments that gouge by more than ``tol`` (midpoint xy at the output precision,
    z on the chord, so each half is measured as it will be written); only new halves are
    swept again. A half the next round halves again when it gouges by more than ``tol``
    needs no more than that known (``above``): the last round's halves, exact values.

    Only the segments still being halved are carried from round to round (a segment left
    whole keeps its length and gouge, so it is never halved later): each midpoint gets a
    key between its segment's ends' (the segment's start index plus a dyadic fraction,
    exact in float64), and the points and the final segments' gouges are put in path order
    once at the end, instead of inserting into the whole polyline every round."""
    if rounds <= 0 or len(points) < 2:
        return points, u, gouge
    seg_len = np.hypot(*(points[1:, :2] - points[:-1, :2]).T)
    live = np.flatnonzero((gouge > tol) & (seg_len > min_len) & ~breaks)
    if not len(live):
        return points, u, gouge
    pa, pb, ua, ub = points[live], points[live + 1], u[live], u[live + 1]
    ka = live.astype(np.float64)
    kb = ka + 1.0
    mids: list[tuple[F64, F64, F64]] = []  # (key, point, u) of every midpoint
    leaves: list[tuple[F64, F64]] = []  # (start key, gouge) of the halves left whole
    for r in range(rounds):
        mid = 0.5 * (pa + pb)
        mid[:, :2] = np.round(mid[:, :2], decimals)
        km = 0.5 * (ka + kb)
        mids.append((km, mid, 0.5 * (ua + ub)))
        a = np.stack([pa, mid], axis=1).reshape(-1, 3)  # the halves in path order
        b = np.stack([mid, pb], axis=1).reshape(-1, 3)
        g = measure(a, b, _above(a, b, tol, min_len, r + 1 < rounds))
        k0 = np.stack([ka, km], axis=1).ravel()
        if r + 1 == rounds:
            leaves.append((k0, g))
            break
        again = (g > tol) & (np.hypot(*(b[:, :2] - a[:, :2]).T) > min_len)
        leaves.append((k0[~again], g[~again]))
        if not again.any():
            break
        u0 = np.stack([ua, mids[-1][2]], axis=1).ravel()
        u1 = np.stack([mids[-1][2], ub], axis=1).ravel()
        k1 = np.stack([km, kb], axis=1).ravel()
        pa, pb, ua, ub, ka, kb = a[again], b[again], u0[again], u1[again], k0[again], k1[again]
    # where each point lands: a point of the polyline after the midpoints before it (those
    # of the segments before its own), a midpoint after the points and midpoints before it
    mk = np.concatenate([m[0] for m in mids])
    mo = np.argsort(mk, kind="stable")
    mk = mk[mo]
    seg = mk.astype(np.int64)  # the polyline segment each midpoint lies on
    before = np.zeros(len(points), np.int64)
    before[1:] = np.cumsum(np.bincount(seg, minlength=len(points) - 1))
    at_p = np.arange(len(points)) + before
    at_m = np.arange(len(mk)) + seg + 1
    m_total = len(points) + len(mk)
    pts = np.empty((m_total, 3))
    pts[at_p] = points
    pts[at_m] = np.concatenate([m[1] for m in mids])[mo]
    uu = np.empty(m_total)
    uu[at_p] = u
    uu[at_m] = np.concatenate([m[2] for m in mids])[mo]
    out = np.empty(m_total - 1)
    out[at_p[:-1]] = gouge
    # a halved segment's start is its first half's (or that half's first half's ...) start
    for k, g in leaves:
        whole = k == np.floor(k)
        pos = np.empty(len(k), np.int64)
        pos[whole] = at_p[k[whole].astype(np.int64)]
        pos[~whole] = at_m[np.searchsorted(mk, k[~whole])]
        out[pos] = g
    return pts, uu, out


class LazyPoints:
    """Tip positions ``(round(x0 + x, decimals), round(y0 + y, decimals), z)`` built only
    where they are read: :func:`follow_part` reads every height but the positions of the
    kept vertices only (about half of a raster's points on Mount Rushmore's Ø1 passes),
    and rounding is per element, so the points taken are those of the whole array.

    Parameters
    ----------
    x0, y0 : float
        Offsets added before rounding, mm.
    x, y, z : (n,) float64
    decimals : int
    """

    def __init__(self, x0: float, y0: float, x: F64, y: F64, z: F64, decimals: int):
        self.x0, self.y0, self.x, self.y, self.z = x0, y0, x, y, z
        self.decimals = decimals

    def __len__(self) -> int:
        return len(self.z)

    def take(self, idx: NDArray[np.int64]) -> F64:
        """``(len(idx), 3)``: the points at ``idx``."""
        out = np.empty((len(idx), 3))
        np.round(self.x0 + self.x[idx], self.decimals, out=out[:, 0])
        np.round(self.y0 + self.y[idx], self.decimals, out=out[:, 1])
        out[:, 2] = self.z[idx]
        return out


def _take(points: F64 | LazyPoints, idx: NDArray[np.int64]) -> F64:
    return points.take(idx) if isinstance(points, LazyPoints) else points[idx]


def follow_part(points: F64 | LazyPoints, u: F64, fixed: BOOL, breaks: BOOL, measure: PartGouge, *,
                chord: float, refine: float, min_len: float, decimals: int = 4,
                rounds: int = 8, moves_at_breaks: bool = True) -> tuple[F64, F64, float]:
    """Thin a CL polyline, then lift it so that no segment's sweep reaches below the part.

    Parameters
    ----------
    points : (n, 3) float64 or LazyPoints
        Tip positions, xy at the output precision (:class:`LazyPoints`: built only for
        the vertices that are kept).
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
    moves_at_breaks : bool
        The links are moves of the path (lines linked beside the stock): they are measured
        and their ends lifted out of their gouge like any segment's. ``False``: the breaks
        only separate pieces that are entered on their own (segments entered from above):
        they are no moves, are not measured, and lift nothing (each piece's own moves lift
        its ends).

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
        return _take(points, np.arange(len(points))).copy(), u.copy(), 0.0
    z = points.z if isinstance(points, LazyPoints) else points[:, 2]
    # a band of chord/2 each way: a chord under the CL polyline gouges by about as much and is
    # lifted by its exact gouge below, so the path ends within ``chord`` above the CL polyline
    keep = thin(u, z, fixed, 0.5 * chord, 0.5 * chord)
    idx = np.flatnonzero(keep)
    kept = _take(points, idx)
    # a chord that gouges by more than ``refine`` gets its dropped points back, or is
    # halved (a link never): its exact gouge is not needed
    a, b, link = kept[:-1], kept[1:], breaks[idx[:-1]]
    gap = idx[1:] - idx[:-1] > 1
    above = np.where(gap, refine, _above(a, b, refine, min_len, rounds > 0))
    gouge = _measure_moves(measure, a, b, above, link, moves_at_breaks)
    bad = np.flatnonzero((gouge > refine) & ~link & gap)
    if len(bad):  # the dropped points of gouging chords come back
        back = np.zeros(len(points) + 1, np.int64)
        np.add.at(back, idx[bad] + 1, 1)
        np.add.at(back, idx[bad + 1], -1)
        keep |= np.cumsum(back)[:-1] > 0
        new = np.flatnonzero(keep)
        # a chord between two vertices kept before is unchanged (every vertex kept before
        # is kept: none lies between them): its measure stays, found by its start's rank
        # among the vertices kept before; the pieces of returned ones are swept
        rank = np.full(len(points), -1, np.int64)
        rank[idx] = np.arange(len(idx))
        start, end = rank[new[:-1]], rank[new[1:]]
        known = (start >= 0) & (end >= 0)
        g = np.empty(len(new) - 1)
        g[known] = gouge[start[known]]
        fresh = np.flatnonzero(~known)
        kept = _take(points, new)
        a, b, link = kept[fresh], kept[fresh + 1], breaks[new[fresh]]
        g[fresh] = _measure_moves(measure, a, b, _above(a, b, refine, min_len, rounds > 0),
                                  link, moves_at_breaks)
        idx, gouge = new, g
    seg_breaks = breaks[idx[:-1]]
    pts, uu, gouge = _split(kept, u[idx], gouge, seg_breaks, measure, refine,
                            min_len, decimals, rounds)
    out, vmax = lift_points(pts, gouge, decimals)
    return out, uu, vmax


def lift_points(pts: F64, gouge: F64, decimals: int) -> tuple[F64, float]:
    """The points ``(n, 3)`` lifted by the gouge of the chords on either side (``gouge``
    ``(n - 1,)``, per chord; only positive values lift) and rounded up to ``decimals``
    (never below the lift), and the largest lift."""
    lift = np.where(gouge > 0.0, gouge, 0.0)
    vert = np.zeros(len(pts))
    vert[:-1] = lift
    vert[1:] = np.maximum(vert[1:], lift)
    out = pts.copy()
    want = pts[:, 2] + vert
    scale = 10.0 ** decimals
    out[:, 2] = np.ceil(want * scale - 1e-6) / scale
    out[out[:, 2] < want, 2] += 1.0 / scale  # the rounding may not go below the lift
    return out, float(vert.max())
