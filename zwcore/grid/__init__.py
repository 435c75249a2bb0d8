"""What every planner shares: the z-map, level models on finer grids, tools, curvature.

- :mod:`zwcore.grid.zmap`: the z-map type and input normalisation;
- :mod:`zwcore.grid.sampling`: level models evaluated at the input's nodes;
- :mod:`zwcore.grid.tools`: end mills and the default library;
- :mod:`zwcore.grid.curvature`: concave radius of curvature of a grid surface.
"""

from zwcore.grid.curvature import min_concave_radius, steepest_slope
from zwcore.grid.sampling import at_fine_nodes, bilinear_at_fine_nodes, cells_at_fine_nodes
from zwcore.grid.tools import DEFAULT_LIBRARY, TOOL_KINDS, Tool, default_tools, tool_library
from zwcore.grid.zmap import INTERPOLATIONS, MAX_ABS_HEIGHT, ZMap, as_heights

__all__ = [
    "DEFAULT_LIBRARY",
    "INTERPOLATIONS",
    "MAX_ABS_HEIGHT",
    "TOOL_KINDS",
    "Tool",
    "ZMap",
    "as_heights",
    "at_fine_nodes",
    "bilinear_at_fine_nodes",
    "cells_at_fine_nodes",
    "default_tools",
    "min_concave_radius",
    "steepest_slope",
    "tool_library",
]
