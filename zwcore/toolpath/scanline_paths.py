"""Scan-line tool paths of ball-end-mill stages (design section 3, issue 12).

A stage's raster runs along its scan direction on the plan's scan lines
(:attr:`~zwcore.scanline.results.ScanlineStage.lines`): the whole lines zig-zag, run past
the stock edges (entry, exit and links in air beside the stock); the extra segments where
the plan needs a finer pick-feed follow, each entered by a rapid to just above the stock it
meets (tracked by sweeping the stage's moves) and a plunge-feed move down to it. Tip
heights come from a drop-cutter against the stage's own model at the stage's own
resolution (``cl_heights``, e.g. :func:`zwcore.sim.drop_cutter`): a coarse stage is a few
hundred points. Each line is thinned one-sidedly (a chord never passes below a dropped
point, and at most ``chord_tolerance`` above), then every move is swept exactly against
the part's nodes at the input resolution and lifted out of any gouge
(:func:`~zwcore.toolpath._polyline.lift_out_of_part`): whatever the model's resolution, no
move reaches below the part.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from zwcore.errors import InvalidInputError
from zwcore.grid.feeds import DEFAULT_RAPID_FEED
from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.scanline.results import ScanlineStage
from zwcore.toolpath._polyline import LazyPoints, PartBounds, PartGouge, follow_part
from zwcore.toolpath._scallop import fine_points, finishing_closing, scallop_segments
from zwcore.toolpath._scan_cl import CLHeights, _stage_cl, sim_cl_heights
from zwcore.toolpath._scan_links import StockBound, merge_stretches, region_stretches
from zwcore.toolpath.program import LINE, RAPID, CuttingData, Moves, StagePath

__all__ = ["CLHeights", "scanline_stage_path", "sim_cl_heights"]

#: Smallest block (input nodes a side) of the gouge measure's coarse first look.
BLOCK_MIN = 1
#: Height above the stock bound where a rapid down or across ends, mm.
ENTRY_GAP = 0.5
#: Rounds of scallop lines on a finishing pass (each halves the spacing where it is added).
SCALLOP_ROUNDS = 2

F64 = NDArray[np.float64]

def _raster(cl: F64, rows: F64) -> F64:
    """CL heights on fractional rows (linear between the grid rows; the lift makes it safe)."""
    r0 = np.clip(np.floor(rows).astype(np.int64), 0, cl.shape[0] - 1)
    t = rows - r0
    r1 = np.where(t > 0.0, np.minimum(r0 + 1, cl.shape[0] - 1), r0)  # a line on a row: one
    t = t[:, None]
    out = (1.0 - t) * cl[r0] + t * cl[r1]
    if np.isnan(out).any():  # a row the CL left out (:func:`_stage_cl`): a bug, not input
        raise RuntimeError("a scan line reads a CL row that was not computed")
    return out


def _segment_points(cl: F64, offset: F64, start: F64, stop: F64, sx: float, sy: float
                    ) -> tuple[F64, F64, F64, NDArray[np.int64]]:
    """Points of line segments on the CL grid: each segment's ends and the model columns
    strictly inside it, heights bilinear between the CL rows and columns.

    Returns
    -------
    u, v, z : (m,) float64
    sizes : (n,) int64
        Points per segment (in order).
    """
    nr, nc = cl.shape
    c_lo = np.floor(start / sx).astype(np.int64) + 1
    c_hi = np.minimum(np.ceil(stop / sx).astype(np.int64) - 1, nc - 1)
    inner = np.maximum(c_hi - c_lo + 1, 0)
    sizes = inner + 2
    first = np.cumsum(sizes) - sizes
    owner = np.repeat(np.arange(len(offset)), sizes)
    j = np.arange(int(sizes.sum())) - first[owner]
    u = (c_lo[owner] + j - 1) * sx
    u[first] = start
    u[first + sizes - 1] = stop
    rows = offset / sy
    r0 = np.clip(np.floor(rows).astype(np.int64), 0, nr - 1)
    r1 = np.where(rows > r0, np.minimum(r0 + 1, nr - 1), r0)  # a segment on a row: one
    t = (rows - r0)[owner]
    k = np.clip(np.floor(u / sx).astype(np.int64), 0, max(nc - 2, 0))
    f = np.clip(u / sx - k, 0.0, 1.0)
    k1 = np.minimum(k + 1, nc - 1)
    a, b = r0[owner], r1[owner]
    left = (1.0 - t) * cl[a, k] + t * cl[b, k]
    right = (1.0 - t) * cl[a, k1] + t * cl[b, k1]
    return u, offset[owner], (1.0 - f) * left + f * right, sizes


class _Polyline:
    """Builds a path (xy rounded to the output) through the refine, thin and lift steps."""

    def __init__(self, part: ZMap, tool: Tool, along_x: bool, chord: float, decimals: int,
                 refine: float, min_len: float, block: int = 1,
                 bounds: PartBounds | None = None):
        self.part, self.tool, self.along_x = part, tool, along_x
        self.measure = PartGouge(part, tool, block, bounds)
        self.chord, self.decimals = chord, decimals
        self.refine, self.min_len = refine, min_len

    def points(self, u: F64, v: F64, z: F64, su: F64, fixed: NDArray[np.bool_],
               breaks: NDArray[np.bool_], moves_at_breaks: bool = True
               ) -> tuple[F64, float, F64]:
        part, dec = self.part, self.decimals
        x, y = (u, v) if self.along_x else (v, u)
        # the points are built only where follow_part reads them (the kept vertices)
        pts = LazyPoints(part.x0, part.y0, x, y, z, dec)
        out, su, lift = follow_part(pts, su, fixed, breaks, self.measure, chord=self.chord,
                                    refine=self.refine, min_len=self.min_len, decimals=dec,
                                    moves_at_breaks=moves_at_breaks)
        return out, lift, su


def _full_lines(cl: F64, rows: F64, sx: float, sy: float, extent: float, ext: float,
                poly: _Polyline) -> tuple[F64, float, int, list[F64]]:
    """Whole lines, zig-zag, run past both stock edges (links in air beside the stock);
    also each line's final ``(u, z)`` polyline, ``u`` increasing."""
    if not len(rows):
        return np.zeros((0, 3)), 0.0, 0, []
    z = _raster(cl, rows)
    cols = np.arange(z.shape[1]) * sx
    u_in = np.concatenate([cols[cols < extent], [extent]])
    k = np.minimum(np.searchsorted(cols, u_in, side="right") - 1, len(cols) - 2)
    t = (u_in - cols[k]) / sx
    z = z[:, k] * (1.0 - t) + z[:, k + 1] * t  # the model may be padded past the part
    n_lines, n_pts = z.shape
    u = np.concatenate([[-ext], u_in, [extent + ext]])
    z = np.concatenate([z[:, :1], z, z[:, -1:]], axis=1)
    odd = (np.arange(n_lines) % 2 == 1)[:, None]
    u_all = np.where(odd, u[::-1], u)
    z_all = np.where(odd, z[:, ::-1], z)
    v_all = np.broadcast_to((rows * sy)[:, None], z.shape)
    fixed = np.zeros(z.shape, bool)
    fixed[:, [0, 1, -2, -1]] = True
    # one increasing parameter for the thinning (reversed lines negated, lines apart)
    su = (np.where(odd, -u_all, u_all) + (np.arange(n_lines) * (u[-1] - u[0] + 1.0))[:, None])
    breaks = np.zeros(z.size - 1, bool)
    breaks[n_pts + 1::n_pts + 2] = True  # the links between lines
    pts, lift, _ = poly.points(u_all.ravel(), v_all.ravel(), z_all.ravel(), su.ravel(),
                               fixed.ravel(), breaks)
    # a line keeps its offset through the thinning and the splits; links change it
    x, y = pts[:, 0] - poly.part.x0, pts[:, 1] - poly.part.y0
    ua, va = (x, y) if poly.along_x else (y, x)
    per_line = np.split(np.column_stack([ua, pts[:, 2]]), np.flatnonzero(np.diff(va) != 0) + 1)
    per_line = [q[::-1] if n % 2 else q for n, q in enumerate(per_line)]
    return pts, lift, int(z.size), per_line


