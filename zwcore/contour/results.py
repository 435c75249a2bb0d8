"""Result types of the contour plan (see :mod:`zwcore.contour.planner`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from zwcore.grid.tools import Tool

__all__ = ["VOLUME_SPREAD_LIMIT", "ContourChecks", "ContourPlan", "ContourStage"]

F64 = NDArray[np.float64]

#: Largest accepted spread of equal-volume slabs (``max/min - 1``) for ``ok``.
VOLUME_SPREAD_LIMIT = 0.10


@dataclass(frozen=True, eq=False)
class ContourStage:
    """One stage of a contour plan.

    Attributes
    ----------
    tool : Tool
    level : int
        MRR level the stage works at (0 = coarsest).
    scale : int
        Input nodes per model cell along an axis, ``2**(J - level)``.
    cell_size : (float, float)
        Cell size ``(x, y)`` in mm.
    origin : (float, float)
        Centre of model cell ``(0, 0)``: the stage grid's ``(x0, y0)``.
    level_rule : str
        Why this level, in words.
    spacing_rule : {"even_flute", "equal_volume", "even_step"}
        How the heights were placed: heavy roughing (fewest slabs within the
        flute length), equal slab volumes, or a constant step-down.
    nominal_step : float
        Step-down that set the slab count, mm.
    z_levels : tuple of float
        Contour heights, descending; the first is the top of the stock the
        stage starts from, each later one is a waterline pass.
    spacings : tuple of float
        ``z_levels[i] - z_levels[i + 1]``.
    slab_volumes : tuple of float
        Volume each slab really removes (between the previous and this model,
        inside the slab), mm³.
    volume_spread : float
        ``max/min - 1`` of the slab volumes where the flute cap does not bind.
    flute_cap_binds : tuple of bool
        Per slab: the flute cap bound it, which exempts it from equal volume. A
        flagged slab is exactly the flute length thick (to the height quantum)
        and removes less than the stage's slab volume: no slab from its bottom
        height, at most a flute long, could remove that volume. Heavy-roughing
        slabs are evenly spaced (no volume target) and flagged only where that
        spacing is the flute length itself.
    removed_volume : float
        Sum of the slab volumes, mm³.
    max_stock_left, mean_stock_left : float
        Stock over the part after the stage, over the input nodes, mm.
    edited_coefficients : int
        Coefficients of the part's representation from the stage level up that
        the edit changed: approximation coefficients raised onto the contour
        grid plus non-zero finer detail coefficients set to zero.
    model : (my, mx) float64
        Terrace heights, one flat cell per node at the stage level: the edited
        approximation coefficients.
    """

    tool: Tool
    level: int
    scale: int
    cell_size: tuple[float, float]
    origin: tuple[float, float]
    level_rule: str
    spacing_rule: str
    nominal_step: float
    z_levels: tuple[float, ...]
    spacings: tuple[float, ...]
    slab_volumes: tuple[float, ...]
    volume_spread: float
    flute_cap_binds: tuple[bool, ...]
    removed_volume: float
    max_stock_left: float
    mean_stock_left: float
    edited_coefficients: int
    model: F64


@dataclass(frozen=True)
class ContourChecks:
    """The invariants of design section 4, verified on the plan.

    Attributes
    ----------
    containment : bool
        Every stage model contains the next and the last contains the part, at
        every input node.
    min_containment_margin : float
        Smallest of those differences, mm (>= 0 when ``containment``).
    spacings_within_flute : bool
        No spacing exceeds its stage tool's flute length.
    spacings_positive : bool
    max_volume_spread : float
        Largest ``volume_spread`` of the equal-volume stages.
    volumes_add_up : bool
        Each stage's slab volumes add up to the volume between its models,
        summed independently over the input nodes.
    terraces_from_coefficients : bool
        Synthesis of every stage's edited representation, at every input node,
        equals the terrace rule applied on its own (cell semantics), bit for bit.
    """

    containment: bool
    min_containment_margin: float
    spacings_within_flute: bool
    spacings_positive: bool
    max_volume_spread: float
    volumes_add_up: bool
    terraces_from_coefficients: bool

    @property
    def ok(self) -> bool:
        return (self.containment and self.spacings_within_flute and self.spacings_positive
                and self.max_volume_spread <= VOLUME_SPREAD_LIMIT and self.volumes_add_up
                and self.terraces_from_coefficients)


@dataclass(frozen=True, eq=False)
class ContourPlan:
    """A contour plan.

    Attributes
    ----------
    stock_top : float
        Top of the stock, mm (as requested, or the default).
    stock_top_source : {"request", "default"}
    strategy : str
    stages : tuple of ContourStage
        In machining order.
    contour_spacings : tuple of float
        Every spacing of every stage, in machining order.
    checks : ContourChecks
    notes : tuple of str
        Rules applied and decisions taken, in words.
    """

    stock_top: float
    stock_top_source: Literal["request", "default"]
    strategy: str
    stages: tuple[ContourStage, ...]
    contour_spacings: tuple[float, ...]
    checks: ContourChecks
    notes: tuple[str, ...]
