"""The contour plan: flat end mills over terraced Haar stage models (seed 000, 5.2 and 6.3).

- :mod:`zwcore.contour.planner`: :func:`plan_contour` (levels, heights, stage models);
- :mod:`zwcore.contour.results`: the plan, stage and checks dataclasses;
- :mod:`zwcore.contour.heights`: contour heights, even and equal-volume slabs
  (private: ``_slabs``, the slab-volume function; ``_equal_volume``, the placement).
"""

from zwcore.contour.planner import (
    STRATEGIES,
    ContourChecks,
    ContourPlan,
    ContourStage,
    level_for_tool,
    plan_contour,
)

__all__ = [
    "STRATEGIES",
    "ContourChecks",
    "ContourPlan",
    "ContourStage",
    "level_for_tool",
    "plan_contour",
]