def _segments(raw: tuple[F64, F64, F64, NDArray[np.int64]], poly: _Polyline
              ) -> tuple[F64, NDArray[np.int64], float, int]:
    """Line segments (extra lines, region pieces) as one polyline (breaks between them)
    through the thin and lift steps; returns the points and how many belong to each."""
    u, v, z, sizes = raw
    ends = np.cumsum(sizes)
    fixed = np.zeros(len(u), bool)
    fixed[ends - 1] = fixed[ends - sizes] = True
    breaks = np.zeros(len(u) - 1, bool)
    breaks[ends[:-1] - 1] = True
    span = float(u.max() - u.min()) + 1.0
    su = u + np.repeat(np.arange(len(sizes)), sizes) * span
    # each segment is entered on its own: the breaks between them are no moves
    pts, lift, su_kept = poly.points(u, v, z, su, fixed, breaks, moves_at_breaks=False)
    # segment n's parameters lie in [n * span + u.min(), (n + 1) * span + u.min() - 1]: the
    # gaps' middles divide them (``n * span / span`` may round below ``n``: the first point
    # of a segment would count with the one before)
    owner = np.floor((su_kept - u.min() + 0.5) / span).astype(np.int64)
    kept = np.bincount(owner, minlength=len(sizes)).astype(np.int64)
    return pts, kept, lift, len(u)


