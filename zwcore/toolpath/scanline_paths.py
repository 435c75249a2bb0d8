"""Scan-line tool paths of ball-end-mill stages (design section 3, issue 12).

A stage's raster runs along its scan direction, one line per grid line of the stage's level
(and evenly placed extra lines where its pick-feed is below the level's spacing). Tip
heights come from a drop-cutter against the stage's own model at the stage's own
resolution (``cl_heights``, e.g. :func:`zwcore.sim.drop_cutter`): a coarse stage is a few
hundred points. Each line is thinned one-sidedly (a chord never passes below a dropped
point, and at most ``chord_tolerance`` above), then every move is swept exactly against
the part's nodes at the input resolution and lifted out of any gouge
(:func:`~zwcore.toolpath._polyline.lift_out_of_part`): whatever the model's resolution, no
move reaches below the part. Lines run past the stock edge by the tool radius so entry,
exit and the zig-zag links between neighbouring lines are in air beside the stock.
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

__all__ = ["CLHeights", "scanline_stage_path"]

F64 = NDArray[np.float64]

#: ``cl_heights(model, tool)``: tip heights of ``tool`` dropped onto every node of ``model``
#: (bilinear surface), an ``(my, mx)`` array, never below the true drop-cutter height.
CLHeights = Callable[[ZMap, Tool], F64]


def _line_positions(n_rows: int, spacing: float, pick_feed: float) -> F64:
    """Row coordinates (fractional) of the scan lines: every grid line, and ``m - 1``
    evenly placed lines inside each strip where ``pick_feed`` is below the spacing."""
    m = max(1, int(np.ceil(spacing / pick_feed - 1e-9)))
    return np.arange((n_rows - 1) * m + 1) / m


def _raster(cl: F64, rows: F64) -> F64:
    """CL heights on fractional rows (linear between the grid rows; the lift makes it safe)."""
    r0 = np.clip(np.floor(rows).astype(np.int64), 0, cl.shape[0] - 1)
    r1 = np.minimum(r0 + 1, cl.shape[0] - 1)
    t = (rows - r0)[:, None]
    return (1.0 - t) * cl[r0] + t * cl[r1]


def scanline_stage_path(part: ZMap, stage: ScanlineStage, index: int, cutting: CuttingData,
                        cl_heights: CLHeights, *, clearance: float, chord_tolerance: float,
                        model: F64 | None = None, spacing: tuple[float, float] | None = None,
                        decimals: int = 4) -> StagePath:
    """Tool path of one scan-line stage.

    Parameters
    ----------
    part : ZMap
        The input z-map (the gouge guarantee is against its nodes).
    stage : ScanlineStage
        Tool, model, spacing, pick-feed and scan direction.
    index : int
        Stage index (for the program's comments).
    cutting : CuttingData
    cl_heights : CLHeights
        Drop-cutter on the stage model.
    clearance : float
        Safe height, mm.
    chord_tolerance : float
        Thinning tolerance, mm (> 0).
    model, spacing : optional
        Another model to compute the path on (e.g. the part itself, for comparisons);
        default: the stage's.

    Returns
    -------
    StagePath
        ``figures``: ``lines``, ``points_before_thinning``, ``points``, ``max_lift``.
    """
    tool = stage.tool
    mdl = stage.model if model is None else model
    sx, sy = stage.spacing if spacing is None else spacing
    cl = cl_heights(ZMap(mdl, part.x0, part.y0, sx, sy), tool)
    along_x = stage.scan_direction == "x"
    if not along_x:  # work as if lines ran along x
        cl, sx, sy = cl.T, sy, sx
    rows = _line_positions(cl.shape[0], sy, min(stage.pick_feed, sy))
    z = _raster(cl, rows)  # (lines, points)
    n_lines, n_pts = z.shape
    ext = tool.radius + max(part.dx, part.dy)
    u = np.concatenate([[-ext], np.arange(n_pts) * sx, [(n_pts - 1) * sx + ext]])
    z = np.concatenate([z[:, :1], z, z[:, -1:]], axis=1)
    u_all = np.where((np.arange(n_lines) % 2 == 1)[:, None], u[::-1], u)
    z_all = np.where((np.arange(n_lines) % 2 == 1)[:, None], z[:, ::-1], z)
    v_all = np.broadcast_to((rows * sy)[:, None], z.shape)
    fixed = np.zeros(z.shape, bool)
    fixed[:, [0, 1, -2, -1]] = True
    # one flat sequence; u increases along every line (reversed lines negated)
    sign = np.where((np.arange(n_lines) % 2 == 1)[:, None], -1.0, 1.0)
    su = (u_all * sign + (np.arange(n_lines) * (u[-1] - u[0] + 1.0))[:, None]).ravel()
    x, y = (u_all, v_all) if along_x else (v_all, u_all)
    pts = np.column_stack([np.round(part.x0 + x.ravel(), decimals),
                           np.round(part.y0 + y.ravel(), decimals), z_all.ravel()])
    breaks = np.zeros(len(pts) - 1, bool)
    breaks[n_pts + 1::n_pts + 2] = True  # links between lines
    pts, su, fx = refine_against_part(pts, su, fixed.ravel(), breaks, part, tool,
                                         chord_tolerance, min(part.dx, part.dy) / 16.0)
    pts[:, :2] = np.round(pts[:, :2], decimals)
    keep = thin(su, pts[:, 2], fx, chord_tolerance)
    pts, max_lift = lift_out_of_part(pts[keep], part, tool, decimals=decimals)
    start = np.array([pts[0, 0], pts[0, 1], clearance])
    moves = Moves.concat([Moves.lines(pts[:1], kind=RAPID), Moves.lines(pts[1:])])
    figures = {"lines": float(n_lines), "points_before_thinning": float(z.size),
               "points": float(len(pts)), "max_lift": max_lift}
    return StagePath(index, "scanline", tool, cutting, start, moves, figures)
