"""Two-sided deviation of a fitted chain from its polyline, measured densely.

Both sides are sampled at ``tol / 20`` (coarser only beyond two million samples)
and each sample's distance is taken *exactly* to the geometry of the other side
(polyline segments, arcs), but only to the nearby part of it that the fitter's
bookkeeping names: a piece covering samples ``k..j`` is compared with polyline
segments ``k-2..j+2``, and a chain point with the few segments around the foot
point it falls between. Distances to a subset are upper bounds of the true ones,
so the figures are conservative; samples whose local figure exceeds the
tolerance (never on a correct chain) are re-measured against everything.
Cost is linear in the number of samples.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from zwcore.arcs._geometry import (
    arc_points,
    local_uv,
    point_to_arc_distance,
    points_to_segments_distance,
)
from zwcore.arcs._pieces import Piece

FloatArray = NDArray[np.float64]

__all__ = ["densify", "deviations"]


def densify(x: FloatArray, step: float) -> FloatArray:
    """Polyline ``x`` with extra points so that no segment is longer than ``step``."""
    return _densify_idx(x, step)[0]


def _densify_idx(x: FloatArray, step: float) -> tuple[FloatArray, NDArray[np.int64]]:
    """Densified polyline and, per point, the index of the original segment it lies on."""
    seg = np.hypot(*(np.diff(x, axis=0).T))
    n = np.maximum(np.ceil(seg / step).astype(np.int64), 1)
    i = np.repeat(np.arange(len(seg)), n)
    if np.all(n == 1):
        return x, np.concatenate([i, [max(len(seg) - 1, 0)]])
    f = np.concatenate([np.arange(m) / m for m in n]) if len(n) < 64 else (
        np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)) / np.repeat(n, n)
    out = x[i] + f[:, None] * (x[i + 1] - x[i])
    return np.vstack([out, x[-1:]]), np.concatenate([i, [len(seg) - 1]])


def _piece_points(pc: Piece, step: float) -> tuple[FloatArray, FloatArray]:
    n = max(math.ceil(pc.length / step), 1) + 1
    sig = np.linspace(0.0, pc.length, n)
    pts = arc_points(pc.p, pc.t, pc.kappa, sig)
    pts[-1] = pc.end
    return pts, sig


def _foot_positions(pc: Piece, pts: FloatArray) -> FloatArray:
    """Arc-length positions along ``pc`` of ``pts`` (unwrapped from the first)."""
    u, v = local_uv(pc.p, pc.t, pts)
    if pc.kappa == 0.0:
        return u
    phi = np.arctan2(pc.kappa * u, 1.0 - pc.kappa * v)
    phi[0] = 0.0
    return np.asarray(np.unwrap(phi) / pc.kappa)


def _dist_all_segments(pts: FloatArray, poly: FloatArray) -> FloatArray:
    out = np.full(len(pts), np.inf)
    a, b = poly[:-1], poly[1:]
    chunk = max(1, int(2e6 // max(len(a), 1)))
    for i in range(0, len(pts), chunk):
        out[i : i + chunk] = points_to_segments_distance(pts[i : i + chunk], a, b).min(axis=1)
    return out


def deviations(samples: FloatArray, pieces: Sequence[Piece], tol: float) -> tuple[float, float]:
    """Dense two-sided deviation ``(polyline -> chain, chain -> polyline)``.

    ``samples`` is the polyline the pieces were fitted to (piece ``k``/``j`` index it).
    """
    nseg = len(samples) - 1
    length = float(np.hypot(*(np.diff(samples, axis=0).T)).sum())
    total = length + sum(pc.length for pc in pieces)
    step = max(tol / 20.0, total / 2e6)
    # polyline -> chain
    dpoly, sid = _densify_idx(samples, step)
    d_p = np.full(len(dpoly), np.inf)
    for pc in pieces:
        lo = int(np.searchsorted(sid, max(pc.k - 2, 0), side="left"))
        hi = int(np.searchsorted(sid, min(pc.j + 2, nseg), side="right"))
        if hi > lo:
            dd = point_to_arc_distance(dpoly[lo:hi], pc.p, pc.t, pc.kappa, pc.length)
            np.minimum(d_p[lo:hi], dd, out=d_p[lo:hi])
    hot = np.flatnonzero(d_p > tol)
    if hot.size:
        best = np.full(hot.size, np.inf)
        for pc in pieces:
            best = np.minimum(best, point_to_arc_distance(dpoly[hot], pc.p, pc.t, pc.kappa,
                                                          pc.length))
        d_p[hot] = best
    # chain -> polyline (segment figures gathered from 1-D arrays: gathering rows of
    # the (M, 2) arrays per offset costs more than the arithmetic)
    d_c_max = 0.0
    ax, ay = samples[:-1, 0].copy(), samples[:-1, 1].copy()
    abx, aby = samples[1:, 0] - ax, samples[1:, 1] - ay
    den_all = np.maximum(abx * abx + aby * aby, 1e-300)
    for pc in pieces:
        cpts, sig = _piece_points(pc, step)
        k, j = max(pc.k, 0), min(pc.j, nseg)
        if nseg == 0:
            d = np.hypot(*(cpts - samples[0]).T)
        else:
            foot = np.maximum.accumulate(_foot_positions(pc, samples[k : j + 1]))
            m = k + np.searchsorted(foot, sig, side="right") - 1
            d = np.full(len(cpts), np.inf)
            cx, cy = cpts[:, 0], cpts[:, 1]
            for off in range(-3, 4):
                s = np.clip(m + off, 0, nseg - 1)
                sx, sy = abx[s], aby[s]
                apx, apy = cx - ax[s], cy - ay[s]
                f = np.clip((apx * sx + apy * sy) / den_all[s], 0.0, 1.0)
                np.minimum(d, np.hypot(apx - f * sx, apy - f * sy), out=d)
            hotc = np.flatnonzero(d > tol)
            if hotc.size:
                d[hotc] = _dist_all_segments(cpts[hotc], samples)
        d_c_max = max(d_c_max, float(d.max()))
    return float(d_p.max()), d_c_max
