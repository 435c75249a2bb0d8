"""zwcore: the numeric core of zwplan.

Arrays in, arrays and small dataclasses out; no idea that HTTP exists.
Subpackages by capability, their public names re-exported here (as
scikit-image and PyWavelets do). Import layers, bottom up (a test holds them):

- :mod:`zwcore.errors`: the error family;
- :mod:`zwcore.grid`: the z-map type, level models on finer grids, tools, curvature;
- :mod:`zwcore.mrr`: wavelet analysis/synthesis, the fast pyramid, terraces;
- :mod:`zwcore.sim`: cutting simulation (drop-cutter CL, envelopes, pass figures),
  beside the MRR;
- :mod:`zwcore.scanline`, :mod:`zwcore.contour`: the two planners;
- :mod:`zwcore.arcs`: C1 arc chains, their offsets and NC programs (beside
  the grid stack: it needs only :mod:`zwcore.errors`).
"""

from zwcore.arcs import ArcChain, Segment, fit_arcs, offset_chain, to_gcode
from zwcore.contour import STRATEGIES, ContourChecks, ContourPlan, ContourStage, plan_contour
from zwcore.errors import InvalidInputError, LimitExceededError, PlanningError, ZwError
from zwcore.grid import (
    DEFAULT_LIBRARY,
    Tool,
    ZMap,
    as_heights,
    at_fine_nodes,
    bilinear_at_fine_nodes,
    cells_at_fine_nodes,
    default_tools,
    tool_library,
)
from zwcore.mrr import (
    WAVELETS,
    Bands,
    Multiresolution,
    analyse,
    analysis_step,
    level_count,
    synthesis_step,
)
from zwcore.scanline import (
    ScanlineChecks,
    ScanlinePlan,
    ScanlineStage,
    plan_scanline,
    scallop_height,
)
from zwcore.sim import PassSimulation, closing, drop_cutter, envelope, simulate_pass

__version__ = "0.1.0"

__all__ = [
    "DEFAULT_LIBRARY",
    "STRATEGIES",
    "WAVELETS",
    "ArcChain",
    "Bands",
    "ContourChecks",
    "ContourPlan",
    "ContourStage",
    "InvalidInputError",
    "LimitExceededError",
    "Multiresolution",
    "PassSimulation",
    "PlanningError",
    "ScanlineChecks",
    "ScanlinePlan",
    "ScanlineStage",
    "Segment",
    "Tool",
    "ZMap",
    "ZwError",
    "__version__",
    "analyse",
    "analysis_step",
    "as_heights",
    "at_fine_nodes",
    "bilinear_at_fine_nodes",
    "cells_at_fine_nodes",
    "closing",
    "default_tools",
    "drop_cutter",
    "envelope",
    "fit_arcs",
    "level_count",
    "offset_chain",
    "plan_contour",
    "plan_scanline",
    "scallop_height",
    "simulate_pass",
    "synthesis_step",
    "to_gcode",
    "tool_library",
]
