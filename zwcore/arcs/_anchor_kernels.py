"""Compiled kernels of the anchors of a refit (:mod:`zwcore.arcs._anchors`).

The beam asks, for every candidate piece of a level (a few hundred), whether it lies
over one of the run's straight runs; in numpy that was a dozen array operations per
anchor and level. The kernel does the same comparisons of the same figures (differences
of the cumulative polyline length, exact equality of points), so its answers are those
of the numpy formulation (``tests/test_arcfast8_kernels.py`` compares the two). The
fillet between two anchors' lines measures the input's distance to the lines' vertex
over the segments after each junction: one loop, no temporaries. A landing biarc tries a
few landing points in one call (:func:`landing_pair`).
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from zwcore.arcs._biarc import biarc
from zwcore.arcs._kernels import seg_dist

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

__all__ = ["anchors_hit", "landing_pair", "min_segment_distance"]


@njit(cache=True, nogil=True, error_model="numpy")
def anchors_hit(cum: FloatArray, samples: FloatArray, k: IntArray, j: IntArray,
                i0s: IntArray, i1s: IntArray, qs: FloatArray) -> NDArray[np.bool_]:
    """Which pieces over samples ``k[c]..j[c]`` ``(C,)`` cover more than half of an
    anchor (samples ``i0s[a]..i1s[a]``, line through ``qs[a]`` ``(A, 2)``) or lie on an
    anchor whose line passes through their end sample at that end of the anchor
    (:meth:`~zwcore.arcs._anchors.StraightRuns.is_over` without the flatness test and
    the arc test): ``(C,)`` booleans. ``cum``: the samples' cumulative length ``(M,)``.
    """
    out = np.zeros(len(k), dtype=np.bool_)
    for c in range(len(k)):
        kc = k[c]
        jc = j[c]
        for a in range(len(i0s)):
            i0 = i0s[a]
            i1 = i1s[a]
            over = cum[min(jc, i1)] - cum[max(kc, i0)]
            if over > 0.5 * (cum[i1] - cum[i0]):
                out[c] = True
                break
            if i0 <= kc and jc <= i1 and (
                    (jc == i1 and samples[jc, 0] == qs[a, 0] and samples[jc, 1] == qs[a, 1])
                    or (kc == i0 and samples[kc, 0] == qs[a, 0]
                        and samples[kc, 1] == qs[a, 1])):
                out[c] = True
                break
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def min_segment_distance(samples: FloatArray, x: float, y: float, k: int, hi: int) -> float:
    """Smallest distance of ``(x, y)`` to the polyline segments ``k..hi-1`` of
    ``samples`` ``(M, 2)`` (each as
    :func:`~zwcore.arcs._geometry.points_to_segments_distance` measures it); 0 when
    there is none."""
    if hi <= k:
        return 0.0
    d = np.inf
    for s in range(k, hi):
        d = min(d, seg_dist(x, y, samples[s, 0], samples[s, 1], samples[s + 1, 0],
                            samples[s + 1, 1]))
    return d


@njit(cache=True, nogil=True, error_model="numpy")
def landing_pair(samples: FloatArray, p0: FloatArray, t0: FloatArray, k: int, e: float,
                 ms: IntArray, p1s: FloatArray, d: FloatArray, splits: FloatArray, tol: float,
                 step0: float, kmin: float, kcap: float) -> tuple[int, FloatArray, int]:
    """The first landing point ``i`` (sample ``ms[i]``, point ``p1s[i]`` ``(L, 2)``) that
    a verified biarc from ``(p0, t0)`` (sample ``k``, distance ``e``) reaches along
    ``d`` with both radii at least ``tol`` (:func:`zwcore.arcs._biarc.biarc`, the same
    tries in the same order as one call per landing point): ``(i, figures, m)`` as
    :func:`~zwcore.arcs._biarc.biarc` returns them (``i = -1``: none)."""
    for i in range(len(ms)):
        got, f, m = biarc(samples, p0, t0, k, e, ms[i], d, p1s[i], splits, tol, step0, kmin,
                          kcap)
        if got < 0 or max(abs(f[0]), abs(f[7])) > 1.0 / tol:
            continue
        return i, f, m
    return -1, np.zeros(10), 0
