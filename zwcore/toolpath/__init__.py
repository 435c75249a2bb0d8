"""Tool paths and NC programs for every stage, verified by simulating the program (issue 12).

- :mod:`zwcore.toolpath.program`: cutting data, moves, stage paths, lengths and times;
- :mod:`zwcore.toolpath.writer`: the program text;
- :mod:`zwcore.toolpath.parse`: an independent reader of programs;
- :mod:`zwcore.toolpath.sweep`: exact swept-tool envelopes on grid nodes;
- :mod:`zwcore.toolpath.simulate`: the program simulated on the stock, verification figures;
- :mod:`zwcore.toolpath.scanline_paths`: raster paths of ball-end-mill stages;
- :mod:`zwcore.toolpath.contour_paths`: rings of flat-end-mill stages, arcs, ramps;
- :mod:`zwcore.toolpath.plans`: a whole plan's paths, program and verification;
- :mod:`zwcore.toolpath.verify_plan`: a scan-line plan's program read back and simulated
  tool stretch by tool stretch (``POST /v1/simulate`` with a task id);
- private: ``_polyline`` (thinning, lifting out of gouges).
"""

from zwcore.toolpath.parse import ParsedProgram, parse_program
from zwcore.toolpath.plans import Toolpaths, contour_toolpaths, scanline_toolpaths
from zwcore.toolpath.program import (
    CuttingData,
    Moves,
    ProgramSettings,
    StagePath,
    cutting_data,
)
from zwcore.toolpath.scanline_paths import CLHeights, scanline_stage_path
from zwcore.toolpath.simulate import ProgramCheck, StageCheck, simulate_program
from zwcore.toolpath.writer import iter_program, program_text

__all__ = [
    "CLHeights",
    "CuttingData",
    "Moves",
    "ParsedProgram",
    "ProgramCheck",
    "ProgramSettings",
    "StageCheck",
    "StagePath",
    "Toolpaths",
    "contour_toolpaths",
    "cutting_data",
    "iter_program",
    "parse_program",
    "program_text",
    "scanline_stage_path",
    "scanline_toolpaths",
    "simulate_program",
]
