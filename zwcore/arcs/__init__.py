"""C1 chains of arcs and lines through an ordered 2-D point curve (seed 004).

- :mod:`zwcore.arcs.fit`: :func:`fit_arcs`, the chain and segment types;
- :mod:`zwcore.arcs.verify`: two-sided deviation of a chain from its polyline;
- :mod:`zwcore.arcs.offset`: tool-radius offsets of a chain;
- :mod:`zwcore.arcs.gcode`: the chain as a G02/G03/G01 program;
- private: ``_search`` (the junction search), ``_pieces`` (tolerance band and
  piece geometry), ``_lines`` (straight runs), ``_start`` (start tangents),
  ``_fallback`` (the always-valid fallback), ``_geometry`` (arc primitives).
"""

from zwcore.arcs.fit import ArcChain, Segment, chain_tangents, fit_arcs
from zwcore.arcs.gcode import to_gcode
from zwcore.arcs.offset import OffsetResult, offset_chain

__all__ = ["ArcChain", "OffsetResult", "Segment", "chain_tangents", "fit_arcs", "offset_chain",
           "to_gcode"]
