"""Ranking of a beam level's candidate pieces (:meth:`zwcore.arcs._search.Fitter._rank`).

Each level ranks a few hundred candidates by how far the next piece reaches from their
ends. The reach scan was compiled already; the scores and sort keys were some ten numpy
calls per level more, now one loop in the same kernel call (:func:`rank_keys`, the same
figures: ``tests/test_arcfast8_kernels.py`` compares the two). The sort stays numpy's
``lexsort``: numba's sorts took twice its time on these keys (a third of the scores
tie).
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

__all__ = ["rank_candidates", "rank_keys", "rank_level"]


@njit(cache=True, nogil=True, error_model="numpy")
def rank_keys(samples: FloatArray, cum: FloatArray, ends: FloatArray, t_ends: FloatArray,
              js: IntArray, b: int, stride: int, wt: float, bonus: FloatArray,
              kappa: FloatArray) -> tuple[IntArray, FloatArray, NDArray[np.bool_], IntArray]:
    """The reach of each candidate piece and its sort keys: ``(reach, -score, is an arc,
    -js)``, each ``(C,)``.

    Candidate ``c`` ends at ``ends[c]`` ``(C, 2)`` with tangent ``t_ends[c]`` standing
    for sample ``js[c]``; ``reach``: the last sample the next piece from there covers
    (:func:`~zwcore.arcs._kernels.reach_lines`, scans at ``stride`` with working
    half-width ``wt``; ``b`` for a candidate at the run's end ``b``). The score is that
    reach's arc length or, where a line from there reaches far, the line's with a 30 %
    bonus on its own length, plus ``bonus[c]``.
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
    return reach, neg_score, isarc, neg_j


def rank_candidates(samples: FloatArray, cum: FloatArray, ends: FloatArray,
                    t_ends: FloatArray, js: IntArray, b: int, stride: int, wt: float,
                    bonus: FloatArray, kappa: FloatArray, n_over: IntArray | None,
                    special: NDArray[np.bool_]) -> tuple[IntArray, IntArray]:
    """The order in which candidate pieces are verified, and their reach
    (:func:`rank_keys`): fewest ``n_over`` (arcs over straight runs in the chain; None:
    no anchors), then the highest score, lines before arcs, the furthest end, the index
    (numpy's ``lexsort``, faster than numba's sorts on a few hundred keys with many
    ties); pieces onto straight runs (``special``) before the rest, each group in that
    order."""
    reach, neg_score, isarc, neg_j = rank_keys(samples, cum, ends, t_ends, js, b, stride,
                                               wt, bonus, kappa)
    if n_over is None:
        return np.lexsort((neg_j, isarc, neg_score)), reach
    order = np.lexsort((neg_j, isarc, neg_score, n_over))
    if special.any():
        order = np.concatenate([order[special[order]], order[~special[order]]])
    return order, reach


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
    n_over = None
    if sr is not None and before is not None:
        sp = sp_all[c.si]
        chord = np.hypot(c.end[:, 0] - sp[:, 0], c.end[:, 1] - sp[:, 1])
        flat = sr.are_over(sk_all[c.si], js, c.kappa, approx_lengths(c, chord))
        # arcs over straight runs in the chain so far, this candidate's included
        n_over = before[c.si] + flat
    return rank_candidates(
        band.samples, band.cum, np.ascontiguousarray(c.end), np.ascontiguousarray(c.t_end),
        np.asarray(js, dtype=np.int64), b, band.reach_stride, band.work_tol, c.bonus,
        c.kappa, n_over, c.special)
