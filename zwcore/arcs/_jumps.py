"""How far the dense check (:mod:`zwcore.arcs._dense`) may jump from a measured point:
bounds of how fast a point's distance to a piece (or to a polyline segment) can grow as
it moves on, while its foot stays inside that piece (segment).

The signed offset ``e`` from the piece (a line's ``v``, a circle's ``rho - R``; from a
segment's line for a point moving along a piece) has a second derivative of one sign
and bounded size there, so after a move ``h`` it lies between ``e0 + rate h`` and
``e0 + rate h + curv h^2 / 2``: the distance ``|e|`` is at most the larger of the upper
one and minus the lower one (:func:`safe_move`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from zwcore.arcs._kernels import arc_angle1, circle_gap1, local1

FloatArray = NDArray[np.float64]

__all__ = ["SLACK", "last_below", "one_piece_distance", "piece_growth", "piece_growth_at",
           "safe_move", "segment_growth"]

#: share of the tolerance the figures may fall short of the maximum over the samples:
#: a point is jumped over when its distance cannot exceed the maximum so far by more
SLACK = 1e-12


@njit(cache=True, nogil=True, error_model="numpy")
def piece_growth(geo: FloatArray, q: int, x: float, y: float, ux: float,
                  uy: float) -> tuple[float, float, float, float]:
    """How the distance of a point moving from ``(x, y)`` along the unit direction
    ``(ux, uy)`` to piece ``q`` can grow: ``(e0, rate, curv, reach)``, its signed offset
    ``e`` from the piece (the distance is ``|e|``) lies between ``e0 + rate h`` and
    ``e0 + rate h + curv h^2 / 2`` after a move ``h <= reach``.

    Valid while the point's foot stays inside the piece (``reach``: 0 when it is not
    inside): the offset is then the line's ``v`` (linear in ``h``) or the circle's
    ``rho - R``, ``rho`` the distance to the centre, convex along a line with
    ``0 <= rho'' <= 1 / rho`` (``rho >= rho0 / 2`` within the reach).
    """
    u, v = local1(x, y, geo[q, 0], geo[q, 1], geo[q, 2], geo[q, 3])
    kappa = geo[q, 4]
    if kappa == 0.0:
        return piece_growth_at(geo, q, u, v, 0.0, 0.0, ux, uy)
    return piece_growth_at(geo, q, u, v, arc_angle1(u, v, kappa), circle_gap1(u, v, kappa),
                           ux, uy)


@njit(cache=True, nogil=True, error_model="numpy")
def piece_growth_at(geo: FloatArray, q: int, u: float, v: float, ang: float, gap: float,
                    ux: float, uy: float) -> tuple[float, float, float, float]:
    """:func:`piece_growth` of a point already in the piece's frame: ``(u, v)`` its
    local coordinates and, for an arc, ``ang`` its foot's angle (``arc_angle1``) and
    ``gap`` its signed gap to the circle (``circle_gap1``), as the caller measured them
    (the dense check's first point of a segment: measured once, not three times)."""
    tx, ty, kappa, length = geo[q, 2], geo[q, 3], geo[q, 4], geo[q, 5]
    du = ux * tx + uy * ty
    dv = uy * tx - ux * ty
    if kappa == 0.0:
        if not 0.0 <= u <= length:
            return 0.0, 1.0, 0.0, 0.0
        # the foot moves along the line at the rate du
        if du > 0.0:
            return v, dv, 0.0, (length - u) / du
        if du < 0.0:
            return v, dv, 0.0, u / -du
        return v, dv, 0.0, np.inf
    # the radial direction in the piece's frame, scaled by |kappa| (stable for tiny ones)
    gu = kappa * u
    gv = kappa * v - 1.0
    n = math.hypot(gu, gv)
    if not n > 0.0:
        return 0.0, 1.0, 0.0, 0.0
    rho = n / abs(kappa)
    if not ang <= abs(kappa * length):
        # the foot is off the arc (the distance is to an end point)
        return 0.0, 1.0, 0.0, 0.0
    # the cosine between the move and the arc's direction at the foot: while the foot
    # turns by less than asin(|cos|) it keeps turning the same way, towards the end
    # (cos > 0) or the start of the arc
    cos = (dv * gu - du * gv) / n
    margin = abs(kappa * length) - ang if cos > 0.0 else ang
    margin = min(margin, math.asin(min(abs(cos), 1.0)))
    if not margin > 0.0:
        return 0.0, 1.0, 0.0, 0.0
    # rho - R: the signed gap is positive right of the piece, outside for kappa > 0
    sgn = 1.0 if kappa > 0.0 else -1.0
    e0 = sgn * gap
    # the foot turns by at most h / (rho - h) <= 2 h / rho about the centre
    return e0, sgn * (du * gu + dv * gv) / n, 2.0 / rho, 0.5 * rho * min(margin, 1.0)


@njit(cache=True, nogil=True, error_model="numpy")
def safe_move(d: float, worst: float, e0: float, rate: float, curv: float,
               reach: float) -> float:
    """How far a point measured at distance ``d`` can move before its distance may
    exceed ``worst`` (the caller's maximum plus :data:`SLACK` of the tolerance, so that
    offsets of rounding size, 1e-18 mm growing at 1e-17 per mm, do not stop the jumps
    along a piece that lies on the polyline): 1-Lipschitz, and within ``reach`` the
    distance ``|e|`` with the signed offset ``e`` between ``e0 + rate h`` and
    ``e0 + rate h + curv h^2 / 2`` (:func:`piece_growth`, :func:`segment_growth`),
    so at most the larger of ``e0 + rate h + curv h^2 / 2`` and ``-(e0 + rate h)``; a
    hair short of it (rounding of the dense points' positions)."""
    room = worst - d
    if not room > 0.0:
        room = 0.0
    h = room
    if reach > h:
        # e0 + rate h + curv h^2 / 2 <= worst: the positive root (the stable forms)
        up = worst - e0
        if not up >= 0.0:
            h_up = 0.0
        elif curv > 0.0:
            disc = math.sqrt(rate * rate + 2.0 * curv * up)
            h_up = 2.0 * up / (rate + disc) if rate > 0.0 else (disc - rate) / curv
        else:
            h_up = up / rate if rate > 0.0 else np.inf
        # -(e0 + rate h) <= worst
        down = worst + e0
        if not down >= 0.0:
            h_down = 0.0
        else:
            h_down = down / -rate if rate < 0.0 else np.inf
        h = max(h, min(h_up, h_down, reach))
    return h * (1.0 - 1e-9)


@njit(cache=True, nogil=True, error_model="numpy")
def segment_growth(samples: FloatArray, s: int, x: float, y: float, tx: float, ty: float,
                    kappa: float, sg: float) -> tuple[float, float, float]:
    """``(e0, rate, reach)`` of the distance of a point moving along the piece from
    ``(x, y)`` (arc length ``sg``; start tangent ``t``, curvature ``kappa``) to segment
    ``s``: while its foot stays inside the segment (a move of at most ``reach``) the
    distance is ``|w|``, ``w`` the offset from the segment's line, with ``w''`` of one
    sign and at most ``|kappa|``; so ``e = +-w`` (the sign that makes ``e''`` positive)
    lies between ``e0 + rate h`` and ``e0 + rate h + |kappa| h^2 / 2``."""
    ax, ay = samples[s, 0], samples[s, 1]
    ex = samples[s + 1, 0] - ax
    ey = samples[s + 1, 1] - ay
    sl = math.hypot(ex, ey)
    if not sl > 0.0:
        return 0.0, 1.0, 0.0
    ex /= sl
    ey /= sl
    lam = (x - ax) * ex + (y - ay) * ey
    if not 0.0 <= lam <= sl:
        return 0.0, 1.0, 0.0
    a = kappa * sg
    c, sn = math.cos(a), math.sin(a)
    # the piece's tangent at sg
    qx = tx * c - ty * sn
    qy = tx * sn + ty * c
    # the foot moves along the segment at the rate cos (the tangent's component along
    # it), which keeps its sign while the tangent turns by less than asin(|cos|); so
    # does w'' = kappa cos
    cos = ex * qx + ey * qy
    reach = sl - lam if cos > 0.0 else lam
    if kappa != 0.0:
        reach = min(reach, math.asin(min(abs(cos), 1.0)) / abs(kappa))
    sgn = -1.0 if kappa * cos < 0.0 else 1.0
    w0 = (y - ay) * ex - (x - ax) * ey
    return sgn * w0, sgn * (ex * qy - ey * qx), reach


@njit(cache=True, nogil=True, error_model="numpy")
def one_piece_distance(geo: FloatArray, q: int, x: float,
                        y: float) -> tuple[float, int, float, float, float, float]:
    """:func:`~zwcore.arcs._dense._nearest_piece` of the one piece ``q`` (``qs == [q]``),
    with the point's local coordinates ``(u, v)``, its foot's angle and its signed gap to
    the circle (arcs; 0 for lines) that :func:`~zwcore.arcs._dense.point_arc_distance`
    measures on the way: the dense check's growth bound and few-point maximum of a
    segment take them as they are (:func:`piece_growth_at`,
    :func:`~zwcore.arcs._dense._segment_max`)."""
    px, py, tx, ty, kappa, length = geo[q, 0], geo[q, 1], geo[q, 2], geo[q, 3], \
        geo[q, 4], geo[q, 5]
    u, v = local1(x, y, px, py, tx, ty)
    ang = 0.0
    gap = 0.0
    if kappa == 0.0:
        if 0.0 <= u <= length:
            d = abs(v)
        else:
            d = min(math.hypot(u, v), math.hypot(x - geo[q, 6], y - geo[q, 7]))
    else:
        gap = circle_gap1(u, v, kappa)
        d = abs(gap)
        ang = arc_angle1(u, v, kappa)
        if not d >= np.inf:
            # (point_arc_distance with nothing known yet)
            d_ends = min(math.hypot(u, v), math.hypot(x - geo[q, 6], y - geo[q, 7]))
            d = min(d, d_ends) if ang <= abs(kappa * length) else d_ends
    # (as _nearest_piece: a figure that is not below infinity names no piece)
    if not d < np.inf:
        return np.inf, -1, u, v, ang, gap
    return d, q, u, v, ang, gap


@njit(cache=True, nogil=True, error_model="numpy")
def last_below(kappa: float, ds: float, i: int, i_r: int, s_par: float, e0: float,
                rate: float, top: float, tol: float, scale: float) -> bool:
    """True when the last point ``i_r`` of a portion
    (:func:`~zwcore.arcs._dense._portion_max`) is, by a
    margin above the rounding, farther from ``lseg`` than none of the points ``i, c2,
    c3`` measured (``top``: their largest offset), so it cannot be the peak.

    With ``e = +-w`` convex (``0 <= e'' <= |kappa|``) from point ``i`` on: ``e`` at
    ``i_r`` is at most ``e0 + rate h + |kappa| h^2 / 2``; ``-e`` is concave with its top
    at the parallel point ``s_par`` (between ``c2`` and ``c3``), where the tangent runs
    along the segment, so past it ``-e'' >= |kappa| cos(|kappa| D)`` (the tangent has
    turned by ``|kappa| D`` from the segment's direction, ``D`` the way from ``s_par``)
    and ``-e`` at ``i_r`` lies at least ``|kappa| (cos(|kappa| D) D^2 - ds^2) / 2``
    below the better of ``c2, c3`` (one of them is within ``ds / 2`` of the top,
    ``-e'' >= -|kappa|``). Both must clear the margin (a billionth of the tolerance
    and 1e-13 of the coordinates' size)."""
    margin = 1e-9 * tol + 1e-13 * scale
    ak = abs(kappa)
    h = (i_r - i) * ds
    dist = i_r * ds - s_par
    ang = ak * dist
    if not ang < 0.5 * math.pi:
        return False
    if not 0.5 * ak * (math.cos(ang) * dist * dist - ds * ds) > 2.0 * margin:
        return False
    return e0 + rate * h + 0.5 * ak * h * h < top - 2.0 * margin
