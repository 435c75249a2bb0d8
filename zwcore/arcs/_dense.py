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

from zwcore.arcs._jumps import (
    SLACK,
    last_below,
    one_piece_distance,
    piece_growth,
    piece_growth_at,
    safe_move,
    segment_growth,
)
from zwcore.arcs._kernels import (
    arc_angle1,
    arc_xy,
    circle_gap1,
    foot_positions,
    local1,
    seg_dist,
)

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

__all__ = ["dense_deviations", "polyline_length"]


@njit(cache=True, nogil=True, error_model="numpy")
def point_arc_distance(x: float, y: float, px: float, py: float, tx: float, ty: float,
                       kappa: float, length: float, ex: float, ey: float,
                       known: float) -> float:
    """Exact distance of ``(x, y)`` to the piece from ``p`` along ``t`` of curvature
    ``kappa`` and arc length ``length`` ending at ``(ex, ey)`` when it is below ``known``
    (a distance already found); else a figure no smaller than ``known``."""
    u, v = local1(x, y, px, py, tx, ty)
    if kappa == 0.0:
        if 0.0 <= u <= length:
            return abs(v)
        return min(math.hypot(u, v), math.hypot(x - ex, y - ey))
    gap = abs(circle_gap1(u, v, kappa))
    if gap >= known:
        return gap  # (no closer than the circle: the arc cannot beat ``known``)
    d_ends = min(math.hypot(u, v), math.hypot(x - ex, y - ey))
    if arc_angle1(u, v, kappa) <= abs(kappa * length):
        return min(gap, d_ends)
    return d_ends


@njit(cache=True, nogil=True, error_model="numpy")
def _dense_offsets(samples: FloatArray, step: float) -> IntArray:
    """Index of the first dense point of each polyline segment ``(nseg + 1,)`` (the last
    entry: the final vertex), segments cut into pieces no longer than ``step``."""
    nseg = len(samples) - 1
    off = np.zeros(nseg + 1, dtype=np.int64)
    for s in range(nseg):
        seg = math.hypot(samples[s + 1, 0] - samples[s, 0], samples[s + 1, 1] - samples[s, 1])
        off[s + 1] = off[s] + max(math.ceil(seg / step), 1)
    return off


@njit(cache=True, nogil=True, error_model="numpy")
def _dense_point(samples: FloatArray, off: IntArray, s: int, i: int) -> tuple[float, float]:
    """Dense point ``i`` of segment ``s`` (the last one: the final vertex)."""
    if i >= off[len(off) - 1]:
        return samples[len(samples) - 1, 0], samples[len(samples) - 1, 1]
    f = (i - off[s]) / (off[s + 1] - off[s])
    return (samples[s, 0] + f * (samples[s + 1, 0] - samples[s, 0]),
            samples[s, 1] + f * (samples[s + 1, 1] - samples[s, 1]))


@njit(cache=True, nogil=True, error_model="numpy")
def _pieces_near(ks: IntArray, js: IntArray, nseg: int) -> tuple[IntArray, IntArray]:
    """The pieces compared with each polyline segment (those covering samples within two
    segments of it), as ``(start (nseg + 1,), piece indices)`` (CSR)."""
    cnt = np.zeros(nseg + 1, dtype=np.int64)
    for q in range(len(ks)):
        for s in range(max(ks[q] - 2, 0), min(js[q] + 2, nseg - 1) + 1):
            cnt[s + 1] += 1
    for s in range(nseg):
        cnt[s + 1] += cnt[s]
    idx = np.empty(cnt[nseg], dtype=np.int64)
    fill = cnt[:-1].copy()
    for q in range(len(ks)):
        for s in range(max(ks[q] - 2, 0), min(js[q] + 2, nseg - 1) + 1):
            idx[fill[s]] = q
            fill[s] += 1
    return cnt, idx


@njit(cache=True, nogil=True, error_model="numpy")
def _nearest_piece(geo: FloatArray, qs: IntArray, x: float, y: float) -> tuple[float, int]:
    """Distance of ``(x, y)`` to the pieces ``qs`` and the piece it is measured to."""
    d = np.inf
    best = -1
    for q in qs:
        dq = point_arc_distance(x, y, geo[q, 0], geo[q, 1], geo[q, 2], geo[q, 3],
                                geo[q, 4], geo[q, 5], geo[q, 6], geo[q, 7], d)
        if dq < d:
            d, best = dq, q
    return d, best


