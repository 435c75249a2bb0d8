"""Part and curve formats in and out: meshes (STL) to z-maps.

Parsers turn file bytes into arrays and raise :class:`zwcore.errors.InvalidInputError`
naming what is wrong; they sit beside the planners and use only the grid layer.
"""

from zwcore.io.mesh import MeshZMap, ZMapGrid, rasterise, read_stl, zmap_grid

__all__ = ["MeshZMap", "ZMapGrid", "rasterise", "read_stl", "zmap_grid"]