def _segment_moves(pts: F64, sizes: NDArray[np.int64], entry_z: F64, lift: F64,
                   stay: NDArray[np.bool_], clearance: float) -> Moves:
    """Segments in turn, each reached from the end of the one before: staying down
    (``stay``: a feed move straight to its start), or by a rapid up to ``lift``, across,
    and down to ``entry_z`` above its start, then a plunge-feed move; the first from the
    clearance, and a rapid up to the clearance after the last.

    Parameters
    ----------
    pts : (m, 3) float64
        The segments' points, one after the other.
    sizes : (n,) int64
        Points per segment.
    entry_z, lift : (n,) float64
        Per segment; ``lift[0]`` is not used (the first comes from the clearance).
    stay : (n,) bool
        ``stay[0]`` must be False.
    """
    head = np.where(stay, 0, 3).astype(np.int64)
    head[0] = 2
    per = head + sizes
    per[-1] += 1
    first = np.cumsum(per) - per  # first row of each segment's entry
    n = int(per.sum())
    end = np.empty((n, 3))
    kind = np.full(n, RAPID, np.int8)
    plunge = np.zeros(n, bool)
    body0 = first + head
    body = np.repeat(body0, sizes) + (np.arange(int(sizes.sum()))
                                      - np.repeat(np.cumsum(sizes) - sizes, sizes))
    end[body] = pts
    kind[body] = LINE
    plunge[body0[~stay]] = True
    start = pts[np.cumsum(sizes) - sizes]
    last = pts[np.cumsum(sizes) - 1]
    lifted = np.flatnonzero(~stay)
    lifted = lifted[lifted > 0]
    # lift: up over the previous end, across at the lift height, down above the start
    end[first[lifted]] = np.column_stack([last[lifted - 1, :2], lift[lifted]])
    end[first[lifted] + 1] = np.column_stack([start[lifted, :2], lift[lifted]])
    end[first[lifted] + 2] = np.column_stack([start[lifted, :2], entry_z[lifted]])
    end[0] = [start[0, 0], start[0, 1], clearance]
    end[1] = [start[0, 0], start[0, 1], entry_z[0]]
    end[-1] = [last[-1, 0], last[-1, 1], clearance]
    return Moves(kind, end, np.full((n, 2), np.nan), plunge)


def _orient(pts: F64, sizes: NDArray[np.int64]) -> F64:
    """The segments (``sizes`` points of ``pts`` in turn), each run from the end nearer where
    the one before ended (a straight move sweeps the same volume both ways)."""
    first = np.cumsum(sizes) - sizes
    flip = np.zeros(len(sizes), np.bool_)
    _flips(pts, first, sizes, flip)
    owner = np.repeat(np.arange(len(sizes)), sizes)
    j = np.arange(len(pts)) - first[owner]
    j = np.where(flip[owner], sizes[owner] - 1 - j, j)
    return pts[first[owner] + j]


@njit(cache=True, nogil=True)
def _flips(pts: F64, first: NDArray[np.int64], sizes: NDArray[np.int64],
           flip: NDArray[np.bool_]) -> None:
    """Greedy: segment ``i`` runs backwards when its last point is nearer the end of
    segment ``i - 1`` (as run) than its first point."""
    for i in range(1, len(sizes)):
        a, b = first[i - 1], first[i - 1] + sizes[i - 1] - 1
        e = a if flip[i - 1] else b
        s0, s1 = first[i], first[i] + sizes[i] - 1
        d0 = (pts[s0, 0] - pts[e, 0]) ** 2 + (pts[s0, 1] - pts[e, 1]) ** 2
        d1 = (pts[s1, 0] - pts[e, 0]) ** 2 + (pts[s1, 1] - pts[e, 1]) ** 2
        flip[i] = d1 < d0


