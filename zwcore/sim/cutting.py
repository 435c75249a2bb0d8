"""Drop-cutter CL surfaces and machined envelopes of ball and flat end mills on z-maps.

A tool position is a node ``c`` of the part's grid with the tool tip at height
``CL[c]``. The drop-cutter height is the lowest tip height at which the tool does
not pass below the part (a grey dilation of the surface by the tool's profile);
the envelope is what tools at all positions leave (a grey erosion of the CL
surface by the same profile); the two together are a morphological closing.

Guarantees (see ``docs/simulation.md``): the CL is never below the true
drop-cutter height over the part's continuous surface (``bilinear`` between nodes
or ``cell`` flat squares), so a tool at ``CL`` never cuts into the part; the
envelope at each node is never below what the tools at the CL positions leave
there. Both are rounded only upward (at most about 2e-5 mm).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from zwcore.errors import InvalidInputError, LimitExceededError
from zwcore.grid.tools import TOOL_KINDS, Tool
from zwcore.grid.zmap import INTERPOLATIONS, Interpolation, ZMap
from zwcore.sim._cells import TIGHT_MAX_CELLS, cells_within, tighten
from zwcore.sim._drop_bb import drop_cutter_pruned
from zwcore.sim._morph import dilate, erode
from zwcore.sim._profiles import drop_profile, envelope_profile, footprint

__all__ = ["MAX_FOOTPRINT", "cell_bound_wanted", "closing", "coarse_grid", "drop_cutter",
           "envelope", "simulation_work", "takes_cell_bound"]

F64 = NDArray[np.float64]

#: With ``method="auto"``, elements of more nodes than this go to the branch and bound
#: (:mod:`zwcore.sim._drop_bb`), smaller ones to the dilation.
PRUNE_FOOTPRINT = 8192
#: Largest structuring element (nodes) a simulation accepts: about a Ø28 ball at 0.02 mm
#: (its profile takes some hundred MB to build).
MAX_FOOTPRINT = 2_000_000


def simulation_work(shape: tuple[int, int], tool: Tool, dx: float, dy: float) -> int:
    """Node-offset pairs a drop-cutter run visits: ``cells * element nodes``, the cost
    model a caller bounds (the run makes about 3/4 of a vector pass per pair / cells)."""
    A, B = footprint(tool, dx, dy)
    return shape[0] * shape[1] * (2 * A + 1) * (2 * B + 1)


def _check(tool: Tool, dx: float, dy: float, interpolation: str) -> None:
    if tool.kind not in TOOL_KINDS:
        raise InvalidInputError("tool.kind", f"must be one of {list(TOOL_KINDS)}, "
                                f"got {tool.kind!r}")
    if not (np.isfinite(tool.diameter) and tool.diameter > 0):
        raise InvalidInputError("tool.diameter", f"must be finite and > 0, got {tool.diameter!r}")
    if interpolation not in INTERPOLATIONS:
        raise InvalidInputError("interpolation", f"must be one of {list(INTERPOLATIONS)}, "
                                f"got {interpolation!r}")
    A, B = footprint(tool, dx, dy)
    if (2 * A + 1) * (2 * B + 1) > MAX_FOOTPRINT:
        raise LimitExceededError("tool.diameter", f"a Ø{tool.diameter:g} tool on a {dx:g} x "
                                 f"{dy:g} mm grid spans {(2 * A + 1) * (2 * B + 1)} nodes, "
                                 f"more than {MAX_FOOTPRINT}")


def drop_cutter(part: ZMap, tool: Tool, interpolation: Interpolation = "bilinear",
                method: str = "dilation", rows: NDArray[np.integer] | None = None,
                threads: int | None = None, cell_bound: bool = False,
                where: NDArray[np.bool_] | None = None) -> F64:
    """Drop-cutter CL surface: the lowest tip height at each node that clears the part.

    Parameters
    ----------
    part : ZMap
        The surface, ``(ny, nx)`` nodes.
    tool : Tool
        A ball (``kind="ball"``) or flat (``"flat"``) end mill of radius ``diameter / 2``.
    interpolation : {"bilinear", "cell"}
        The surface's meaning between nodes.
    method : {"dilation", "pruned", "auto"}
        ``dilation``: every offset of the element at every node (vector passes, float32
        where the rounding bound allows); ``pruned`` (``bilinear`` only): the same
        structuring functions by branch and bound over tiles of offsets in float64
        (:mod:`zwcore.sim._drop_bb`; never below the exact dilation, above it by a float64
        rounding bound, so it may lie up to the dilation's float32 rounding, about
        2e-5 mm, under the ``dilation`` result); ``auto``: ``pruned`` for ``bilinear``
        elements of more than :data:`PRUNE_FOOTPRINT` nodes (a Ø20 ball at 0.1 mm: about
        1/10 of the time), else ``dilation``.
    rows : (m,) int, optional
        Rows that are needed (e.g. a raster's lines): the ``pruned`` method computes only
        these (the same values as in the whole grid) and leaves the others NaN; the
        ``dilation`` method computes every row whatever ``rows`` says.
    threads : int, optional
        Threads of the ``pruned`` method (default: up to four) and of the dilation
        (default: two), as the cores this process may use allow; a caller that is itself
        one of several threads asks for 1.
    cell_bound : bool
        A ball's ``bilinear`` CL lowered to the per-cell bound of
        :mod:`zwcore.sim._cells` (the ball's curvature under each cell; balls of at most
        :data:`~zwcore.sim._cells.TIGHT_MAX_CELLS` cells, :func:`takes_cell_bound`):
        :func:`coarse_grid` says where a plan wants it.
    where : (ny, nx) bool, optional
        With ``cell_bound``: the nodes it is computed on (default all; the others keep
        the plane bound).

    Returns
    -------
    cl : (ny, nx) float64
        Tip height of the tool centred on each node. Never below the true
        drop-cutter height over the continuous surface (beyond the grid there is
        no surface); exact for ``cell``; for ``bilinear`` above it by at most the
        gap between ``h`` and its tangent planes over one cell (about
        ``cell_diagonal² / (8 R cos³θ)`` on a slope θ, more where the ball's rim
        meets a wall) and the float32 rounding bound.
    """
    _check(tool, part.dx, part.dy, interpolation)
    if method not in ("dilation", "pruned", "auto"):
        raise InvalidInputError("method", f"must be dilation, pruned or auto, got {method!r}")
    if method != "dilation" and interpolation == "bilinear":
        A, B = footprint(tool, part.dx, part.dy)
        if method == "pruned" or (2 * A + 1) * (2 * B + 1) > PRUNE_FOOTPRINT:
            cl = drop_cutter_pruned(part, tool, rows, threads)
            return _tightened(part, tool, cl, rows, threads, cell_bound, where)
    cl = dilate(part.z, drop_profile(tool, part.dx, part.dy, interpolation), threads)
    if interpolation != "bilinear":
        return cl
    return _tightened(part, tool, cl, rows, threads, cell_bound, where)


def takes_cell_bound(tool: Tool, dx: float, dy: float) -> bool:
    """Whether ``cell_bound`` changes a tool's CL on a ``dx`` x ``dy`` grid: a ball whose
    disc covers at most :data:`~zwcore.sim._cells.TIGHT_MAX_CELLS` cells."""
    return tool.kind == "ball" and cells_within(tool.radius, dx, dy) <= TIGHT_MAX_CELLS


def cell_bound_wanted(tool: Tool, dx: float, dy: float, tolerance: float) -> bool:
    """Whether the planes' gap of a ball inside a cell of a ``dx`` x ``dy`` grid,
    ``(dx² + dy²) / 8R``, exceeds ``tolerance`` (a plan's scallop tolerance: the plane
    bound alone would leave more than the plan may, so the ball would finish nothing),
    for a ball that :func:`takes_cell_bound`."""
    return (takes_cell_bound(tool, dx, dy)
            and (dx * dx + dy * dy) / (8.0 * tool.radius) > tolerance)


def coarse_grid(balls: Sequence[Tool], dx: float, dy: float, tolerance: float) -> bool:
    """A plan's choice of ``cell_bound``: the input's ``dx`` x ``dy`` grid is coarse for
    some ball of its library (:func:`cell_bound_wanted` at the plan's scallop
    ``tolerance``). One choice for all its balls: a rest ball's closing compared with the
    ball before's then measures reach, not which bound each took. On finer grids the
    planes stay (the per-cell bound follows a rough surface's detail the planes smooth
    over, and doubled Mount Rushmore's program at 0.1 mm)."""
    return any(cell_bound_wanted(b, dx, dy, tolerance) for b in balls)


def _tightened(part: ZMap, tool: Tool, cl: F64, rows: NDArray[np.integer] | None,
               threads: int | None, cell_bound: bool,
               where: NDArray[np.bool_] | None) -> F64:
    if not (cell_bound and takes_cell_bound(tool, part.dx, part.dy)):
        return cl
    return tighten(part.z, part.dx, part.dy, tool.radius, cl, rows, threads, where)


def envelope(cl: F64, tool: Tool, dx: float, dy: float,
             interpolation: Interpolation = "bilinear") -> F64:
    """Surface the tool leaves with its tip at ``cl`` on every node (+inf: not reached).

    Parameters
    ----------
    cl : (ny, nx) float64
        Tip heights of the tool positions, one per node of a grid of spacing ``dx, dy``.
    tool : Tool
    dx, dy : float
        Node spacing in mm.
    interpolation : {"bilinear", "cell"}
        ``bilinear``: the envelope at each node (exact there, rounded up);
        ``cell``: the highest envelope point over each node's square (an upper bound).

    Returns
    -------
    (ny, nx) float64
        ``min over positions c within R of cl[c] + h(|p - c|)`` per node ``p``.
    """
    _check(tool, dx, dy, interpolation)
    cl = np.asarray(cl, dtype=np.float64)
    if cl.ndim != 2 or not np.isfinite(cl).all():
        raise InvalidInputError("cl", "must be a 2-D grid of finite heights")
    return erode(cl, envelope_profile(tool, dx, dy, interpolation))


def closing(part: ZMap, tool: Tool, interpolation: Interpolation = "bilinear") -> F64:
    """What the tool leaves machining everywhere it can: the envelope of its drop-cutter CL.

    Returns
    -------
    (ny, nx) float64
        Never below the part at any node (and, the CL being safe, the tool never cuts
        the continuous part); equal to the part where the tool reaches it.
    """
    return envelope(drop_cutter(part, tool, interpolation), tool, part.dx, part.dy,
                    interpolation)
