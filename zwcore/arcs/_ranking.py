"""Compiled ranking of a beam level's candidate pieces (:meth:`zwcore.arcs._search.Fitter._rank`).

Each level ranks a few hundred candidates by how far the next piece reaches from their
ends. The reach scan was compiled already; the score, the lexicographic order and the
split of pieces onto straight runs were some fifteen numpy calls per level, more than
the arithmetic. Here they are one loop and one sort by the same keys (numpy's
``lexsort``: the same order, ties by index), on the same figures
(``tests/test_arcfast8_kernels.py`` compares the two).
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from zwcore.arcs._anchors import StraightRuns
from zwcore.arcs._kernels import reach_lines
from zwcore.arcs._pieces import ToleranceBand
from zwcore.arcs._states import Cands, approx_lengths

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

__all__ = ["rank_candidates", "rank_level", "stable_lexsort"]


@njit(cache=True, nogil=True, error_model="numpy")
def stable_lexsort(neg_j: IntArray, isarc: NDArray[np.bool_], neg_score: FloatArray,
                   n_over: IntArray) -> IntArray:
    """``numpy.lexsort((neg_j, isarc, neg_score, n_over))``: ``n_over`` the primary key,
    then ``neg_score``, ``isarc`` and ``neg_j``, ties in index order (``(C,)`` each; the
    scores not NaN).

    The keys with the index make a total order, so any sort by them gives lexsort's
    order: the scores by one quicksort, each run of equal scores by the rest packed
    into one integer (unique: the index is in it), then a counting sort by ``n_over``
    (stable, few distinct values).
    """
    n = len(neg_j)
    order = np.argsort(neg_score)
    if n == 0:
        return order
    jmin = neg_j.min()
    span = neg_j.max() - jmin + 1
    i = 0
    while i < n:
        e = i + 1
        while e < n and neg_score[order[e]] == neg_score[order[i]]:
            e += 1
        if e - i > 1:
            key = np.empty(e - i, dtype=np.int64)
            for m in range(i, e):
                c = order[m]
                key[m - i] = ((1 if isarc[c] else 0) * span + (neg_j[c] - jmin)) * n + c
            key.sort()
            for m in range(i, e):
                order[m] = key[m - i] % n
        i = e
    lo = n_over.min()
    nb = n_over.max() - lo + 1
    if nb == 1:
        return order
    start = np.zeros(nb + 1, dtype=np.int64)
    for c in range(n):
        start[n_over[c] - lo + 1] += 1
    for v in range(nb):
        start[v + 1] += start[v]
    out = np.empty(n, dtype=np.int64)
    for m in range(n):
        c = order[m]
        v = n_over[c] - lo
        out[start[v]] = c
        start[v] += 1
    return out


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


def rank_level(
    band: ToleranceBand, c: Cands, b: int, sp_all: FloatArray, sk_all: IntArray,
    sr: StraightRuns | None, before: IntArray | None,
) -> tuple[IntArray, IntArray]:
    """The order in which a level's candidates ``c`` are verified, and their reach
    (:func:`rank_candidates`): with straight runs to follow (``sr``), by the arcs over
    them in each candidate's chain first, ``before[s]`` those in state ``s``'s chain
    (``sp_all, sk_all``: the states' points and samples as arrays).
    """
    js = c.j
    if sr is None or before is None:
        n_over = np.zeros(len(js), dtype=np.int64)
    else:
        sp = sp_all[c.si]
        chord = np.hypot(c.end[:, 0] - sp[:, 0], c.end[:, 1] - sp[:, 1])
        flat = sr.are_over(sk_all[c.si], js, c.kappa, approx_lengths(c, chord))
        # arcs over straight runs in the chain so far, this candidate's included
        n_over = before[c.si] + flat
    return rank_candidates(
        band.samples, band.cum, np.ascontiguousarray(c.end), np.ascontiguousarray(c.t_end),
        np.asarray(js, dtype=np.int64), b, band.reach_stride, band.work_tol, c.bonus,
        c.kappa, n_over, c.special)
