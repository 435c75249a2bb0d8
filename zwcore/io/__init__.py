"""Part, curve and program formats in and out.

- :mod:`zwcore.io.mesh`: meshes (STL) to z-maps;
- :mod:`zwcore.io.gcode_program`: :func:`rewrite_program`, the G01 runs of an NC
  program as C1 arc chains (:func:`program_runs`: the runs alone);
- :mod:`zwcore.io.dxf`: :func:`dxf_to_chains`, the polylines and splines of a DXF
  drawing as arc chains, and :func:`chains_to_dxf`, chains as LINE/ARC entities.

Parsers turn file bytes into arrays and raise :class:`zwcore.errors.InvalidInputError`
naming what is wrong; they sit beside the planners and use only the layers below.
"""

from zwcore.io.dxf import DxfChain, DxfResult, chains_to_dxf, dxf_to_chains
from zwcore.io.gcode_program import GcodeRun, RewrittenProgram, program_runs, rewrite_program
from zwcore.io.mesh import MeshZMap, ZMapGrid, rasterise, read_stl, zmap_grid

__all__ = ["DxfChain", "DxfResult", "GcodeRun", "MeshZMap", "RewrittenProgram", "ZMapGrid",
           "chains_to_dxf", "dxf_to_chains", "program_runs", "rasterise", "read_stl",
           "rewrite_program", "zmap_grid"]
