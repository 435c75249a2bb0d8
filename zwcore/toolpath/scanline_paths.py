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
from zwcore.scanline.results import ScanlineStage
from zwcore.toolpath._polyline import lift_out_of_part, refine_against_part, thin
from zwcore.toolpath.program import RAPID, CuttingData, Moves, StagePath
from zwcore.toolpath.sweep import GridFrame, sweep_moves

__all__ = ["CLHeights", "scanline_stage_path"]

F64 = NDArray[np.float64]

#: ``cl_heights(model, tool)``: tip heights of ``tool`` dropped onto every node of ``model``
#: (bilinear surface), an ``(my, mx)`` array, never below the true drop-cutter height.
CLHeights = Callable[[ZMap, Tool], F64]


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

    def __init__(self, part: ZMap, tool: Tool, along_x: bool, chord: float, decimals: int):
        self.part, self.tool, self.along_x = part, tool, along_x
        self.chord, self.decimals = chord, decimals

    def points(self, u: F64, v: F64, z: F64, su: F64, fixed: NDArray[np.bool_],
               breaks: NDArray[np.bool_]) -> tuple[F64, float]:
        part, dec = self.part, self.decimals
        x, y = (u, v) if self.along_x else (v, u)
        pts = np.column_stack([np.round(part.x0 + x, dec), np.round(part.y0 + y, dec), z])
        pts, su, fx = refine_against_part(pts, su, fixed, breaks, part, self.tool, self.chord,
                                          min(part.dx, part.dy) / 16.0)
        pts[:, :2] = np.round(pts[:, :2], dec)
        keep = thin(su, pts[:, 2], fx, self.chord)
        return lift_out_of_part(pts[keep], part, self.tool, decimals=dec)


def _full_lines(cl: F64, rows: F64, sx: float, sy: float, ext: float, poly: _Polyline
                ) -> tuple[F64, float, int]:
    """Whole lines, zig-zag, run past both stock edges (links in air beside the stock)."""
    z = _raster(cl, rows)
    n_lines, n_pts = z.shape
    u = np.concatenate([[-ext], np.arange(n_pts) * sx, [(n_pts - 1) * sx + ext]])
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
    pts, lift = poly.points(u_all.ravel(), v_all.ravel(), z_all.ravel(), su.ravel(),
                            fixed.ravel(), breaks)
    return pts, lift, int(z.size)


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
                        stock: F64, model: F64 | None = None,
                        spacing: tuple[float, float] | None = None,
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
    width = (cl.shape[1] - 1) * sx
    lines = stage.lines
    full = (lines.start <= 1e-9) & (lines.stop >= width - 1e-9)
    poly = _Polyline(part, tool, along_x, chord_tolerance, decimals)
    ext = tool.radius + max(part.dx, part.dy)
    pts, max_lift, n_raw = _full_lines(cl, lines.offset[full] / sy, sx, sy, ext, poly)
    frame = GridFrame(part.x0, part.y0, part.dx, part.dy, part.shape)
    ball = tool.kind == "ball"
    parts = [Moves.lines(pts[:1], kind=RAPID), Moves.lines(pts[1:])]
    sweep_moves(frame, pts[:-1], pts[1:], tool.radius, ball, stock)
    extra = np.flatnonzero(~full)
    for j in extra:
        row = _raster(cl, np.array([lines.offset[j] / sy]))[0]
        u, z = _along(row, sx, float(lines.start[j]), float(lines.stop[j]))
        v = np.full(len(u), lines.offset[j])
        fixed = np.zeros(len(u), bool)
        seg, lift = poly.points(u, v, z, u.copy(), fixed, np.zeros(len(u) - 1, bool))
        max_lift = max(max_lift, lift)
        n_raw += len(u)
        top = max(_entry_height(stock, part, seg[0, :2], tool.radius), seg[0, 2])
        air = min(clearance, np.ceil((top + 0.5) * 10 ** decimals) / 10 ** decimals)
        entry = np.array([[seg[0, 0], seg[0, 1], clearance], [seg[0, 0], seg[0, 1], air]])
        parts += [Moves.lines(entry, kind=RAPID), Moves.lines(seg, plunge=np.arange(len(seg)) == 0),
                  Moves.lines(np.array([[seg[-1, 0], seg[-1, 1], clearance]]), kind=RAPID)]
        sweep_moves(frame, np.vstack([seg[:1], seg[:-1]]), seg, tool.radius, ball, stock)
    start = np.array([pts[0, 0], pts[0, 1], clearance])
    moves = Moves.concat(parts)
    figures = {"lines": float(full.sum()), "extra_segments": float(len(extra)),
               "points_before_thinning": float(n_raw), "points": float(len(moves)),
               "max_lift": max_lift}
    return StagePath(index, "scanline", tool, cutting, start, moves, figures)