@njit(cache=True, nogil=True, error_model="numpy")
def _segment_max(samples: FloatArray, off: IntArray, s: int, hi: int, geo: FloatArray,
                 qs: IntArray, q: int, tol: float, d0: float, known: bool, uk: float,
                 vk: float, ak: float) -> float:
    """The largest distance of the dense points ``off[s]..hi-1`` of segment ``s`` to the
    pieces ``qs``, exactly, when every point's foot lies inside piece ``q`` and ``q`` is
    the nearest piece where that distance peaks; else -1 (walk the points). ``d0``: the
    first point's distance, measured by the caller (``q`` the nearest there); with
    ``known`` also its local coordinates ``(uk, vk)`` and (arcs) its foot's angle ``ak``.

    Along a line the offset ``e`` from the piece (a line's ``v``, a circle's ``rho - R``)
    is linear or convex (``rho`` is), so over the evenly spaced points ``|e| = max(e,
    -e)`` peaks at the first or last point or, ``-e`` being concave, at the two points
    about the line's closest approach to the centre: at most four points to measure.
    The distance to the pieces is at most ``|e|`` at every point and equal to it where
    ``q`` is the nearest, so where that holds at the peak the peak is the maximum.
    """
    i0 = off[s]
    i1 = hi - 1
    if i1 <= i0 + 3:
        return -1.0
    px, py, tx, ty, kappa, length = geo[q, 0], geo[q, 1], geo[q, 2], geo[q, 3], \
        geo[q, 4], geo[q, 5]
    x0, y0 = _dense_point(samples, off, s, i0)
    x1, y1 = _dense_point(samples, off, s, i1)
    u0, v0 = (uk, vk) if known else local1(x0, y0, px, py, tx, ty)
    u1, v1 = local1(x1, y1, px, py, tx, ty)
    c2 = i0
    if kappa == 0.0:
        if not (0.0 <= u0 <= length and 0.0 <= u1 <= length):
            return -1.0
    else:
        a0 = ak if known else arc_angle1(u0, v0, kappa)
        a1 = arc_angle1(u1, v1, kappa)
        sweep = abs(kappa * length)
        # (the foot turns monotonically, by less than pi, along a line)
        if not (a0 <= sweep and a1 <= sweep and abs(a1 - a0) < math.pi):
            return -1.0
        # the dense point before the line's closest approach to the centre
        cx = px - ty / kappa
        cy = py + tx / kappa
        dx = x1 - x0
        dy = y1 - y0
        span = math.hypot(dx, dy)
        if not span > 0.0:
            return -1.0
        h = ((cx - x0) * dx + (cy - y0) * dy) / span
        f = h / span * (i1 - i0)
        c2 = i0 + int(min(max(f, 0.0), float(i1 - i0)))
    # (at the first point the nearest piece is ``q``: its figure is ``d0`` both ways, as
    # with one piece near, where the nearest is that piece's own figure)
    best_q = d0
    best_d = d0
    single = len(qs) == 1
    c3 = min(c2 + 1, i1)
    # the candidates after i0 in the order (i1, c2, c3), each measured once: a slot
    # repeating an earlier one is dropped (-1), never the last point itself
    for c in (i1, c2 if c2 != i0 and c2 != i1 else -1,
              c3 if c3 != i0 and c3 != c2 and c3 != i1 else -1):
        if c < 0:
            continue
        x, y = _dense_point(samples, off, s, c)
        if c == i1:
            # (point_arc_distance's figure from the local coordinates and the foot's
            # angle found above: the foot is on the piece)
            if kappa == 0.0:
                dq = abs(v1)
            else:
                dq = min(abs(circle_gap1(u1, v1, kappa)),
                         min(math.hypot(u1, v1), math.hypot(x - geo[q, 6], y - geo[q, 7])))
        else:
            dq = point_arc_distance(x, y, px, py, tx, ty, kappa, length, geo[q, 6],
                                    geo[q, 7], np.inf)
        d = dq if single else _nearest_piece(geo, qs, x, y)[0]
        if not d <= tol:
            return -1.0
        if dq > best_q:
            best_q, best_d = dq, d
    return best_q if best_d == best_q else -1.0


