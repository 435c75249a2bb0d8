"""Two-sided deviation of a fitted chain from its polyline, measured densely.

Both sides are sampled at ``tol / 20`` (coarser only beyond two million samples)
and each sample's distance is taken *exactly* to the geometry of the other side
(polyline segments, arcs), but only to the nearby part of it that the fitter's
bookkeeping names: a piece covering samples ``k..j`` is compared with polyline
segments ``k-2..j+2``, and a chain point with the few segments around the foot
point it falls between. Distances to a subset are upper bounds of the true ones,
so the figures are conservative; samples whose local figure exceeds the
tolerance (never on a correct chain) are re-measured against everything.
Samples that cannot raise the maximum found so far are jumped over (a bound of how
fast the distance grows from the last measured sample: 1-Lipschitz, and slower along
a nearly parallel piece or segment), so the figure is the maximum over all samples
at the cost of a few measurements per polyline segment where the band is not full.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from zwcore.arcs._dense import dense_deviations, polyline_length
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


def deviations(samples: FloatArray, pieces: Sequence[Piece], tol: float) -> tuple[float, float]:
    """Dense two-sided deviation ``(polyline -> chain, chain -> polyline)``.

    ``samples`` ``(M, 2)`` is the polyline the pieces were fitted to (piece ``k``/``j``
    index it); both sides are sampled at ``tol / 20`` (coarser beyond two million
    points), measured by :func:`zwcore.arcs._dense.dense_deviations`.
    """
    samples = np.ascontiguousarray(samples, dtype=np.float64)
    chain = sum(pc.length for pc in pieces)
    step = tol / 20.0
    # the figures' step is coarser only beyond two million points: a compiled sum, a
    # millionth below that bound, decides without numpy's five calls (its own sum, in
    # pairwise order, where the bound is that close)
    if not polyline_length(samples) + chain < 2e6 * step * (1.0 - 1e-6):
        length = float(np.hypot(*(np.diff(samples, axis=0).T)).sum())
        step = max(step, (length + chain) / 2e6)
    geo = np.array([[pc.p[0], pc.p[1], pc.t[0], pc.t[1], pc.kappa, pc.length, pc.end[0],
                     pc.end[1]] for pc in pieces], dtype=np.float64).reshape(-1, 8)
    ks = np.array([pc.k for pc in pieces], dtype=np.int64)
    js = np.array([pc.j for pc in pieces], dtype=np.int64)
    d_p, d_c = dense_deviations(samples, geo, ks, js, float(tol), float(step))
    return float(d_p), float(d_c)
