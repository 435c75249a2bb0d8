"""Biarc geometry: the junction of two tangent arcs between two point-tangent pairs,
and which samples the first arc stands for (used by
:meth:`zwcore.arcs._pieces.ToleranceBand.biarc`)."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from zwcore.arcs._geometry import unwrap

FloatArray = NDArray[np.float64]

__all__ = ["junction", "last_on_first_arc"]


def junction(
    p0: FloatArray, t0: FloatArray, p1: FloatArray, t1: FloatArray, f: float
) -> FloatArray | None:
    """The junction of the biarc from ``(p0, t0)`` to ``(p1, t1)`` whose first tangent
    leg is ``f`` chords long, or None when that biarc does not exist."""
    vv = p1 - p0
    dist2 = float(vv @ vv)
    dist = math.sqrt(dist2)
    vt0 = float(vv @ t0)
    vt1 = float(vv @ t1)
    t01 = float(t0 @ t1)
    d1 = f * dist
    den = vt1 - d1 * (t01 - 1.0)
    if abs(den) < 1e-300:
        return None
    d2 = (0.5 * dist2 - d1 * vt0) / den
    if not (d2 > 0.0 and math.isfinite(d2)):
        return None
    p0x, p0y, t0x, t0y = float(p0[0]), float(p0[1]), float(t0[0]), float(t0[1])
    p1x, p1y, t1x, t1y = float(p1[0]), float(p1[1]), float(t1[0]), float(t1[1])
    # (per coordinate: numpy's overhead on two elements dominates)
    return np.array([
        (d2 * (p0x + d1 * t0x) + d1 * (p1x - d2 * t1x)) / (d1 + d2),
        (d2 * (p0y + d1 * t0y) + d1 * (p1y - d2 * t1y)) / (d1 + d2)])


def last_on_first_arc(
    uu: FloatArray, vv: FloatArray, k1: float, s1: float, k: int, b: int
) -> int:
    """The last sample (in ``k..b-1``) whose foot point lies on the first arc (curvature
    ``k1``, length ``s1``); ``uu, vv`` are samples ``k..b`` in the start frame."""
    if k1 != 0.0:
        ph = np.arctan2(k1 * uu, 1.0 - k1 * vv)
        ph[0] = 0.0
        sg = unwrap(ph) / k1
    else:
        sg = uu
    over = np.flatnonzero(sg > s1)
    m = k + (int(over[0]) - 1 if over.size else b - k - 1)
    return min(max(m, k), b - 1)