@njit(cache=True, nogil=True, error_model="numpy")
def _polyline_to_chain(samples: FloatArray, geo: FloatArray, ks: IntArray, js: IntArray,
                       off: IntArray, tol: float) -> float:
    """Largest distance of the dense polyline points to the chain: to the pieces covering
    samples near each point's segment, to every piece where that exceeds ``tol``.

    Points that cannot raise the maximum are skipped: along one segment the distance to
    a fixed set of pieces changes no faster than the position (1-Lipschitz), and no
    faster than the distance to the nearest piece grows
    (:func:`~zwcore.arcs._jumps.piece_growth`: nearly parallel curves drift apart
    slowly), so a point whose bound from the last measured one is within ``worst`` is no
    farther than ``worst``; a segment the walk would not cross in one jump is measured
    at a few points where that gives its maximum exactly (:func:`_segment_max`).
    """
    nseg = len(samples) - 1
    total = off[nseg] + 1
    start, idx = _pieces_near(ks, js, nseg)
    every = np.arange(len(geo))
    worst = 0.0
    for s in range(nseg):
        qs = idx[start[s] : start[s + 1]]
        # (the final vertex counts as a point of the last segment)
        hi = off[s + 1] if s < nseg - 1 else total
        sx = samples[s + 1, 0] - samples[s, 0]
        sy = samples[s + 1, 1] - samples[s, 1]
        sl = math.hypot(sx, sy)
        ux, uy = (sx / sl, sy / sl) if sl > 0.0 else (1.0, 0.0)
        # the spacing of the segment's dense points
        dl = sl / max(off[s + 1] - off[s], 1)
        i = off[s]
        # one piece near (most segments): its figures at a point measured once
        single = len(qs) == 1
        while i < hi:
            x, y = _dense_point(samples, off, s, i)
            if single:
                d, q, u, v, ang, gap = one_piece_distance(geo, qs[0], x, y)
            else:
                d, q = _nearest_piece(geo, qs, x, y)
                u = v = ang = gap = 0.0
            e0, rate, curv, reach = 0.0, 1.0, 0.0, 0.0
            if q >= 0 and d <= tol:
                if single:
                    e0, rate, curv, reach = piece_growth_at(geo, q, u, v, ang, gap, ux, uy)
                else:
                    e0, rate, curv, reach = piece_growth(geo, q, x, y, ux, uy)
            if not d <= tol:
                d = _nearest_piece(geo, every, x, y)[0]
            worst = max(worst, d)
            # the next points within the safe move cannot raise the maximum
            skip = 0
            if dl > 0.0:
                skip = int(min(safe_move(d, worst + SLACK * tol, e0, rate, curv, reach) / dl,
                               hi))
            if i == off[s] and i + 1 + skip < hi and q >= 0 and d <= tol:
                # the whole segment from a few points, where the closed form holds
                top = _segment_max(samples, off, s, hi, geo, qs, q, tol, d, single, u, v,
                                   ang)
                if top >= 0.0:
                    worst = max(worst, top)
                    break
            i += 1 + skip
    if nseg == 0:
        worst = _nearest_piece(geo, every, samples[0, 0], samples[0, 1])[0]
    return worst


@njit(cache=True, nogil=True, error_model="numpy")
def _seg_dist2(samples: FloatArray, s: int, x: float, y: float) -> float:
    """Squared distance of ``(x, y)`` to polyline segment ``s`` (the arithmetic of
    :func:`_segments_near`, so that one segment's figure equals the window's bit for bit
    where it is the nearest)."""
    ax, ay = samples[s, 0], samples[s, 1]
    abx = samples[s + 1, 0] - ax
    aby = samples[s + 1, 1] - ay
    den = abx * abx + aby * aby
    if not den > 0.0:
        den = 1.0
    apx = x - ax
    apy = y - ay
    dot = apx * abx + apy * aby
    # (a foot before the start or past the end needs no division: the clamp's result,
    # up to the sign of a zero that the squares drop)
    if dot <= 0.0:
        f = 0.0
    elif dot >= den:
        f = 1.0
    else:
        f = min(max(dot / den, 0.0), 1.0)
    qx = apx - f * abx
    qy = apy - f * aby
    return qx * qx + qy * qy


