"""C1 chains of arcs and lines through an ordered 2-D point curve (seed 004).

- :mod:`zwcore.arcs.fit`: :func:`fit_arcs`, the chain and segment types;
- :mod:`zwcore.arcs.verify`: two-sided deviation of a chain from its polyline;
- :mod:`zwcore.arcs.offset`: tool-radius offsets of a chain;
- :mod:`zwcore.arcs.gcode`: the chain as a G02/G03/G01 program;
- private, in the order of the fit: ``_prepare`` (validation, corners, samples),
  ``_runs`` (runs between corners, joined; the loop start sweep), ``_search`` (the
  beam search of one run) with ``_states`` (its junction states) and ``_unstick``
  (bridges and the fallback when it is stuck), ``_start`` (start tangents, one-piece
  runs), ``_pieces`` (the tolerance band: feasible curvatures, reach, verification,
  biarcs) with ``_kernels`` (its compiled scans and two-sided bounds), ``_biarc`` (the
  compiled biarc), ``_select`` (a beam level's candidates, compiled), ``_dense`` (the
  compiled dense deviation of :mod:`zwcore.arcs.verify`) with ``_jumps`` (how far it may
  jump),
  ``_lines`` (refits along straight runs) with ``_straight`` (finding them) and
  ``_anchors`` (following them), ``_fallback`` (the filleted polyline, valid by
  construction), ``_geometry`` (arc primitives).
"""

from zwcore.arcs.fit import ArcChain, Segment, chain_tangents, fit_arcs
from zwcore.arcs.gcode import segment_blocks, to_gcode
from zwcore.arcs.offset import OffsetResult, offset_chain

__all__ = ["ArcChain", "OffsetResult", "Segment", "chain_tangents", "fit_arcs", "offset_chain",
           "segment_blocks",
           "to_gcode"]
