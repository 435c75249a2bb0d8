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

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.scanline.results import ScanLines, ScanlineStage
from zwcore.sim import drop_cutter
from zwcore.toolpath._polyline import lift_out_of_part, refine_against_part, thin
from zwcore.toolpath.program import RAPID, CuttingData, Moves, StagePath
from zwcore.toolpath.sweep import GridFrame, sweep_moves

__all__ = ["CLHeights", "scanline_stage_path", "sim_cl_heights"]

F64 = NDArray[np.float64]

#: ``cl_heights(model, tool)``: tip heights of ``tool`` dropped onto every node of ``model``
#: (bilinear surface), an ``(my, mx)`` array, never below the true drop-cutter height.
CLHeights = Callable[[ZMap, Tool], F64]


def sim_cl_heights(model: ZMap, tool: Tool) -> F64:
    """The default :data:`CLHeights`: :func:`zwcore.sim.drop_cutter` on the bilinear model
    (never below the true drop-cutter height)."""
    return drop_cutter(model, tool, "bilinear")


def _raster(cl: F64, rows: F64) -> F64:
    """CL heights on fractional rows (linear between the grid rows; the lift makes it safe)."""
    r0 = np.clip(np.floor(rows).astype(np.int64), 0, cl.shape[0] - 1)
    r1 = np.minimum(r0 + 1, cl.shape[0] - 1)
    t = (rows - r0)[:, None]
    return (1.0 - t) * cl[r0] + t * cl[r1]


def _along(line: F64, sx: float, start: float, stop: float) -> tuple[F64, F64]:
    """Points of one segment along a CL row: model columns inside, ends interpolated."""
    cols = np.arange(len(line)) * sx
    inner = cols[(cols > start) & (cols < stop)]
    u = np.concatenate([[start], inner, [stop]])
    return u, np.interp(u, cols, line)


class _Polyline:
    """Builds a path (xy rounded to the output) through the refine, thin and lift steps."""

    def __init__(self, part: ZMap, tool: Tool, along_x: bool, chord: float, decimals: int,
                 refine: float, min_len: float):
        self.part, self.tool, self.along_x = part, tool, along_x
        self.chord, self.decimals = chord, decimals
        self.refine, self.min_len = refine, min_len

    def points(self, u: F64, v: F64, z: F64, su: F64, fixed: NDArray[np.bool_],
               breaks: NDArray[np.bool_]) -> tuple[F64, float, F64]:
        part, dec = self.part, self.decimals
        x, y = (u, v) if self.along_x else (v, u)
        pts = np.column_stack([np.round(part.x0 + x, dec), np.round(part.y0 + y, dec), z])
        pts, su, fx = refine_against_part(pts, su, fixed, breaks, part, self.tool, self.refine,
                                          self.min_len)
        pts[:, :2] = np.round(pts[:, :2], dec)
        keep = thin(su, pts[:, 2], fx, self.chord)
        out, lift = lift_out_of_part(pts[keep], part, self.tool, decimals=dec)
        return out, lift, su[keep]


def _full_lines(cl: F64, rows: F64, sx: float, sy: float, extent: float, ext: float,
                poly: _Polyline) -> tuple[F64, float, int]:
    """Whole lines, zig-zag, run past both stock edges (links in air beside the stock)."""
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
    return pts, lift, int(z.size)


def _extra_segments(cl: F64, lines: ScanLines, extra: NDArray[np.intp], sx: float, sy: float,
                    poly: _Polyline) -> tuple[list[F64], float, int]:
    """The extra segments as one polyline (breaks between them) through the refine, thin
    and lift steps, then split again."""
    rows = _raster(cl, lines.offset[extra] / sy)
    us, zs, vs = [], [], []
    for n, j in enumerate(extra):
        u, z = _along(rows[n], sx, float(lines.start[j]), float(lines.stop[j]))
        us.append(u)
        zs.append(z)
        vs.append(np.full(len(u), lines.offset[j]))
    sizes = np.array([len(u) for u in us])
    u, z, v = np.concatenate(us), np.concatenate(zs), np.concatenate(vs)
    ends = np.cumsum(sizes)
    fixed = np.zeros(len(u), bool)
    fixed[ends - 1] = fixed[ends - sizes] = True
    breaks = np.zeros(len(u) - 1, bool)
    breaks[ends[:-1] - 1] = True
    span = float(u.max() - u.min()) + 1.0
    su = u + np.repeat(np.arange(len(sizes)), sizes) * span
    pts, lift, su_kept = poly.points(u, v, z, su, fixed, breaks)
    # segment n's parameters lie in [n * span + u.min(), (n + 1) * span + u.min())
    owner = np.floor((su_kept - u.min()) / span).astype(np.int64)
    cuts = np.searchsorted(owner, np.arange(1, len(sizes)))
    return np.split(pts, cuts), lift, len(u)


