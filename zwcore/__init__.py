"""zwcore: the numeric core of zwplan.

Arrays in, arrays and small dataclasses out; no idea that HTTP exists.
Topical modules, re-exported here (as PyWavelets does):

- :mod:`zwcore.zmap`: the z-map type and its validation;
- :mod:`zwcore.wavelets`: Haar and single-knot MRR with the overcut-free lift;
- :mod:`zwcore.sampling`: level models evaluated on finer grids;
- :mod:`zwcore.tools`: end mills and the default library;
- :mod:`zwcore.curvature`: concave radius of curvature of a grid surface;
- :mod:`zwcore.scanline`: the scan-line plan (ball end mills, stage models);
- :mod:`zwcore.contour`: the contour plan (flat end mills, equal-load heights, terraces);
- :mod:`zwcore.arcs`, :mod:`zwcore.offset`, :mod:`zwcore.gcode`: C1 arc chains,
  their tool offsets and NC programs;
- :mod:`zwcore.errors`: the error family.
"""

from zwcore.arcs import ArcChain, Segment, fit_arcs
from zwcore.contour import STRATEGIES, ContourChecks, ContourPlan, ContourStage, plan_contour
from zwcore.errors import InvalidInputError, LimitExceededError, PlanningError, ZwError
from zwcore.gcode import to_gcode
from zwcore.offset import offset_chain
from zwcore.sampling import at_fine_nodes, bilinear_at_fine_nodes, cells_at_fine_nodes
from zwcore.scanline import (
    ScanlineChecks,
    ScanlinePlan,
    ScanlineStage,
    plan_scanline,
    scallop_height,
)
from zwcore.tools import DEFAULT_LIBRARY, Tool, default_tools, tool_library
from zwcore.wavelets import (
    WAVELETS,
    Bands,
    Multiresolution,
    analyse,
    analysis_step,
    level_count,
    synthesis_step,
)
from zwcore.zmap import ZMap, as_heights

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
    "default_tools",
    "fit_arcs",
    "level_count",
    "offset_chain",
    "plan_contour",
    "plan_scanline",
    "scallop_height",
    "synthesis_step",
    "to_gcode",
    "tool_library",
]
