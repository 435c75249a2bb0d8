"""Per-pass figures from the cutting simulation: stock, gouge, rest, depth of cut.

A planner calls :func:`simulate_pass` once per stage (the simulated stock of one
stage is the previous stock of the next) and :func:`rest_regions` to send a
smaller ball only where the larger ones left material.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from zwcore.errors import InvalidInputError
from zwcore.grid.tools import Tool
from zwcore.grid.zmap import Interpolation, ZMap, finite_number, positive_number
from zwcore.sim._morph import dilate
from zwcore.sim._profiles import flat_reach_profile
from zwcore.sim.cutting import drop_cutter, envelope

__all__ = ["MAX_BOXES", "DepthOfCut", "PassSimulation", "RegionBox", "RestMaterial",
           "RestRegions", "depth_of_cut", "gouge", "rest_material", "rest_regions",
           "simulate_pass"]

F64 = NDArray[np.float64]

#: Most bounding boxes a :class:`RestRegions` lists (the largest regions first).
MAX_BOXES = 256


@dataclass(frozen=True)
class RestMaterial:
    """Material a surface leaves over a target, node by node (``max(surface - target, 0)``).

    Attributes
    ----------
    max, p95, mean : float
        Over all nodes, mm.
    volume : float
        Sum times the cell area, mm³.
    """

    max: float
    p95: float
    mean: float
    volume: float


@dataclass(frozen=True, eq=False)
class DepthOfCut:
    """Material a tool really meets: per position, the highest stock inside its cylinder
    (radius R) above its tip.

    Attributes
    ----------
    per_position : (ny, nx) float64
        mm, 0 where the tool cuts nothing.
    max : float
    mean : float
        Over the positions that cut (0 when none does).
    flute_length : float
    flute_length_ok : bool
        ``max <= flute_length``.
    """

    per_position: F64
    max: float
    mean: float
    flute_length: float
    flute_length_ok: bool


@dataclass(frozen=True)
class RegionBox:
    """Bounding box of one connected rest region, mm (node positions); its area in mm²."""

    x_min: float
    y_min: float
    x_max: float
    y_max: float
    area: float


@dataclass(frozen=True, eq=False)
class RestRegions:
    """Where a surface lies more than ``tolerance`` above the part, grown by a radius.

    Attributes
    ----------
    mask : (ny, nx) bool
    area_fraction : float
        Share of the grid's nodes in the mask.
    count : int
        Connected regions (8-connected).
    boxes : tuple of RegionBox
        The largest :data:`MAX_BOXES` regions, largest first.
    """

    mask: NDArray[np.bool_]
    area_fraction: float
    count: int
    boxes: tuple[RegionBox, ...]


@dataclass(frozen=True, eq=False)
class PassSimulation:
    """One pass simulated: positions, surfaces and figures.

    Attributes
    ----------
    cl : (ny, nx) float64
        Tip heights of the tool positions (one per node).
    envelope : (ny, nx) float64
        What the tool alone leaves (+inf where no position reaches).
    stock : (ny, nx) float64
        Simulated stock after the pass, ``min(previous stock, envelope)``.
    gouge : float
        ``max(part - stock)`` clipped at 0: 0 unless a given CL cuts into the part.
    rest : RestMaterial
        Stock left over the part.
    depth : DepthOfCut
        From the previous stock.
    """

    cl: F64
    envelope: F64
    stock: F64
    gouge: float
    rest: RestMaterial
    depth: DepthOfCut


def gouge(part: F64, machined: F64) -> float:
    """Deepest cut into the part, ``max(part - machined)`` clipped at 0, mm.

    Parameters
    ----------
    part, machined : (ny, nx) float64
    """
    return float(max(0.0, float(np.max(part - machined))))


def rest_material(surface: F64, target: F64, cell_area: float = 1.0) -> RestMaterial:
    """Material ``surface`` leaves over ``target``.

    Parameters
    ----------
    surface, target : (ny, nx) float64
    cell_area : float
        mm² per node, for the volume.
    """
    rest = np.maximum(surface - target, 0.0)
    return RestMaterial(max=float(rest.max()), p95=float(np.percentile(rest, 95)),
                        mean=float(rest.mean()), volume=float(rest.sum() * cell_area))


def rest_regions(surface: F64, part: ZMap, tolerance: float, grow_radius: float = 0.0
                 ) -> RestRegions:
    """Nodes where ``surface`` lies more than ``tolerance`` above the part, grown by
    ``grow_radius`` (the next ball's radius, so its region covers every position that
    reaches the rest).

    Parameters
    ----------
    surface : (ny, nx) float64
        Simulated surface after the previous passes.
    part : ZMap
    tolerance : float
        > 0, mm.
    grow_radius : float
        >= 0, mm (Euclidean, on the node grid).
    """
    tolerance = positive_number(tolerance, "tolerance")
    grow_radius = finite_number(grow_radius, "grow_radius")
    if grow_radius < 0:
        raise InvalidInputError("grow_radius", f"must be >= 0, got {grow_radius!r}")
    seed = (surface - part.z) > tolerance
    if grow_radius > 0 and seed.any() and not seed.all():
        dist = ndimage.distance_transform_edt(~seed, sampling=(part.dy, part.dx))
        mask = dist <= grow_radius
    else:
        mask = seed
    labels, count = ndimage.label(mask, structure=np.ones((3, 3), dtype=bool))
    sizes = np.bincount(labels.ravel())[1:]
    order = np.argsort(-sizes, kind="stable")[:MAX_BOXES]
    slices = ndimage.find_objects(labels)
    boxes = []
    for n in order:
        sy, sx = slices[n]
        boxes.append(RegionBox(
            x_min=part.x0 + sx.start * part.dx, y_min=part.y0 + sy.start * part.dy,
            x_max=part.x0 + (sx.stop - 1) * part.dx, y_max=part.y0 + (sy.stop - 1) * part.dy,
            area=float(sizes[n]) * part.cell_area))
    return RestRegions(mask=mask, area_fraction=float(mask.mean()), count=int(count),
                       boxes=tuple(boxes))


def depth_of_cut(stock: F64 | float, cl: F64, tool: Tool, dx: float, dy: float,
                 interpolation: Interpolation = "bilinear") -> DepthOfCut:
    """Material inside the tool's cylinder above its tip at each position.

    Parameters
    ----------
    stock : (ny, nx) float64 or float
        The stock before the pass (a grid in ``interpolation``, or a flat top).
    cl : (ny, nx) float64
        Tip heights.
    tool : Tool
    dx, dy : float
    interpolation : {"bilinear", "cell"}
        The stock grid's meaning; its highest point over the tool's disc is bounded
        from above (never an engagement too small).
    """
    if np.ndim(stock) == 0:
        top = np.full(cl.shape, float(stock))
    else:
        top = dilate(np.asarray(stock, dtype=np.float64),
                     flat_reach_profile(tool.radius, dx, dy, interpolation))
    depth = np.maximum(top - cl, 0.0)
    cutting = depth > 0
    mx = float(depth.max())
    mean = float(depth[cutting].mean()) if cutting.any() else 0.0
    return DepthOfCut(per_position=depth, max=mx, mean=mean, flute_length=tool.flute_length,
                      flute_length_ok=mx <= tool.flute_length)


def _grid_on_part(values: object, part: ZMap, field: str) -> F64:
    """``values`` as a finite float64 grid on the part's nodes (else an error on ``field``)."""
    grid = np.asarray(values, dtype=np.float64)
    if grid.shape != part.shape:
        raise InvalidInputError(field, f"grid of shape {list(grid.shape)}; the part's is "
                                f"{list(part.shape)}")
    if not np.isfinite(grid).all():
        raise InvalidInputError(field, "heights must be finite")
    return grid


