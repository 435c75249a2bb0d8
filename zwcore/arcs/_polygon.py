"""Coarse polygons: a line along every edge and a tangent fillet at every vertex.

Where every vertex of a run turns so sharply, at the tolerance scale, that the largest
fillet the tolerance allows (tangent length ``L = w tol / tan(theta / 4)``: the fillet
and the legs it replaces are ``L tan(theta / 4)`` apart at most) fits on its legs beside
its neighbours' fillets, no arc can span two vertices, and the chain is the filleted
polygon: one line per edge, one arc per vertex. It is built in closed form, cost linear
in the vertices, instead of by the beam search (whose cost per piece is the same as on
any curve). The lines lie on the edges and the fillets within ``w tol`` of them, so the
chain is within the tolerance both ways by construction; :func:`zwcore.arcs.fit_arcs`
measures it densely like every chain and refits the run with the beam if it failed.

A loop starts and ends at its first point, a vertex: the chain leaves it along the first
edge, and a biarc from the last edge arriving at it with that direction replaces the
vertex's fillet (verified pieces of :meth:`~zwcore.arcs._pieces.ToleranceBand.biarc`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from zwcore.arcs._geometry import arc_points
from zwcore.arcs._pieces import Piece, ToleranceBand

FloatArray = NDArray[np.float64]

__all__ = ["polygon_run"]

#: share of the tolerance a fillet may use
_WORK = 0.9
#: directions turning less than this (radians) between samples are one edge
_STRAIGHT = 1e-9
#: a run needs this many vertices to be worth the closed form
_MIN_VERTICES = 3


def _turn(d0: FloatArray, d1: FloatArray) -> FloatArray:
    return np.arctan2(d0[:, 0] * d1[:, 1] - d0[:, 1] * d1[:, 0], (d0 * d1).sum(axis=1))


@njit(cache=True, nogil=True, error_model="numpy")
def _fillets_clash(S: FloatArray, work_tol: float, slack: float) -> bool:
    """True when two neighbouring inner samples of ``S`` ``(n, 2)`` both turn (clearly
    more than :data:`_STRAIGHT`) and their largest fillets (tangent lengths ``work_tol /
    tan(theta / 4)``) overlap on the edge between them, by more than a millionth of it:
    then :func:`polygon_run` has no filleted polygon (that edge's ``need`` exceeds its
    gap; the margins, a millionth and ``slack`` for the rounding of the run's cumulative
    lengths, cover the rounding of its own figures). One pass, stopping at the
    first clash: most runs that are not coarse polygons (any finely sampled curve) are
    told at their first vertices instead of after a dozen whole-run array operations."""
    n = len(S)
    prev_l = -1.0  # the previous sample's tangent length (-1: not a clear vertex)
    for i in range(1, n - 1):
        ax, ay = S[i, 0] - S[i - 1, 0], S[i, 1] - S[i - 1, 1]
        bx, by = S[i + 1, 0] - S[i, 0], S[i + 1, 1] - S[i, 1]
        la, lb = math.hypot(ax, ay), math.hypot(bx, by)
        if not (la > 0.0 and lb > 0.0):
            return False
        th = abs(math.atan2(ax * by - ay * bx, ax * bx + ay * by))
        if th > 2.0 * _STRAIGHT:
            cur = work_tol / math.tan(0.25 * th)
            if prev_l >= 0.0 and prev_l + cur > la * (1.0 + 1e-6) + slack:
                return True
            prev_l = cur
        else:
            prev_l = -1.0
    return False


def polygon_run(band: ToleranceBand, a: int, b: int, loop: bool) -> list[Piece] | None:
    """The filleted polygon through samples ``a..b`` (see the module notes), or None
    when the run is not a coarse polygon at this tolerance or a loop's seam fails."""
    S = band.samples[a : b + 1]
    if len(S) < 3 or _fillets_clash(S, _WORK * band.tol, 1e-13 * float(band.cum[b])):
        return None
    d = np.diff(S, axis=0)
    ln = np.hypot(d[:, 0], d[:, 1])
    if not np.all(ln > 0.0):
        return None
    u = d / ln[:, None]
    if loop:
        # the seam (first sample, repeated at the end) is a vertex too
        turn = _turn(np.vstack([u[-1:], u[:-1]]), u)
        vi = np.flatnonzero(np.abs(turn) > _STRAIGHT)
        if vi.size == 0 or vi[0] != 0:
            return None
    else:
        turn = np.concatenate([[0.0], _turn(u[:-1], u[1:])])
        vi = np.flatnonzero(np.abs(turn) > _STRAIGHT)
    if vi.size < _MIN_VERTICES:
        return None
    th = turn[vi]
    if np.any(np.abs(th) > math.pi - 1e-3):
        return None
    cum = band.cum[a : b + 1] - band.cum[a]
    pos = cum[vi]
    L = _WORK * band.tol / np.tan(0.25 * np.abs(th))
    # edges between consecutive vertices (and the run's ends) hold both fillets
    if loop:
        gaps = np.diff(np.concatenate([pos, [cum[-1]]]))
        need = L + np.roll(L, -1)
        need[-1] = L[-1] + 3.0 * L[0]  # room for the seam's biarc
        need[0] = L[1]
    else:
        gaps = np.diff(np.concatenate([[0.0], pos, [cum[-1]]]))
        need = np.concatenate([[L[0]], L[:-1] + L[1:], [L[-1]]])
    if np.any(need > gaps):
        return None
    pieces = _fillets(S, u, vi, th, L, cum, a, loop)
    if loop:
        return _close_seam(band, S, u, vi, L, cum, a, pieces)
    return pieces


