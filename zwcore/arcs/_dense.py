"""Compiled kernel of :func:`zwcore.arcs.verify.deviations`: the two-sided deviation of a
chain from its polyline, measured densely.

One loop per piece over the dense points near it, with the exact distance of each point
to the other side's geometry (arcs, polyline segments); no temporaries, so the dense
check of a chain costs about as much as the points it samples. The figures are those of
the numpy formulation kept in ``tests/arc_reference.py`` (property tests compare them).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from zwcore.arcs._kernels import arc_xy, circle_gap1, foot_positions, seg_dist

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

__all__ = ["dense_deviations"]


@njit(cache=True, nogil=True)
def point_arc_distance(x: float, y: float, px: float, py: float, tx: float, ty: float,
                       kappa: float, length: float, ex: float, ey: float) -> float:
    """Exact distance of ``(x, y)`` to the piece from ``p`` along ``t`` of curvature
    ``kappa`` and arc length ``length`` ending at ``(ex, ey)``."""
    dx = x - px
    dy = y - py
    u = dx * tx + dy * ty
    v = dy * tx - dx * ty
    d_ends = min(math.hypot(u, v), math.hypot(x - ex, y - ey))
    if kappa == 0.0:
        return abs(v) if 0.0 <= u <= length else d_ends
    phi = math.atan2(kappa * u, 1.0 - kappa * v)
    ang = phi if kappa > 0.0 else -phi
    if ang < 0.0:
        ang += 2.0 * math.pi
    if ang <= abs(kappa * length):
        return min(abs(circle_gap1(u, v, kappa)), d_ends)
    return d_ends


@njit(cache=True, nogil=True)
def _dense_offsets(samples: FloatArray, step: float) -> IntArray:
    """Index of the first dense point of each polyline segment ``(nseg + 1,)`` (the last
    entry: the final vertex), segments cut into pieces no longer than ``step``."""
    nseg = len(samples) - 1
    off = np.zeros(nseg + 1, dtype=np.int64)
    for s in range(nseg):
        seg = math.hypot(samples[s + 1, 0] - samples[s, 0], samples[s + 1, 1] - samples[s, 1])
        off[s + 1] = off[s] + max(math.ceil(seg / step), 1)
    return off


@njit(cache=True, nogil=True)
def _dense_point(samples: FloatArray, off: IntArray, s: int, i: int) -> tuple[float, float]:
    """Dense point ``i`` of segment ``s`` (the last one: the final vertex)."""
    if i >= off[len(off) - 1]:
        return samples[len(samples) - 1, 0], samples[len(samples) - 1, 1]
    f = (i - off[s]) / (off[s + 1] - off[s])
    return (samples[s, 0] + f * (samples[s + 1, 0] - samples[s, 0]),
            samples[s, 1] + f * (samples[s + 1, 1] - samples[s, 1]))


@njit(cache=True, nogil=True)
def _polyline_to_chain(samples: FloatArray, geo: FloatArray, ks: IntArray, js: IntArray,
                       off: IntArray) -> FloatArray:
    """Distance of every dense polyline point to the pieces covering samples near it."""
    nseg = len(samples) - 1
    total = off[nseg] + 1
    d_p = np.full(total, np.inf)
    for q in range(len(geo)):
        s0 = max(ks[q] - 2, 0)
        s1 = min(js[q] + 2, nseg)
        # (the final vertex counts as a point of the last segment)
        for s in range(s0, min(s1, nseg - 1) + 1):
            hi = off[s + 1] if s < nseg - 1 else total
            for i in range(off[s], hi):
                x, y = _dense_point(samples, off, s, i)
                d = point_arc_distance(x, y, geo[q, 0], geo[q, 1], geo[q, 2], geo[q, 3],
                                       geo[q, 4], geo[q, 5], geo[q, 6], geo[q, 7])
                d_p[i] = min(d_p[i], d)
    return d_p


@njit(cache=True, nogil=True)
def _segments_near(samples: FloatArray, x: float, y: float, m: int) -> float:
    """Distance of ``(x, y)`` to the polyline segments ``m-3..m+3`` (clipped)."""
    nseg = len(samples) - 1
    d = np.inf
    for o in range(-3, 4):
        s = min(max(m + o, 0), nseg - 1)
        d = min(d, seg_dist(x, y, samples[s, 0], samples[s, 1], samples[s + 1, 0],
                            samples[s + 1, 1]))
    return d


@njit(cache=True, nogil=True)
def _all_segments(samples: FloatArray, x: float, y: float) -> float:
    d = np.inf
    for s in range(len(samples) - 1):
        d = min(d, seg_dist(x, y, samples[s, 0], samples[s, 1], samples[s + 1, 0],
                            samples[s + 1, 1]))
    return d


@njit(cache=True, nogil=True)
def _chain_to_polyline(samples: FloatArray, geo: FloatArray, ks: IntArray, js: IntArray,
                       step: float, tol: float) -> float:
    """Largest distance of the dense chain points to the polyline (near the foot points
    first, everything where that exceeds ``tol``)."""
    nseg = len(samples) - 1
    worst = 0.0
    for q in range(len(geo)):
        px, py, tx, ty, kappa, length = geo[q, 0], geo[q, 1], geo[q, 2], geo[q, 3], \
            geo[q, 4], geo[q, 5]
        n = max(math.ceil(length / step), 1) + 1
        k = max(ks[q], 0)
        j = min(js[q], nseg)
        nf = max(j - k + 1, 0)
        u = np.empty(nf)
        v = np.empty(nf)
        for i in range(nf):
            dx = samples[k + i, 0] - px
            dy = samples[k + i, 1] - py
            u[i] = dx * tx + dy * ty
            v[i] = dy * tx - dx * ty
        foot = np.empty(nf)
        foot_positions(u, v, kappa, foot)
        if kappa == 0.0 and nf:
            foot[0] = u[0]  # (a line's foot positions are u itself, the first one too)
        for i in range(1, nf):
            foot[i] = max(foot[i], foot[i - 1])
        ptr = 0
        for i in range(n):
            sg = length if i == n - 1 else i * (length / (n - 1))
            if i == n - 1:
                x, y = geo[q, 6], geo[q, 7]
            else:
                x, y = arc_xy(px, py, tx, ty, kappa, sg)
            if nseg == 0:
                d = math.hypot(x - samples[0, 0], y - samples[0, 1])
            else:
                while ptr < nf and foot[ptr] <= sg:
                    ptr += 1
                d = _segments_near(samples, x, y, k + ptr - 1)
                if not d <= tol:
                    d = _all_segments(samples, x, y)
            worst = max(worst, d)
    return worst


@njit(cache=True, nogil=True)
def dense_deviations(samples: FloatArray, geo: FloatArray, ks: IntArray, js: IntArray,
                     tol: float, step: float) -> tuple[float, float]:
    """Dense two-sided deviation ``(polyline -> chain, chain -> polyline)``.

    ``geo`` ``(P, 8)`` holds each piece's start point, start tangent, curvature, length
    and end point; piece ``q`` stands for samples ``ks[q]..js[q]``. Both sides are sampled
    at ``step``; each dense point is measured exactly against the nearby part of the other
    side (an upper bound of its distance), and again against everything where that
    exceeds ``tol``.
    """
    off = _dense_offsets(samples, step)
    d_p = _polyline_to_chain(samples, geo, ks, js, off)
    worst_p = 0.0
    for i in range(len(d_p)):
        if not d_p[i] <= tol:
            s = int(np.searchsorted(off, i, side="right")) - 1
            x, y = _dense_point(samples, off, s, i)
            for q in range(len(geo)):
                d_p[i] = min(d_p[i], point_arc_distance(
                    x, y, geo[q, 0], geo[q, 1], geo[q, 2], geo[q, 3], geo[q, 4], geo[q, 5],
                    geo[q, 6], geo[q, 7]))
        worst_p = max(worst_p, d_p[i])
    return worst_p, _chain_to_polyline(samples, geo, ks, js, step, tol)