def _stock_grid(stock: F64 | float, part: ZMap) -> F64:
    if np.ndim(stock) == 0:
        top = finite_number(stock, "stock")
        if top < float(part.z.max()):
            raise InvalidInputError("stock", f"flat stock top {top!r} lies below the part's "
                                    f"highest point {float(part.z.max())!r}")
        return np.full(part.shape, top)
    grid = _grid_on_part(stock, part, "stock")
    below = grid < part.z
    if below.any():
        i, k = np.argwhere(below)[0]
        raise InvalidInputError("stock", f"lies below the part at {int(below.sum())} node(s), "
                                f"first row {i}, column {k}")
    return grid


def simulate_pass(part: ZMap, tool: Tool, stock: F64 | float, *, cl: F64 | None = None,
                  interpolation: Interpolation = "bilinear") -> PassSimulation:
    """Simulate one tool machining ``stock`` over ``part``.

    Parameters
    ----------
    part : ZMap
        The finished part, ``(ny, nx)``.
    tool : Tool
    stock : (ny, nx) float64 or float
        Stock before the pass (at or above the part), a grid on the part's nodes or a
        flat top.
    cl : (ny, nx) float64, optional
        Tip heights on the part's nodes. Default: the drop-cutter CL, i.e. the tool
        machines everywhere it can (the result is then the closing, capped by the stock).
    interpolation : {"bilinear", "cell"}
        Meaning of the part and stock grids.

    Returns
    -------
    PassSimulation

    Raises
    ------
    InvalidInputError
        ``stock`` of another shape or below the part, ``cl`` of another shape or
        not finite.
    """
    previous = _stock_grid(stock, part)
    if cl is None:
        positions = drop_cutter(part, tool, interpolation)
    else:
        positions = _grid_on_part(cl, part, "cl")
    env = envelope(positions, tool, part.dx, part.dy, interpolation)
    after = np.minimum(previous, env)
    return PassSimulation(
        cl=positions, envelope=env, stock=after, gouge=gouge(part.z, after),
        rest=rest_material(after, part.z, part.cell_area),
        depth=depth_of_cut(stock if np.ndim(stock) == 0 else previous, positions, tool,
                           part.dx, part.dy, interpolation))