def _index_at(cum: FloatArray, s: float) -> int:
    """The last sample at or before arc-length position ``s``."""
    return int(np.searchsorted(cum, s, side="right")) - 1


def _fillets(
    S: FloatArray, u: FloatArray, vi: NDArray[np.int64], th: FloatArray, L: FloatArray,
    cum: FloatArray, a: int, loop: bool,
) -> list[Piece]:
    """Line, fillet, line, ... from the first sample (a loop: its fillet left out) to the
    last; sample indices shifted by ``a``."""
    n_last = len(S) - 1
    pieces: list[Piece] = []
    cur_p = S[0].copy()
    cur_s = 0.0
    first = 1 if loop else 0
    for m in range(first, len(vi)):
        v = int(vi[m])
        din, dout = u[v - 1], u[v]
        s_in = cum[v] - L[m]
        p_in = S[v] - L[m] * din
        if s_in > cur_s:
            pieces.append(_piece(cur_p, din, 0.0, s_in - cur_s, cur_s, s_in, cum, a, p_in,
                                 din))
        r = L[m] / math.tan(0.5 * abs(th[m]))
        kap = math.copysign(1.0 / r, th[m])
        length = r * abs(th[m])
        end = arc_points(p_in, din, kap, np.array([length]))[0]
        pieces.append(_piece(p_in, din, kap, length, s_in, cum[v] + L[m], cum, a, end,
                             dout))
        cur_p, cur_s = end, cum[v] + L[m]
    if cum[n_last] > cur_s:
        dl = u[-1]
        pieces.append(_piece(cur_p, dl, 0.0, cum[n_last] - cur_s, cur_s, cum[n_last], cum,
                             a, S[n_last].copy(), dl))
    return pieces


def _piece(
    p: FloatArray, t: FloatArray, kappa: float, length: float, s0: float, s1: float,
    cum: FloatArray, a: int, end: FloatArray, t_end: FloatArray,
) -> Piece:
    """A piece from polyline position ``s0`` to ``s1`` (the samples it stands for)."""
    k = max(_index_at(cum, s0), 0)
    j = min(_index_at(cum, s1) + 1, len(cum) - 1)
    return Piece(p.copy(), t.copy(), kappa, length, a + k, a + j, end.copy(), t_end.copy(),
                 0.0)


def _close_seam(
    band: ToleranceBand, S: FloatArray, u: FloatArray, vi: NDArray[np.int64], L: FloatArray,
    cum: FloatArray, a: int, pieces: list[Piece],
) -> list[Piece] | None:
    """A loop's seam at its first sample: the chain leaves it along the first edge and
    the last line ends in a biarc arriving at it with that direction (C1 at the seam)."""
    n_last = len(S) - 1
    if len(pieces) < 2 or pieces[0].kappa != 0.0 or pieces[-1].kappa != 0.0:
        return None
    tail = pieces[-1]
    tail_s0 = cum[vi[-1]] + L[-1]
    for f in (1.5, 2.0, 3.0, 1.0):
        ka = _index_at(cum, cum[-1] - f * L[0])
        if ka <= 0 or cum[ka] <= tail_s0:
            continue
        two = band.biarc(S[ka].copy(), u[-1], a + ka, 0.0, a + n_last, u[0])
        if two is None:
            continue
        into = _piece(tail.p, u[-1], 0.0, cum[ka] - tail_s0, tail_s0, cum[ka], cum, a,
                      S[ka], u[-1])
        out = [*pieces[:-1], into, *two]
        out[-1].end = S[n_last].copy()
        return out
    return None
