"""Fallback of the arc fit that is valid by construction: a filleted polyline.

When the beam of :mod:`zwcore.arcs._search` cannot place a verified piece from any
junction state, the stretch ahead is covered by the sample polyline itself with
every interior vertex replaced by a tangent fillet arc (lines in between). For a
vertex turning by ``theta`` with tangent length ``L`` the fillet and the two leg
portions it replaces are within ``L tan(theta / 4)`` of each other, both ways
(the farthest points are the vertex and the arc's midpoint), so choosing
``L <= budget / tan(theta / 4)`` keeps the fillet inside the band; the lines lie
on the polyline. The stretch joins the chain C1 at both ends through *virtual*
vertices: ``W = p + eps t`` continues the incoming tangent ``t`` (its fillet
uses the whole leg ``p -> W``, so it starts exactly at ``p`` with tangent
``t``), and at a closing loop ``W' = q - eps' t_end`` arrives with the required
tangent. Replacing original vertices by virtual ones moves the polyline by a
known amount (``legdev``), which is taken off the fillet budget of the
neighbouring vertices. Exact reversals (turn of ``pi``, no fillet exists) get
an extra vertex beside them; collinear and repeated vertices are dropped.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from zwcore.arcs._geometry import arc_points
from zwcore.arcs._pieces import Piece

FloatArray = NDArray[np.float64]

__all__ = ["fillet_stretch"]

#: turns closer than this to pi are treated as reversals (an extra vertex beside them)
_REVERSAL = 1e-3
#: share of the remaining band a fillet may use
_SAFETY = 0.85
#: turns below this (radians) get no fillet
_STRAIGHT = 1e-10
#: lines shorter than this many tolerances are left out of the fallback chain
_SHORT = 1e-7


def _turn(d0: FloatArray, d1: FloatArray) -> float:
    return math.atan2(float(d0[0] * d1[1] - d0[1] * d1[0]), float(d0 @ d1))


def _unit(v: FloatArray) -> FloatArray:
    return v / float(np.hypot(v[0], v[1]))


def fillet_stretch(
    S: FloatArray,
    tol: float,
    p: FloatArray,
    t: FloatArray,
    k: int,
    m: int,
    mode: str,
    t_end: FloatArray | None = None,
) -> tuple[list[Piece], tuple[FloatArray, FloatArray, float] | None]:
    """Pieces from junction ``(p, t)`` (standing for sample ``k``) along samples ``k..m``.

    ``mode``: ``"sample"`` ends exactly at ``S[m]`` (free tangent); ``"tangent"``
    ends at ``S[m]`` with tangent ``t_end``; ``"state"`` stops on the last leg
    shortly before ``S[m]`` and returns the end state ``(point, tangent, e)``
    with ``e`` its distance from ``S[m]`` (the chain then continues from there).
    """
    poly = _virtual_polyline(S, tol, p, t, k, m, mode, t_end)
    if mode == "tangent" and _no_length(poly, tol):
        assert t_end is not None
        loop = _loop_circle(S, tol, p, t, k, m, t_end)
        if loop is not None:
            return [loop], None
    _simplify(poly, tol)
    _split_reversals(poly, tol)
    fil = _fillets(poly, tol, mode)
    return _assemble(poly, fil, S, tol, k, m, mode, t_end)


@dataclass
class _Polyline:
    """The polyline the fallback fillets: vertices ``V``, the largest displacement ``D``
    of each leg from the original polyline (one per leg), whether the first virtual
    vertex is pinned and the index of the pinned last one (-1: none)."""

    V: list[FloatArray]
    D: list[float]
    pinned_first: bool
    n_pin_last: int

    def pinned(self, x: int) -> bool:
        """True for a pinned vertex (its fillet joins the chain C1)."""
        return (x == 1 and self.pinned_first) or x == self.n_pin_last


@dataclass
class _Fillets:
    """Legs, their directions, the tangent lengths ``L`` and turns ``th`` per vertex and
    the distance ``e_last`` the chain stops short of the last vertex."""

    legs: list[float]
    dirs: list[FloatArray]
    L: list[float]
    th: list[float]
    e_last: float


def _near_run(S: FloatArray, at: FloatArray, idx: range, tol: float) -> tuple[int, float]:
    """First index of ``idx`` whose sample is further than ``0.2 tol`` from ``at``, and
    the largest distance of the nearer ones passed (``-1`` for the index when none)."""
    near = 0.0
    for i in idx:
        d = float(np.hypot(*(S[i] - at)))
        if d > 0.2 * tol:
            return i, near
        near = max(near, d)
    return -1, near


def _reversal_vertex(w: FloatArray, dv: FloatArray, tt: FloatArray, away: bool,
                     h: float) -> FloatArray | None:
    """A vertex ``h`` beside the virtual vertex ``w`` when the leg ``dv`` and the pinned
    tangent ``tt`` turn by nearly pi there (a reversal: the vertex makes room for its
    fillet), on the side of ``dv`` (``away``: the other side), else None."""
    if not (float(np.hypot(*dv)) > 0.0 and abs(_turn(tt, _unit(dv))) > math.pi - 0.1):
        return None
    nrm = np.array([-tt[1], tt[0]])
    if (float(nrm @ dv) > 0.0) if away else (float(nrm @ dv) < 0.0):
        nrm = -nrm
    return w + h * nrm


def _virtual_polyline(
    S: FloatArray, tol: float, p: FloatArray, t: FloatArray, k: int, m: int, mode: str,
    t_end: FloatArray | None,
) -> _Polyline:
    """The polyline ``p .. S[m]`` with the virtual vertices that join it C1."""
    q = S[m]
    # first original vertex clearly away from p; nearer ones are replaced by the
    # virtual leg W -> S[i] (convexity bounds the move by their distance from W)
    near = float(np.hypot(*(S[k] - p)))
    i, near_p = _near_run(S, p, range(k + 1, m), tol)
    i = m if i < 0 else i
    near = max(near, near_p)
    # last original vertex clearly away from q (only when the end tangent is pinned)
    j = m - 1
    near_end = 0.0
    if mode == "tangent":
        j, near_end = _near_run(S, q, range(m - 1, i - 1, -1), tol)
        j = i - 1 if j < 0 else j
    mids = [S[x] for x in range(i, j + 1)] if mode == "tangent" else [S[x] for x in range(i, m)]
    first_far = mids[0] if mids else q
    if mode == "tangent" and not mids:
        near = max(near, near_end)
    room = max(tol - near, 0.0)
    eps = min(0.08 * room, 0.3 * float(np.hypot(*(first_far - p))))
    # virtual vertices and their displacement from the original vertices they stand for;
    # a leg deviates from the original polyline by at most its ends' displacements
    verts: list[FloatArray] = [p.copy()]
    disp: list[float] = [near]
    pinned_first = eps > 0.0
    if pinned_first:
        w = p + eps * t
        verts.append(w)
        disp.append(near + eps)
        side = _reversal_vertex(w, first_far - w, t, False, 2.5 * eps)
        if side is not None:
            verts.append(side)
            disp.append(near + eps + 2.5 * eps)
    verts.extend(mids)
    disp.extend([0.0] * len(mids))
    pinned_last = False
    if mode == "tangent":
        assert t_end is not None
        room_e = max(tol - near_end, 0.0)
        eps_e = min(0.08 * room_e, 0.3 * float(np.hypot(*(q - verts[-1]))))
        if eps_e > 0.0:
            pinned_last = True
            w2 = q - eps_e * t_end
            side = _reversal_vertex(w2, w2 - verts[-1], t_end, True, 2.5 * eps_e)
            if side is not None:
                verts.append(side)
                disp.append(near_end + eps_e + 2.5 * eps_e)
            verts.append(w2)
            disp.append(near_end + eps_e)
    verts.append(q.copy())
    disp.append(near_end)
    legdev = [max(disp[x], disp[x + 1]) for x in range(len(verts) - 1)]
    return _Polyline(verts, legdev, pinned_first, len(verts) - 2 if pinned_last else -1)


def _no_length(poly: _Polyline, tol: float) -> bool:
    """The virtual polyline has no length to fillet (its legs add up to at most
    ``_SHORT`` tolerances): a loop closing where it starts, every sample near there."""
    V = poly.V
    return sum(float(np.hypot(*(b - a))) for a, b in itertools.pairwise(V)) <= _SHORT * tol


def _loop_circle(
    S: FloatArray, tol: float, p: FloatArray, t: FloatArray, k: int, m: int,
    t_end: FloatArray,
) -> Piece | None:
    """A full circle from ``p`` with tangent ``t`` back to ``S[m]`` (standing for
    samples ``k..m``), when the stretch closes on itself with that tangent and every
    sample is within ``near < tol`` of ``p``, else None. A radius of ``(tol - near) / 4``
    keeps it inside the band both ways: the circle's points are within its diameter
    ``(tol - near) / 2`` of ``p``, a point of the polyline, and every point of the
    polyline is within ``near`` of ``p``, a point of the circle. (A polyline of no
    length has no vertex to fillet: filleting it gave one line of length zero.)"""
    q = S[m]
    near = float(np.hypot(S[k : m + 1, 0] - p[0], S[k : m + 1, 1] - p[1]).max())
    if not (float(np.hypot(*(q - p))) <= _SHORT * tol and float(t @ t_end) > 1.0 - 1e-12
            and near < tol):
        return None
    r = 0.25 * (tol - near)
    return Piece(p.copy(), t.copy(), 1.0 / r, 2.0 * math.pi * r, k, m, q.copy(),
                 t_end.copy(), 0.0)


def _simplify(poly: _Polyline, tol: float) -> None:
    """Drop repeated and collinear vertices (never the pinned ones), in place."""
    verts, legdev = poly.V, poly.D
    V: list[FloatArray] = [verts[0]]
    D: list[float] = []
    cur = legdev[0]
    n_pin_last = poly.n_pin_last
    for x in range(1, len(verts) - 1):
        pinned = poly.pinned(x)
        a, b, c = V[-1], verts[x], verts[x + 1]
        lab = float(np.hypot(*(b - a)))
        lbc = float(np.hypot(*(c - b)))
        if not pinned:
            if lab <= 1e-12 * tol:
                cur = max(cur, legdev[x]) + lab
                continue
            if lbc > 0.0:
                cr = abs(float((b - a)[0] * (c - b)[1] - (b - a)[1] * (c - b)[0]))
                dist = cr / max(lab, lbc) if max(lab, lbc) > 0 else 0.0
                if dist <= 1e-9 * tol and float((b - a) @ (c - b)) > 0.0:
                    cur = max(cur, legdev[x]) + dist
                    continue
        V.append(b)
        D.append(cur)
        cur = legdev[x]
        if pinned and x == poly.n_pin_last:
            n_pin_last = len(V) - 1
    V.append(verts[-1])
    D.append(cur)
    poly.V, poly.D, poly.n_pin_last = V, D, n_pin_last


def _split_reversals(poly: _Polyline, tol: float) -> None:
    """Exact reversals: a vertex beside them, in place."""
    V, D = poly.V, poly.D
    x = 1
    while x < len(V) - 1:
        d0 = V[x] - V[x - 1]
        d1 = V[x + 1] - V[x]
        l0, l1 = float(np.hypot(*d0)), float(np.hypot(*d1))
        if (not poly.pinned(x) and l0 > 0 and l1 > 0
                and abs(_turn(d0 / l0, d1 / l1)) > math.pi - _REVERSAL):
            h = 0.2 * min(l0, l1, max(tol - max(D[x - 1], D[x]), 0.0))
            nrm = np.array([-d0[1], d0[0]]) / l0
            V.insert(x + 1, V[x] + h * nrm)
            D.insert(x + 1, D[x] + h)
            D[x] = D[x] + h
            if poly.n_pin_last > x:
                poly.n_pin_last += 1
            x += 2
            continue
        x += 1


def _fillets(poly: _Polyline, tol: float, mode: str) -> _Fillets:
    """Tangent lengths of the fillets: within the band left by the legs' displacement,
    at most half of each leg, pinned fillets using their whole virtual leg."""
    V, D = poly.V, poly.D
    n = len(V)
    legs = [float(np.hypot(*(V[x + 1] - V[x]))) for x in range(n - 1)]
    dirs = [(V[x + 1] - V[x]) / legs[x] if legs[x] > 0 else np.zeros(2) for x in range(n - 1)]
    L = [0.0] * n
    th = [0.0] * n
    for x in range(1, n - 1):
        th[x] = _turn(dirs[x - 1], dirs[x])
        budget = _SAFETY * max(tol - max(D[x - 1], D[x]), 0.0)
        tq = math.tan(0.25 * abs(th[x]))
        lim = budget / tq if tq > 0 else math.inf
        if x == 1 and poly.pinned_first:
            L[x] = legs[0]
        elif x == poly.n_pin_last:
            L[x] = legs[-1]
        else:
            L[x] = min(lim, 0.5 * legs[x - 1], 0.5 * legs[x])
    # a pinned fillet may use more than half of its inner leg: the neighbour gives way
    for x in range(1, n - 1):
        if x + 1 < n - 1 and L[x] + L[x + 1] > legs[x]:
            if poly.pinned(x):
                L[x + 1] = max(legs[x] - L[x], 0.0)
            else:
                L[x] = max(legs[x] - L[x + 1], 0.0)
    e_last = min(0.3 * tol, 0.5 * legs[-1]) if mode == "state" else 0.0
    return _Fillets(legs, dirs, L, th, e_last)


def _assemble(
    poly: _Polyline, fil: _Fillets, S: FloatArray, tol: float, k: int, m: int, mode: str,
    t_end: FloatArray | None,
) -> tuple[list[Piece], tuple[FloatArray, FloatArray, float] | None]:
    """Line, fillet, line, ... (see :func:`fillet_stretch` for the result).

    Each piece starts exactly where the previous one ends with its end tangent (lines
    run along the leg direction from there), so the chain is C1 up to rounding; lines
    shorter than ``_SHORT`` tolerances are left out (their end points' rounding would
    make a visible kink).
    """
    V, dirs, L, th = poly.V, fil.dirs, fil.L, fil.th
    n = len(V)
    nseg = len(S) - 1
    pieces: list[Piece] = []
    cur_p = V[0].copy()
    cur_k = k
    kidx = _sample_index_map(V, S, k, m)
    for x in range(1, n):
        d = dirs[x - 1]
        stop = V[x] - (L[x] if x < n - 1 else fil.e_last) * d
        ln = float((stop - cur_p) @ d)
        if ln > _SHORT * tol or (x == n - 1 and mode != "state" and not pieces):
            end = cur_p + ln * d
            pieces.append(Piece(cur_p, d.copy(), 0.0, ln, cur_k, kidx[x], end, d.copy(), 0.0))
            cur_p = end
        if x == n - 1:
            break
        if L[x] <= 0.0 or abs(th[x]) < _STRAIGHT:
            # (nearly) no turn: the chain runs straight on (a huge-radius fillet would
            # lose its precision far from its centre)
            continue
        r = L[x] / math.tan(0.5 * abs(th[x]))
        kap = math.copysign(1.0 / r, th[x])
        length = r * abs(th[x])
        end = arc_points(cur_p, d, kap, np.array([length]))[0]
        kk = kidx[x]
        pieces.append(Piece(cur_p, d.copy(), kap, length, max(cur_k, kk - 1),
                            min(kk + 1, nseg), end, dirs[x].copy(), 0.0))
        cur_p = end
        cur_k = kk
    q = S[m]
    if mode == "state":
        return pieces, (cur_p.copy(), dirs[-1].copy(), float(np.hypot(*(q - cur_p))))
    if pieces:
        pieces[-1].end = q.copy()
        if mode == "tangent":
            assert t_end is not None
            pieces[-1].t_end = t_end.copy()
    return pieces, None


def _sample_index_map(V: list[FloatArray], S: FloatArray, k: int, m: int) -> list[int]:
    """Nearest sample index (in ``k..m``) of each vertex: the bookkeeping of the verifier."""
    seg = S[k : m + 1]
    out = []
    for v in V:
        d = np.hypot(seg[:, 0] - v[0], seg[:, 1] - v[1])
        out.append(k + int(np.argmin(d)))
    out = list(np.maximum.accumulate(out))
    return [int(o) for o in out]
