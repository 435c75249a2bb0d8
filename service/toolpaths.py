"""Tool paths of a plan at the HTTP boundary: cutting data from the request's tools, the
response section, and where the NC program is stored (issue 12)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pybase64

from service.schemas.common import ToolIn
from zwcore.grid.tools import Tool
from zwcore.toolpath import CuttingData, Toolpaths, cutting_data

#: What the service drops the tool onto a stage model with (see docs/toolpaths.md).
CL_SOURCE = ("zwcore.sim.drop_cutter on the stage model (bilinear, conservative), then every "
             "move lifted by its exact gouge against the part's nodes (zwcore.toolpath)")


def program_key(task_id: str) -> str:
    """Store key of a task's NC program."""
    return f"{task_id}.program"


def plan_inputs_key(task_id: str) -> str:
    """Store key of what a plan was computed from (its hashed parameters and the core
    build), kept beside its result so that ``POST /v1/simulate`` can run it again."""
    return f"{task_id}.inputs"


def cutting(given: Sequence[ToolIn] | None, tools: Sequence[Tool]) -> dict[str, CuttingData]:
    """Cutting data per tool id from the request (validated, field names ``tools[i].x``);
    tools without it get defaults with ``tool_number`` their place in the library."""
    by_id = {t.id: (i, t) for i, t in enumerate(given or [])}
    out: dict[str, CuttingData] = {}
    for n, tool in enumerate(tools, 1):
        i, t = by_id.get(tool.id, (None, None))
        fields: dict[str, Any] = {"tool_number": n}
        prefix = "tools" if i is None else f"tools[{i}]"
        if t is not None:
            for name in ("tool_number", "spindle_rpm", "feed", "plunge_feed", "ramp_angle_deg"):
                v = getattr(t, name)
                if v is not None:
                    fields[name] = v
        out[tool.id] = cutting_data(prefix, **fields)
    return out


def _b64(a: np.ndarray, dtype: str) -> str:
    return pybase64.b64encode(np.ascontiguousarray(a, dtype=dtype).tobytes()).decode()


def toolpaths_section(tp: Toolpaths, task_id: str) -> dict[str, Any]:
    """The ``toolpaths`` object of a plan response."""
    stages = []
    for p, fig in zip(tp.stages, tp.stage_figures(), strict=True):
        cd = p.cutting
        stages.append({
            "index": p.index, "kind": p.kind, "tool_id": p.tool.id,
            "tool_number": cd.tool_number, "spindle_rpm": cd.spindle_rpm, "feed": cd.feed,
            "plunge_feed": cd.plunge_feed, "ramp_angle_deg": cd.ramp_angle_deg,
            "moves": len(p.moves), "rapid_length": fig["rapid_length"],
            "feed_length": fig["feed_length"], "plunge_length": fig["plunge_length"],
            "time_min": fig["time_min"], "figures": dict(p.figures),
            "move_kinds_b64": _b64(p.moves.kind, "u1"),
            "points_b64": _b64(p.moves.end, "<f4"),
            "centers_b64": _b64(p.moves.center, "<f4")})
    chk = tp.check
    verification = None
    if chk is not None:
        verification = {
            "gouge": chk.gouge, "below_part_moves": chk.below_part_moves,
            "final_over_part_max": chk.final_over_part_max,
            "final_over_part_p95": chk.final_over_part_p95,
            "finished_over_part_max": chk.finished_over_part_max,
            "finished_area_fraction": chk.finished_area_fraction,
            "within_tolerance": chk.within_tolerance,
            "rapid_in_material": chk.rapid_in_material,
            "arc_radius_mismatch": chk.arc_radius_mismatch,
            "stages": [vars(s) for s in chk.stages]}
    return {"clearance": tp.settings.clearance, "rapid_feed": tp.settings.rapid_feed,
            "length": tp.length, "time_min": tp.time_min,
            "program_bytes": len(tp.program.encode()),
            "program_url": f"/v1/tasks/{task_id}/program", "cl_source": CL_SOURCE,
            "timings": {k: round(v, 4) for k, v in tp.timings}, "stages": stages,
            "verification": verification}
