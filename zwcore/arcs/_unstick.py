"""Ways out of a stuck level of the beam (:mod:`zwcore.arcs._search`): a biarc bridge
onto a sample just ahead, and the filleted-polyline fallback (valid by construction,
:mod:`zwcore.arcs._fallback`)."""

from __future__ import annotations

import numpy as np

from zwcore.arcs._fallback import fillet_stretch
from zwcore.arcs._pieces import Piece, ToleranceBand
from zwcore.arcs._states import State, unwind

__all__ = ["bridge", "fallback"]


def bridge(band: ToleranceBand, st: State, b: int, loop: bool) -> State | None:
    """Two verified arcs from ``st`` to a sample just ahead, ending along the polyline.

    The end state lies on the polyline with the direction of one of its segments
    (or their bisector), from which progress is always possible.
    """
    assert st.t is not None
    samples = band.samples
    for m in range(st.k + 1, min(st.k + 12, b) + 1):
        if m == b and loop:
            continue
        dirs = []
        for i0, i1 in ((m - 1, m), (m, m + 1)):
            if 0 <= i0 and i1 <= b:
                dv = samples[i1] - samples[i0]
                n = float(np.hypot(*dv))
                if n > 0.0:
                    dirs.append(dv / n)
        if len(dirs) == 2:
            bis = dirs[0] + dirs[1]
            nb = float(np.hypot(*bis))
            if nb > 1e-9:
                dirs.append(bis / nb)
        for t1 in dirs:
            got = band.biarc(st.p, st.t, st.k, st.e, m, t1)
            if got is None:
                continue
            a1, a2 = got
            mid = State(a1.end, a1.t_end, a1.j, 0.0, st, a1, st.t_first, st.depth + 1)
            return State(a2.end, a2.t_end, m, 0.0, mid, a2, st.t_first, st.depth + 2)
    return None

def fallback(
band: ToleranceBand, st: State, b: int, loop: bool, span: float
) -> tuple[list[Piece], State | None]:
    """A filleted-polyline stretch from ``st`` over ``span`` tolerances: the whole chain, or
    the state after it."""
    assert st.t is not None
    k = st.k
    m = int(np.searchsorted(band.cum, band.cum[k] + span * band.tol))
    m = max(m, k + 2)
    if m >= b - 1:
        m = b
    if m == b:
        mode = "tangent" if loop else "sample"
    else:
        mode = "state"
    pieces, end = fillet_stretch(band.samples, band.tol, st.p, st.t, k, m, mode,
                                 st.t_first if loop else None)
    node = st
    for pc in pieces:
        node = State(pc.end, pc.t_end, pc.j, 0.0, node, pc, st.t_first, node.depth + 1)
    if end is None:
        return unwind(node), None
    ep, et, ee = end
    return [], State(ep, et, m, ee, node, None, st.t_first, node.depth, fresh=True)
