"""zwcore: the numeric core of zwplan.

Arrays in, arrays and small dataclasses out; no idea that HTTP exists.
Topical modules re-exported here (as PyWavelets does):

- :mod:`zwcore.zmap`: the z-map type and its validation;
- :mod:`zwcore.wavelets`: Haar and single-knot MRR with the overcut-free lift;
- :mod:`zwcore.sampling`: level models evaluated on finer grids;
- :mod:`zwcore.tools`: end mills and the default library;
- :mod:`zwcore.errors`: the error family.
"""

from zwcore.errors import InvalidInputError, LimitExceededError, PlanningError, ZwError
from zwcore.sampling import at_fine_nodes, bilinear_at_fine_nodes, cells_at_fine_nodes
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
    "WAVELETS",
    "Bands",
    "InvalidInputError",
    "LimitExceededError",
    "Multiresolution",
    "PlanningError",
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
    "level_count",
    "synthesis_step",
    "tool_library",
]
