"""Cutting simulation on z-maps: what a ball or flat end mill really reaches and leaves.

- :mod:`zwcore.sim.cutting`: drop-cutter CL surfaces (grey dilation by the tool's
  profile), machined envelopes (erosion of a CL surface) and their closing, exact or
  conservative for the surface's meaning;
- :mod:`zwcore.sim.figures`: one pass simulated over a stock, and the figures a
  planner needs (gouge, rest material, rest regions, real depth of cut);
- private: ``_profiles`` (structuring functions), ``_morph`` (the symmetric
  dilation, linear in the grid), ``_drop_bb`` (the same drop-cutter by branch and
  bound over tiles of offsets, for large tools: ``drop_cutter(method="pruned")``),
  ``_nodal`` (reach against the nodes: drop cutter and closing by branch and bound,
  balls between nodes; exported below), ``_cells`` (small balls' per-cell bound of the
  bilinear drop-cutter: the ball's curvature under each cell, ``CellBound``).
"""

from zwcore.sim._cells import TIGHT_MAX_CELLS, CellBound, cells_within
from zwcore.sim._nodal import ball_offsets, nodal_closing, nodal_drop_cutter, refine_rest
from zwcore.sim.cutting import (
    MAX_FOOTPRINT,
    cell_bound_wanted,
    closing,
    coarse_grid,
    drop_cutter,
    envelope,
    simulation_work,
    takes_cell_bound,
)
from zwcore.sim.figures import (
    MAX_BOXES,
    DepthOfCut,
    PassSimulation,
    RegionBox,
    RestMaterial,
    RestRegions,
    depth_of_cut,
    gouge,
    rest_material,
    rest_regions,
    simulate_pass,
)

__all__ = [
    "MAX_BOXES",
    "MAX_FOOTPRINT",
    "TIGHT_MAX_CELLS",
    "CellBound",
    "DepthOfCut",
    "PassSimulation",
    "RegionBox",
    "RestMaterial",
    "RestRegions",
    "ball_offsets",
    "cell_bound_wanted",
    "cells_within",
    "closing",
    "coarse_grid",
    "depth_of_cut",
    "drop_cutter",
    "envelope",
    "gouge",
    "nodal_closing",
    "nodal_drop_cutter",
    "refine_rest",
    "rest_material",
    "rest_regions",
    "simulate_pass",
    "simulation_work",
    "takes_cell_bound",
]