def _feed_pairs(pts: F64, groups: list[tuple[F64, NDArray[np.int64]]]) -> tuple[F64, F64]:
    """Start and end points of the feed moves of a polyline and of groups of segments
    (``(points, sizes)``: moves within each segment only)."""
    p0, p1 = [pts[:-1]], [pts[1:]]
    for g, sizes in groups:
        inside = np.ones(max(len(g) - 1, 0), bool)
        inside[(np.cumsum(sizes) - 1)[:-1]] = False  # from one segment's end to the next
        p0.append(g[:-1][inside])
        p1.append(g[1:][inside])
    return np.vstack(p0), np.vstack(p1)


class _Entered:
    """Builds segments entered from above (extra lines, region stretches, scallop lines):
    their points through the thin and lift steps, each run from the end nearer the previous
    segment's end, and the links between them; keeps every segment's points.

    A link stays down (a feed move) where the stock bound over its reach (from the stage's
    whole lines, :func:`~zwcore.toolpath._scan_links.link_heights`) lies under both of its
    ends, else lifts to :data:`ENTRY_GAP` above that bound, crosses and comes down to the
    same gap above the stock bound around the next start, then plunges at the plunge feed;
    of the two the one with the smaller time estimate (feeds and ``rapid_feed``)."""

    def __init__(self, part: ZMap, tool: Tool, cl: F64, sx: float, sy: float, poly: _Polyline,
                 along_x: bool, line_v: F64, per_line: list[F64],
                 grid: tuple[float, float, tuple[int, int]], stock_top: float,
                 clearance: float, decimals: int, cutting: CuttingData, rapid_feed: float,
                 before: F64 | None = None):
        self.part, self.tool, self.cl, self.sx, self.sy, self.poly = part, tool, cl, sx, sy, poly
        self.along_x, self.line_v, self.per_line, self.grid = along_x, line_v, per_line, grid
        self.stock_top, self.clearance, self.decimals = stock_top, clearance, decimals
        self.cutting, self.rapid_feed = cutting, rapid_feed
        du, dv, shape_uv = grid
        self.bound = StockBound(line_v, per_line, du, dv, shape_uv, tool.radius, stock_top,
                                before)
        self.points: list[tuple[F64, NDArray[np.int64]]] = []
        self.max_lift, self.n_raw = 0.0, 0
        self.stays = self.lifts = 0

    def _uv(self, xy: F64) -> F64:
        part = self.part
        return (xy[:, :2] - [part.x0, part.y0]) if self.along_x else (
            xy[:, 1::-1] - [part.y0, part.x0])

    def _up(self, z: F64) -> F64:
        """``z + ENTRY_GAP`` rounded up to the output, at most the clearance."""
        scale = 10.0 ** self.decimals
        return np.minimum(self.clearance, np.ceil((z + ENTRY_GAP) * scale) / scale)

    def __call__(self, off: F64, a: F64, b: F64, fine: bool = False) -> Moves:
        """Segments ``off, a, b``: CL from the stage's grid, or (``fine``) from the node
        drop-cutter every quarter of an input step."""
        part, (du, dv, _), tool = self.part, self.grid, self.tool
        raw = (fine_points(part, tool, off, a, b, self.along_x, 0.25 * min(du, dv))
               if fine else _segment_points(self.cl, off, a, b, self.sx, self.sy))
        seg_pts, sizes, lift, n = _segments(raw, self.poly)
        self.max_lift, self.n_raw = max(self.max_lift, lift), self.n_raw + n
        seg_pts = _orient(seg_pts, sizes)
        self.points.append((seg_pts, sizes))
        first = seg_pts[np.cumsum(sizes) - sizes]
        last = seg_pts[np.cumsum(sizes) - 1]
        uv = self._uv(first)
        entry = self._up(np.maximum(self.bound.heights(uv, uv), first[:, 2]))
        over = self.bound.heights(self._uv(last[:-1]), uv[1:])
        over = np.concatenate([[np.inf], over])
        prev = np.concatenate([first[:1], last[:-1]])
        high = np.maximum(np.maximum(over, prev[:, 2]), first[:, 2])
        up = np.maximum(self._up(high), entry)
        stay = over <= np.minimum(prev[:, 2], first[:, 2])
        # time of each way (min): a feed across against up, across, down and plunge
        cd = self.cutting
        d = first - prev
        t_stay = np.sqrt((d**2).sum(1)) / cd.feed
        t_lift = ((up - prev[:, 2]) + np.hypot(d[:, 0], d[:, 1]) + (up - entry)
                  ) / self.rapid_feed + (entry - first[:, 2]) / cd.plunge_feed
        stay &= t_stay <= t_lift
        stay[0] = False
        self.stays += int(stay.sum())
        self.lifts += int((~stay).sum()) - 1
        return _segment_moves(seg_pts, sizes, entry, up, stay, self.clearance)