@njit(cache=True, nogil=True, error_model="numpy")
def _segments_near(samples: FloatArray, x: float, y: float, m: int) -> tuple[float, int]:
    """Distance of ``(x, y)`` to the polyline segments ``m-3..m+3`` (clipped), and the
    nearest of them."""
    nseg = len(samples) - 1
    d2 = np.inf
    best = 0
    for o in range(-3, 4):
        s = min(max(m + o, 0), nseg - 1)
        e2 = _seg_dist2(samples, s, x, y)
        if e2 < d2:
            d2 = e2
            best = s
    return math.sqrt(d2), best


@njit(cache=True, nogil=True, error_model="numpy")
def _all_segments(samples: FloatArray, x: float, y: float) -> float:
    d = np.inf
    for s in range(len(samples) - 1):
        d = min(d, seg_dist(x, y, samples[s, 0], samples[s, 1], samples[s + 1, 0],
                            samples[s + 1, 1]))
    return d


@njit(cache=True, nogil=True, error_model="numpy")
def _window_w(samples: FloatArray, foot: FloatArray, k: int, px: float, py: float,
              tx: float, ty: float, kappa: float, ds: float, c: int,
              lseg: int) -> tuple[float, float]:
    """Dense point ``c`` of a piece: its distance to its window of segments (as the walk
    measures it) and to segment ``lseg`` (the window's arithmetic: equal where ``lseg``
    is the nearest)."""
    x, y = arc_xy(px, py, tx, ty, kappa, c * ds)
    m = k + int(np.searchsorted(foot, c * ds, side="right")) - 1
    return _segments_near(samples, x, y, m)[0], math.sqrt(_seg_dist2(samples, lseg, x, y))


@njit(cache=True, nogil=True, error_model="numpy")
def _portion_max(samples: FloatArray, foot: FloatArray, k: int, px: float, py: float,
                 tx: float, ty: float, kappa: float, ds: float, i: int, i_r: int,
                 lseg: int, tol: float, d0: float, e0: float, rate: float) -> float:
    """The largest distance to the polyline of the dense points ``i..i_r`` of a piece
    (start ``p``, tangent ``t``, curvature ``kappa``, spacing ``ds``; ``foot``: the foot
    positions of its samples from ``k`` on), exactly, when their feet all lie inside
    segment ``lseg``, each one's window holds it and ``lseg`` is the nearest where the
    distance peaks; else -1 (walk the points).

    The offset ``w`` from the segment's line has a second derivative of one sign over
    the points (see :func:`~zwcore.arcs._jumps.segment_growth`), so ``|w| = max(w, -w)``
    peaks at the first or last point or at the two points about where the piece runs parallel to the
    segment: at most four points to measure (each against its window, as the walk
    does, which is at most ``|w|`` and equal to it where ``lseg`` is the nearest).
    ``d0``: point ``i``'s distance, measured by the caller (``lseg`` the nearest there);
    ``(e0, rate)``: its growth from there (:func:`~zwcore.arcs._jumps.segment_growth`).
    The last point is not measured where it cannot be the peak
    (:func:`~zwcore.arcs._jumps.last_below`).
    """
    c2 = i
    s_par = -1.0
    if kappa != 0.0:
        ax, ay = samples[lseg, 0], samples[lseg, 1]
        phi = math.atan2(samples[lseg + 1, 1] - ay, samples[lseg + 1, 0] - ax)
        rel = math.atan2(ty, tx) + kappa * i * ds - phi
        rel -= math.pi * np.rint(rel / math.pi)
        s_par = i * ds - rel / kappa
        if i * ds < s_par < i_r * ds:
            c2 = min(int(s_par / ds), i_r)
        else:
            s_par = -1.0
    c3 = min(c2 + 1, i_r)
    # the candidates in the walk's order (i, i_r, c2, c3; the first of equal ones wins):
    # (at point i the nearest segment is ``lseg``: its figure is ``d0`` both ways)
    w2 = d2 = w3 = d3 = -1.0
    if c2 != i and c2 != i_r:
        d2, w2 = _window_w(samples, foot, k, px, py, tx, ty, kappa, ds, c2, lseg)
    if c3 != i and c3 != c2 and c3 != i_r:
        d3, w3 = _window_w(samples, foot, k, px, py, tx, ty, kappa, ds, c3, lseg)
    if not (d2 <= tol and d3 <= tol):
        return -1.0
    best_w = d0
    best_d = d0
    top = max(d0, w2, w3)
    if not (s_par >= 0.0 and c3 < i_r and last_below(
            kappa, ds, i, i_r, s_par, e0, rate, top, tol, abs(px) + abs(py) + i_r * ds)):
        d1, w1 = _window_w(samples, foot, k, px, py, tx, ty, kappa, ds, i_r, lseg)
        if not d1 <= tol:
            return -1.0
        if w1 > best_w:
            best_w, best_d = w1, d1
    if w2 > best_w:
        best_w, best_d = w2, d2
    if w3 > best_w:
        best_w, best_d = w3, d3
    return best_w if best_d == best_w else -1.0


