"""Compiled ranking of a beam level's candidate pieces (:meth:`zwcore.arcs._search.Fitter._rank`).

Each level ranks a few hundred candidates by how far the next piece reaches from their
ends. The reach scan was compiled already; the score, the lexicographic order and the
split of pieces onto straight runs were some fifteen numpy calls per level, more than
the arithmetic. Here they are one loop and three stable sorts (numpy's ``lexsort`` is a
stable sort per key from the last to the first: the same order, ties by index), on the
same figures (``tests/test_arcfast8_kernels.py`` compares the two).
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from zwcore.arcs._kernels import reach_lines

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

__all__ = ["rank_candidates", "stable_lexsort"]


@njit(cache=True, nogil=True, error_model="numpy")
def stable_lexsort(neg_j: IntArray, isarc: NDArray[np.bool_], neg_score: FloatArray,
                   n_over: IntArray) -> IntArray:
    """``numpy.lexsort((neg_j, isarc, neg_score, n_over))``: ``n_over`` the primary key,
    then ``neg_score``, ``isarc`` and ``neg_j``, ties in index order (``(C,)`` each)."""
    order = np.argsort(neg_j, kind="mergesort")
    order = order[np.argsort(isarc[order], kind="mergesort")]
    order = order[np.argsort(neg_score[order], kind="mergesort")]
    return order[np.argsort(n_over[order], kind="mergesort")]


@njit(cache=True, nogil=True, error_model="numpy")
def rank_candidates(samples: FloatArray, cum: FloatArray, ends: FloatArray,
                    t_ends: FloatArray, js: IntArray, b: int, stride: int, wt: float,
                    bonus: FloatArray, kappa: FloatArray, n_over: IntArray,
                    special: NDArray[np.bool_]) -> tuple[IntArray, IntArray]:
    """The order in which candidate pieces are verified, and their reach.

    Candidate ``c`` ends at ``ends[c]`` ``(C, 2)`` with tangent ``t_ends[c]`` standing
    for sample ``js[c]``; ``reach``: the last sample the next piece from there covers
    (:func:`~zwcore.arcs._kernels.reach_lines`, scans at ``stride`` with working
    half-width ``wt``; ``b`` for a candidate at the run's end ``b``). The score is that
    reach's arc length or, where a line from there reaches far, the line's with a 30 %
    bonus on its own length, plus ``bonus[c]``. The order: fewest ``n_over`` (arcs over
    straight runs in the chain; zeros without anchors), then the highest score, lines
    before arcs, the furthest end, the index; pieces onto straight runs
    (``special``) before the rest, each group in that order.
    """
    n = len(js)
    reach, lreach = reach_lines(samples, ends, t_ends, js, b, stride, wt)
    neg_score = np.empty(n)
    neg_j = np.empty(n, dtype=np.int64)
    isarc = np.empty(n, dtype=np.bool_)
    for c in range(n):
        if js[c] >= b:
            reach[c] = b
            lreach[c] = b
        lscore = cum[lreach[c]] + 0.3 * (cum[lreach[c]] - cum[js[c]])
        neg_score[c] = -(max(cum[reach[c]], lscore) + bonus[c])
        neg_j[c] = -js[c]
        isarc[c] = kappa[c] != 0.0
    order = stable_lexsort(neg_j, isarc, neg_score, n_over)
    out = np.empty(n, dtype=np.int64)
    m = 0
    for i in range(n):
        if special[order[i]]:
            out[m] = order[i]
            m += 1
    for i in range(n):
        if not special[order[i]]:
            out[m] = order[i]
            m += 1
    return out, reach