def scanline_stage_path(part: ZMap, stage: ScanlineStage, index: int, cutting: CuttingData,
                        cl_heights: CLHeights, *, clearance: float, chord_tolerance: float,
                        stock_top: float, refine_tolerance: float | None = None,
                        model: F64 | None = None, spacing: tuple[float, float] | None = None,
                        region: NDArray[np.bool_] | None = None,
                        scallop_tolerance: float | None = None, decimals: int = 4,
                        rapid_feed: float = DEFAULT_RAPID_FEED,
                        stock_before: F64 | None = None,
                        part_bounds: PartBounds | None = None,
                        cell_bound: bool = False) -> StagePath:
    """Tool path of one scan-line stage.

    Parameters
    ----------
    part : ZMap
        The input z-map (the gouge guarantee is against its nodes).
    stage : ScanlineStage
        Tool, model, spacing, scan lines (whole lines and extra segments).
    index : int
        Stage index (for the program's comments).
    cutting : CuttingData
    cl_heights : CLHeights
        Drop-cutter on the stage model.
    clearance : float
        Safe height, mm.
    chord_tolerance : float
        Thinning tolerance, mm (> 0).
    stock_top : float
        The stock before the program: segments are entered from above the stock, bounded
        by it and by the stage's whole lines (:func:`~zwcore.toolpath._scan_links.link_heights`).
    refine_tolerance : float, optional
        Segments whose gouge against the part exceeds this are split (down to a sixteenth
        of the part's spacing) before the lift; default ``chord_tolerance``. A roughing
        stage may take more: what it leaves is the next stage's stock.
    model, spacing : optional
        Another model to compute the path on (e.g. the part itself, for comparisons);
        default: the stage's.
    region : (my, mx) bool, optional
        Where the stage cuts, on the nodes of the model the path is computed on (e.g. its
        rest regions): only the stretches of lines over it are cut
        (:func:`~zwcore.toolpath._scan_links.region_stretches`); default everywhere.
    rapid_feed : float
        Rapid rate, mm/min: a link between segments stays down or lifts, whichever the
        time estimate favours.
    stock_before : (ny, nx) float64, optional
        An upper bound of the stock before this stage on the part's nodes (the previous
        stage's :attr:`StagePath.stock_after`): links and entries come down to just above
        it instead of the stock top (a rest stage with no whole lines of its own would
        otherwise plunge from the stock top into every stretch). Default: the stock top.
    scallop_tolerance : float, optional
        For a finishing pass on the input's nodes, without a region: the pass's moves are
        swept over the part's nodes and segments added where they leave more than this
        above what its CL allows (:mod:`~zwcore.toolpath._scallop`), up to
        :data:`SCALLOP_ROUNDS` times.
    part_bounds : PartBounds, optional
        The part's block bounds for the gouge measure, shared by a plan's stages (built
        once per part and block size instead of once per stage); default: this stage's.
    cell_bound : bool
        The plan's choice (``ScanlinePlan.cell_bound``): with the default ``cl_heights``,
        small balls take the per-cell drop-cutter bound as the plan's simulation did.

    Returns
    -------
    StagePath
        ``figures``: ``lines`` (cut whole), ``extra_segments`` (the plan's), ``segments``
        (entered from above: extra segments and region stretches), ``scallop_segments``
        (added from the simulated scallop), ``points_before_thinning``, ``points``,
        ``max_lift``, ``links_down`` and ``links_lifted`` (links between segments that
        stay down, or lift to above the stock they pass instead of the clearance).
    """
    tool = stage.tool
    mdl = stage.model if model is None else model
    sx, sy = stage.spacing if spacing is None else spacing
    cl = _stage_cl(part, stage, mdl, sx, sy, cl_heights,
                   whole=scallop_tolerance is not None and region is None,
                   cell_bound=cell_bound)
    # the CL on the part's own nodes (a finishing pass): the scallop pass can compare with it
    on_nodes = (abs(sx - part.dx) <= 1e-9 * part.dx and abs(sy - part.dy) <= 1e-9 * part.dy
                and cl.shape[0] >= part.shape[0] and cl.shape[1] >= part.shape[1])
    cl_nodes = cl  # before any transposition
    if region is not None and region.shape != mdl.shape:
        raise InvalidInputError("region", f"must be a grid of the model's shape {mdl.shape}, "
                                f"got {region.shape}")
    along_x = stage.scan_direction == "x"
    if not along_x:  # work as if lines ran along x
        cl, sx, sy = cl.T, sy, sx
        region = None if region is None else region.T
    ny, nx = part.shape
    du, dv, shape_uv = ((part.dx, part.dy, (nx, ny)) if along_x else
                        (part.dy, part.dx, (ny, nx)))
    extent = (shape_uv[0] - 1) * du
    lines = stage.lines
    full = (lines.start <= 1e-9) & (lines.stop >= extent - 1e-9)
    seg_off, seg_a, seg_b = lines.offset[~full], lines.start[~full], lines.stop[~full]
    if region is not None:  # whole lines inside the region zig-zag, the rest are segments
        li, a, b = region_stretches(region, lines.offset, lines.start, lines.stop, sx, sy)
        zig = full[li] & (a <= lines.start[li] + 1e-9) & (b >= lines.stop[li] - 1e-9)
        full = np.zeros(len(full), bool)
        full[li[zig]] = True
        seg_off, seg_a, seg_b = lines.offset[li[~zig]], a[~zig], b[~zig]
    refine = chord_tolerance if refine_tolerance is None else refine_tolerance
    min_len = min(part.dx, part.dy) / 16.0 if refine_tolerance is None else 0.25 * min(sx, sy)
    # the gouge measure's coarse look: blocks of a quarter of the model's spacing
    block = max(BLOCK_MIN, round(0.25 * min(sx / du, sy / dv)))
    poly = _Polyline(part, tool, along_x, chord_tolerance, decimals, refine, min_len, block,
                     part_bounds)
    ext = tool.radius + max(part.dx, part.dy)
    pts, max_lift, n_raw, per_line = _full_lines(cl, lines.offset[full] / sy, sx, sy, extent,
                                                 ext, poly)
    parts = [Moves.lines(pts[:1], kind=RAPID), Moves.lines(pts[1:])] if len(pts) else []
    before = None if stock_before is None else (stock_before if along_x else stock_before.T)
    entered = _Entered(part, tool, cl, sx, sy, poly, along_x, lines.offset[full], per_line,
                       (du, dv, shape_uv), stock_top, clearance, decimals, cutting,
                       rapid_feed, before)
    seg_off, seg_a, seg_b = merge_stretches(seg_off, seg_a, seg_b)
    if len(seg_off):
        if len(pts):  # up from the last whole line's exit
            parts.append(Moves.lines(np.array([[pts[-1, 0], pts[-1, 1], clearance]]),
                                     kind=RAPID))
        parts.append(entered(seg_off, seg_a, seg_b))
    n_scallop = 0
    if scallop_tolerance is not None and region is None and on_nodes:
        env = np.full(part.shape, np.inf)
        node_cl = np.ascontiguousarray(cl_nodes[:part.shape[0], :part.shape[1]])
        best = finishing_closing(part, tool, node_cl)
        p0, p1 = _feed_pairs(pts, entered.points)
        for _ in range(SCALLOP_ROUNDS):
            new = scallop_segments(part, tool, env, p0, p1, best, node_cl, scallop_tolerance,
                                   along_x)
            if not len(new[0]):
                break
            seen = len(entered.points)
            if not seen and len(pts):
                parts.append(Moves.lines(np.array([[pts[-1, 0], pts[-1, 1], clearance]]),
                                         kind=RAPID))
            parts.append(entered(*new, fine=True))
            n_scallop += len(new[0])
            p0, p1 = _feed_pairs(np.zeros((0, 3)), entered.points[seen:])
    max_lift, n_raw = max(max_lift, entered.max_lift), n_raw + entered.n_raw
    moves = Moves.concat(parts)
    start = np.array([moves.end[0, 0], moves.end[0, 1], clearance]) if len(moves) else \
        np.array([part.x0, part.y0, clearance])
    figures = {"lines": float(full.sum()), "extra_segments": float(stage.extra_segments),
               "segments": float(len(seg_off)), "scallop_segments": float(n_scallop),
               "points_before_thinning": float(n_raw),
               "points": float(len(moves)), "max_lift": max_lift,
               "links_down": float(entered.stays), "links_lifted": float(entered.lifts)}
    after = entered.bound.grid if along_x else entered.bound.grid.T
    return StagePath(index, "scanline", tool, cutting, start, moves, figures, after)