@njit(cache=True, nogil=True, error_model="numpy")
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
            u[i], v[i] = local1(samples[k + i, 0], samples[k + i, 1], px, py, tx, ty)
        foot = np.empty(nf)
        foot_positions(u, v, kappa, foot)
        if kappa == 0.0 and nf:
            foot[0] = u[0]  # (a line's foot positions are u itself, the first one too)
        for i in range(1, nf):
            foot[i] = max(foot[i], foot[i - 1])
        ptr = 0
        # the last measured point (arc length, distance, nearest segment): the distance
        # to that segment grows no faster than the arc length (see _polyline_to_chain),
        # nor, while the foot stays on it, than its offset from the segment's line
        # (slope: the sine of the angle between them, |second derivative| <= |kappa|)
        ds = length / (n - 1)
        i = 0
        while i < n:
            sg = length if i == n - 1 else i * ds
            while ptr < nf and foot[ptr] <= sg:
                ptr += 1
            m = k + ptr - 1
            if i == n - 1:
                x, y = geo[q, 6], geo[q, 7]
            else:
                x, y = arc_xy(px, py, tx, ty, kappa, sg)
            if nseg == 0:
                worst = max(worst, math.hypot(x - samples[0, 0], y - samples[0, 1]))
                i += 1
                continue
            d, lseg = _segments_near(samples, x, y, m)
            e0, rate, reach = segment_growth(samples, lseg, x, y, tx, ty, kappa, sg)
            if not d <= tol:
                d = _all_segments(samples, x, y)
            worst = max(worst, d)
            # skip the points within the safe move whose window (segments m-3..m+3 of
            # their foot) still holds lseg; the last point is always measured
            lim = sg + safe_move(d, worst + SLACK * tol, e0, rate, abs(kappa), reach)
            pf = lseg + 4 - k  # from this foot on, m > lseg + 3
            if 0 <= pf < nf:
                lim = min(lim, np.nextafter(foot[pf], -np.inf))
            nxt = i + 1
            if ds > 0.0 and lim > sg:
                nxt = max(nxt, min(int(lim / ds) + 1, n - 1))
            if d <= tol and reach > 0.0 and ds > 0.0 and pf >= 0 and i < n - 1:
                # the points while the foot stays on lseg and their windows hold it (not
                # the last one) from a few points, where the walk would not cross them
                far = sg + reach
                if pf < nf:
                    far = min(far, np.nextafter(foot[pf], -np.inf))
                i_r = min(int(far / ds), n - 2)
                if nxt < i_r - 2:
                    top = _portion_max(samples, foot, k, px, py, tx, ty, kappa, ds, i, i_r,
                                       lseg, tol, d, e0, rate)
                    if top >= 0.0:
                        worst = max(worst, top)
                        nxt = i_r + 1
            i = nxt
    return worst


@njit(cache=True, nogil=True, error_model="numpy")
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
    return (_polyline_to_chain(samples, geo, ks, js, off, tol),
            _chain_to_polyline(samples, geo, ks, js, step, tol))


@njit(cache=True, nogil=True, error_model="numpy")
def polyline_length(samples: FloatArray) -> float:
    """Length of the polyline ``samples`` ``(M, 2)`` (summed in order)."""
    total = 0.0
    for s in range(len(samples) - 1):
        total += math.hypot(samples[s + 1, 0] - samples[s, 0], samples[s + 1, 1] - samples[s, 1])
    return total
