"""The scan-line plan: ball end mills over single-knot stage models (seed 000, 6.1-6.2).

- :mod:`zwcore.scanline.planner`: :func:`plan_scanline`;
- :mod:`zwcore.scanline.results`: the plan, stage and checks dataclasses;
- :mod:`zwcore.scanline.replay`: a plan's passes simulated again on its part;
- private: ``_models`` (nested stage targets), ``_tool_choice`` (which level
  becomes a stage, with which ball), ``_passes`` (pick-feed strips and
  scallops), ``_stage_passes`` (the passes of every stage and the flute rule),
  ``_stock`` (the simulated stock), ``_checks`` (per-stage figures and the invariants).
"""

from zwcore.scanline._passes import scallop_height
from zwcore.scanline.planner import plan_scanline
from zwcore.scanline.results import ScanlineChecks, ScanlinePlan, ScanlineStage

__all__ = ["ScanlineChecks", "ScanlinePlan", "ScanlineStage", "plan_scanline", "scallop_height"]
