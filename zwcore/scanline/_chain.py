"""The finishing chain the time ranking chooses (:mod:`zwcore.scanline._regions`) and its
figures, as the tool choice (:mod:`zwcore.scanline._tool_choice`) and the reach figures
read them: apart from the ranking, so that those modules need not import it."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from zwcore.grid.tools import Tool

__all__ = ["TOOL_CHANGE_MM", "Chain", "MainBall"]

F64 = NDArray[np.float64]

#: A tool change (stop, change, measure, approach) costs as much finishing time as
#: cutting this length, mm (about 7 s at a 2,000 mm/min finishing feed).
TOOL_CHANGE_MM = 250.0


@dataclass(frozen=True)
class MainBall:
    """The chain's main ball (it machines the whole part) and its estimated figures.

    Attributes
    ----------
    tool : Tool
    cut_length : float
        Part area / flat pick-feed at ``tolerance``, mm.
    rest_max : float
        Most material left over the part after this ball, mm.
    reason : str
    """

    tool: Tool
    cut_length: float
    rest_max: float
    reason: str


@dataclass(frozen=True, eq=False)
class Chain:
    """The finishing chain and the figures of its choice.

    Attributes
    ----------
    balls : tuple of Tool
        The chain's balls, main ball first.
    main : MainBall
    smallest_everywhere : float
        Cut length if the smallest library ball finished the whole part, mm.
    rho : (ny, nx) float64
        The part's concave radii (:func:`zwcore.scanline._reach.concave_radii`), for the
        rest rules and the reach figures (computed once per plan).
    cell_bound : bool
        The plan's choice of the per-cell drop-cutter bound for its small balls
        (:func:`zwcore.sim.coarse_grid`), for its simulation, rest rules and paths.
    """

    balls: tuple[Tool, ...]
    main: MainBall
    smallest_everywhere: float
    rho: F64
    cell_bound: bool = False