def _entry_height(stock: F64, part: ZMap, xy: F64, radius: float) -> float:
    """Highest stock within the tool's reach of ``xy``: a rapid down to above it is in air."""
    k0 = max(0, int(np.floor((xy[0] - radius - part.x0) / part.dx)))
    k1 = min(part.shape[1], int(np.ceil((xy[0] + radius - part.x0) / part.dx)) + 1)
    i0 = max(0, int(np.floor((xy[1] - radius - part.y0) / part.dy)))
    i1 = min(part.shape[0], int(np.ceil((xy[1] + radius - part.y0) / part.dy)) + 1)
    window = stock[i0:i1, k0:k1]
    return float(window.max()) if window.size else -np.inf


def scanline_stage_path(part: ZMap, stage: ScanlineStage, index: int, cutting: CuttingData,
                        cl_heights: CLHeights, *, clearance: float, chord_tolerance: float,
                        stock: F64, refine_tolerance: float | None = None,
                        model: F64 | None = None, spacing: tuple[float, float] | None = None,
                        decimals: int = 4) -> StagePath:
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
    stock : (ny, nx) float64
        The stock before the stage at the part's nodes; lowered in place by the stage's
        moves (extra segments are entered from above the stock they meet).
    refine_tolerance : float, optional
        Segments whose gouge against the part exceeds this are split (down to a sixteenth
        of the part's spacing) before the lift; default ``chord_tolerance``. A roughing
        stage may take more: what it leaves is the next stage's stock.
    model, spacing : optional
        Another model to compute the path on (e.g. the part itself, for comparisons);
        default: the stage's.

    Returns
    -------
    StagePath
        ``figures``: ``lines``, ``extra_segments``, ``points_before_thinning``,
        ``points``, ``max_lift``.
    """
    tool = stage.tool
    mdl = stage.model if model is None else model
    sx, sy = stage.spacing if spacing is None else spacing
    cl = cl_heights(ZMap(mdl, part.x0, part.y0, sx, sy), tool)
    along_x = stage.scan_direction == "x"
    if not along_x:  # work as if lines ran along x
        cl, sx, sy = cl.T, sy, sx
    ny, nx = part.shape
    extent = (nx - 1) * part.dx if along_x else (ny - 1) * part.dy
    lines = stage.lines
    full = (lines.start <= 1e-9) & (lines.stop >= extent - 1e-9)
    refine = chord_tolerance if refine_tolerance is None else refine_tolerance
    min_len = min(part.dx, part.dy) / 16.0 if refine_tolerance is None else 0.25 * min(sx, sy)
    poly = _Polyline(part, tool, along_x, chord_tolerance, decimals, refine, min_len)
    ext = tool.radius + max(part.dx, part.dy)
    pts, max_lift, n_raw = _full_lines(cl, lines.offset[full] / sy, sx, sy, extent, ext, poly)
    frame = GridFrame(part.x0, part.y0, part.dx, part.dy, part.shape)
    ball = tool.kind == "ball"
    parts = [Moves.lines(pts[:1], kind=RAPID), Moves.lines(pts[1:])]
    sweep_moves(frame, pts[:-1], pts[1:], tool.radius, ball, stock)
    extra = np.flatnonzero(~full)
    if len(extra):
        segs, lift, n = _extra_segments(cl, lines, extra, sx, sy, poly)
        max_lift, n_raw = max(max_lift, lift), n_raw + n
        # entered from above the stock the whole lines left (later segments only lower it)
        scale = 10.0 ** decimals
        # up from the last whole line's exit, then from segment to segment at the clearance
        parts.append(Moves.lines(np.array([[pts[-1, 0], pts[-1, 1], clearance]]), kind=RAPID))
        for seg in segs:
            top = max(_entry_height(stock, part, seg[0, :2], tool.radius), seg[0, 2])
            air = min(clearance, np.ceil((top + 0.5) * scale) / scale)
            entry = np.array([[seg[0, 0], seg[0, 1], clearance], [seg[0, 0], seg[0, 1], air]])
            parts += [Moves.lines(entry, kind=RAPID),
                      Moves.lines(seg, plunge=np.arange(len(seg)) == 0),
                      Moves.lines(np.array([[seg[-1, 0], seg[-1, 1], clearance]]), kind=RAPID)]
        cut = np.vstack([np.vstack([g[:1], g[:-1]]) for g in segs])
        sweep_moves(frame, cut, np.vstack(segs), tool.radius, ball, stock)
    start = np.array([pts[0, 0], pts[0, 1], clearance])
    moves = Moves.concat(parts)
    figures = {"lines": float(full.sum()), "extra_segments": float(len(extra)),
               "points_before_thinning": float(n_raw), "points": float(len(moves)),
               "max_lift": max_lift}
    return StagePath(index, "scanline", tool, cutting, start, moves, figures)
