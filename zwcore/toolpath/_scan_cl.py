"""CL heights of a scan-line stage on its model (issue 12): the drop-cutter on the rows its
lines read, a depth pass's plateaus at their own heights.

Part of :mod:`zwcore.toolpath.scanline_paths` (which re-exports :func:`sim_cl_heights`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.scanline.results import ScanlineStage
from zwcore.sim import drop_cutter
from zwcore.sim.cutting import PRUNE_FOOTPRINT, footprint

F64 = NDArray[np.float64]

#: ``cl_heights(model, tool)``: tip heights of ``tool`` dropped onto every node of ``model``
#: (bilinear surface), an ``(my, mx)`` array, never below the true drop-cutter height.
CLHeights = Callable[[ZMap, Tool], F64]


def sim_cl_heights(model: ZMap, tool: Tool, rows: NDArray[np.integer] | None = None,
                   cell_bound: bool = False) -> F64:
    """The default :data:`CLHeights`: :func:`zwcore.sim.drop_cutter` on the bilinear model
    (never below the true drop-cutter height), by branch and bound for large tools
    (``method="auto"``: a Ø20 ball at the input's 0.1 mm spans 43,000 nodes); with
    ``rows``, a large tool's CL on those rows only (the others may be NaN). ``cell_bound``:
    the plan's choice of the per-cell bound (``ScanlinePlan.cell_bound``: the same CL as
    its simulation)."""
    return drop_cutter(model, tool, "bilinear", method="auto", rows=rows,
                       cell_bound=cell_bound)


def _line_rows(offset: F64, spacing: float, n: int) -> NDArray[np.int64]:
    """The model rows (or columns) that lines at ``offset`` (mm) read: the one each lies on
    or the two it lies between."""
    f = offset / spacing
    lo = np.clip(np.floor(f).astype(np.int64), 0, n - 1)
    hi = np.where(f > lo, np.minimum(lo + 1, n - 1), lo)
    return np.unique(np.concatenate([lo, hi]))


def _stage_cl(part: ZMap, stage: ScanlineStage, mdl: F64, sx: float, sy: float,
              cl_heights: CLHeights, whole: bool, cell_bound: bool = False) -> F64:
    """The stage's CL grid on its model, ``(my, mx)``. With the default drop-cutter, only the
    rows (a pass along x) or columns (along y, on the transposed model) the stage's lines
    read are computed (the pruned method's values there are those of the whole grid; the
    others are NaN and never read), and of those only the ones a plateau does not settle
    (:func:`_plateau_cl`); ``whole``: every node (the scallop pass compares with the CL on
    all of them)."""
    if cl_heights is not sim_cl_heights:
        return cl_heights(ZMap(mdl, part.x0, part.y0, sx, sy), stage.tool)
    if whole or not len(stage.lines.offset):
        return sim_cl_heights(ZMap(mdl, part.x0, part.y0, sx, sy), stage.tool,
                              cell_bound=cell_bound)
    if stage.scan_direction == "x":
        rows = _line_rows(stage.lines.offset, sy, mdl.shape[0])
        return _plateau_cl(ZMap(mdl, part.x0, part.y0, sx, sy), stage.tool, rows, cell_bound)
    cols = _line_rows(stage.lines.offset, sx, mdl.shape[1])
    # the ball and the pruned bounds are symmetric in x and y: the transposed model's rows
    return _plateau_cl(ZMap(np.ascontiguousarray(mdl.T), part.y0, part.x0, sy, sx),
                       stage.tool, cols, cell_bound).T


def _plateau_cl(model: ZMap, tool: Tool, rows: NDArray[np.int64],
                cell_bound: bool = False) -> F64:
    """:func:`sim_cl_heights` on ``rows``, except at the nodes no node within the tool's
    reach rises above (a depth pass's model is flat wherever the part lies below it): the
    tip centred there meets the surface at the node itself, and nothing higher within the
    radius (the bilinear surface under the ball lies below the corners of its cells, all
    within ``ceil(R / spacing) + 1`` nodes), so the drop-cutter height is the node's own.
    The others are computed on the part of the model within reach of them (the
    drop-cutter at a node reads no node further away)."""
    wy, wx = footprint(tool, model.dx, model.dy)  # ceil(R / spacing) + 1 each way
    if (2 * wy + 1) * (2 * wx + 1) <= PRUNE_FOOTPRINT:
        # small tools: every row at once anyway
        return sim_cl_heights(model, tool, rows, cell_bound)
    z = model.z
    sub = z[rows]
    flat = sub >= ndimage.maximum_filter(z, size=(2 * wy + 1, 2 * wx + 1),
                                         mode="nearest")[rows]
    need_r, need_c = np.nonzero(~flat)
    out = np.full(z.shape, np.nan)
    out[rows] = sub
    if len(need_r):
        r0, r1 = max(0, int(rows[need_r.min()]) - wy), min(z.shape[0], int(rows[need_r.max()])
                                                             + wy + 1)
        c0, c1 = max(0, int(need_c.min()) - wx), min(z.shape[1], int(need_c.max()) + wx + 1)
        crop = ZMap(np.ascontiguousarray(z[r0:r1, c0:c1]), model.x0 + c0 * model.dx,
                    model.y0 + r0 * model.dy, model.dx, model.dy)
        need = np.unique(rows[need_r])
        cl = sim_cl_heights(crop, tool, need - r0, cell_bound)
        rr, cc = rows[need_r], need_c
        out[rr, cc] = cl[rr - r0, cc - c0]
    return out
