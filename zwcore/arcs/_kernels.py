"""Compiled kernels of the tolerance band (:mod:`zwcore.arcs._pieces`): reach scans,
running curvature bounds and the two-sided verification of one piece.

The band's questions are asked thousands of times per run on a few dozen to a few
thousand samples each; as numpy expressions their cost is the per-call overhead of some
thirty small array operations, not the arithmetic. These numba kernels do the same
arithmetic in the same order in one loop (so the figures, and the chains, are those of
the numpy formulas in :mod:`zwcore.arcs._geometry` and ``tests/arc_reference.py``; the
property tests in ``tests/test_arc_kernels.py`` compare the two), and stop at the first
sample that decides the answer.

Conventions as in :mod:`zwcore.arcs._geometry`: a piece starts at ``(px, py)`` with unit
tangent ``(tx, ty)`` and signed curvature ``kappa``; a sample's local coordinates are
``u`` along the tangent and ``v`` to its left.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

__all__ = ["arc_near_polyline", "chord_circle_gap", "foot_positions", "kappa_fits", "last_before",
           "line_reaches", "line_spread", "piece_bounds", "reach_lines", "verify_piece"]

_TWO_PI = 2.0 * math.pi
#: Relative slack past a piece's end within which a segment's later foot still counts
#: as on the arc (:func:`_segments_within`): a piece given its length (a biarc's second
#: arc, ending where sample ``j`` stands) puts that sample's foot on its end or, by an
#: ulp of ``atan2``, past it, where the segment test would jump to its far coarser bound
#: (``end_slack`` of ``tests/arc_reference.py``'s ``segments_within``).
_END_SLACK = 1e-12


@njit(cache=True, nogil=True, error_model="numpy")
def sinc(x: float) -> float:
    """``numpy.sinc`` of one number (the same figures)."""
    y = math.pi * (x if x != 0.0 else 1.0e-20)
    return math.sin(y) / y


@njit(cache=True, nogil=True, error_model="numpy")
def circle_gap1(u: float, v: float, kappa: float) -> float:
    """The signed distance of one local point ``(u, v)`` to the circle (or line) of
    curvature ``kappa`` (``circle_gap`` of ``tests/arc_reference.py``)."""
    w = kappa * (u * u + v * v) - 2.0 * v
    return w / (1.0 + math.sqrt(max(1.0 + kappa * w, 0.0)))


@njit(cache=True, nogil=True, error_model="numpy")
def local1(x: float, y: float, px: float, py: float, tx: float,
           ty: float) -> tuple[float, float]:
    """:func:`zwcore.arcs._geometry.local_uv` of one point: ``(u, v)`` in the frame of
    ``(p, t)``."""
    dx = x - px
    dy = y - py
    return dx * tx + dy * ty, dy * tx - dx * ty


@njit(cache=True, nogil=True, error_model="numpy")
def arc_angle1(u: float, v: float, kappa: float) -> float:
    """Angle (in ``[0, 2 pi)``, along the turn of curvature ``kappa != 0``) of a local
    point's foot on the circle from the piece's start."""
    phi = math.atan2(kappa * u, 1.0 - kappa * v)
    ang = phi if kappa > 0.0 else -phi
    return ang + _TWO_PI if ang < 0.0 else ang


@njit(cache=True, nogil=True, error_model="numpy")
def kappa_interval1(u: float, v: float, wt: float) -> tuple[float, float]:
    """``kappa_bounds`` (``tests/arc_reference.py``) of one local point: the curvatures of
    the circles through it within ``wt`` (``(-inf, inf)`` for a point that close)."""
    den = u * u + v * v - wt * wt
    if den > 0.0:
        return 2.0 * (v - wt) / den, 2.0 * (v + wt) / den
    return -np.inf, np.inf


@njit(cache=True, nogil=True, error_model="numpy")
def arc_xy(px: float, py: float, tx: float, ty: float, kappa: float,
           sigma: float) -> tuple[float, float]:
    """:func:`zwcore.arcs._geometry.arc_points` at one arc length."""
    a = kappa * sigma
    x = sigma * sinc(a / math.pi)
    sc = sinc(a / _TWO_PI)
    y = sigma * (0.5 * a) * (sc * sc)
    return px + x * tx + y * -ty, py + x * ty + y * tx


@njit(cache=True, nogil=True, error_model="numpy")
def sagitta1(kappa: float, length: float) -> float:
    """:func:`zwcore.arcs._geometry.sagitta` of one length."""
    b = 0.25 * kappa * length
    sc = sinc(b / math.pi)
    return abs(length) * abs(b) * 0.5 * (sc * sc)


@njit(cache=True, nogil=True, error_model="numpy")
def reach_lines(samples: FloatArray, ps: FloatArray, ts: FloatArray, ks: IntArray, b: int,
                stride: int, wt: float) -> tuple[IntArray, IntArray]:
    """Last sample each junction ``(C,)`` covers with one piece, and with one line.

    Junction ``c`` starts at ``ps[c]`` with tangent ``ts[c]`` standing for sample
    ``ks[c]``; the samples scanned are those of the grid ``k0 + 1 + stride * i``
    (``k0 = ks.min()``) after ``ks[c]``, up to ``b``, with working half-width ``wt``
    (see :meth:`zwcore.arcs._pieces.ToleranceBand.reach_with_lines`).
    """
    c = len(ps)
    reach = np.full(c, b, dtype=np.int64)
    lreach = np.full(c, b, dtype=np.int64)
    if c == 0:
        return reach, lreach
    k0 = ks.min()
    for i in range(c):
        px, py, tx, ty = ps[i, 0], ps[i, 1], ts[i, 0], ts[i, 1]
        col = k0 + 1 + stride * ((ks[i] - k0 - 1) // stride + 1)
        lo, up = -np.inf, np.inf
        r, lr = b, b
        line_alive = True
        while col <= b:
            u, v = local1(samples[col, 0], samples[col, 1], px, py, tx, ty)
            lo_i, up_i = kappa_interval1(u, v, wt)
            lo = max(lo, lo_i)
            up = min(up, up_i)
            if lo > up:
                r = col - 1
                break
            if line_alive and (abs(v) > wt or u < -wt):
                lr = col - 1
                line_alive = False
            col += stride
        reach[i] = r
        lreach[i] = min(lr, r)
    return reach, lreach


@njit(cache=True, nogil=True, error_model="numpy")
def _bounds_scan(samples: FloatArray, px: float, py: float, tx: float, ty: float, k: int,
                 b: int, wt: float, lo_out: FloatArray, up_out: FloatArray) -> int:
    """Running curvature bounds from sample ``k + 1`` on, written to ``lo_out, up_out``
    while they fit (both may be empty: only counted); the number of feasible samples."""
    lo, up = -np.inf, np.inf
    cap = len(lo_out)
    for i in range(k + 1, b + 1):
        u, v = local1(samples[i, 0], samples[i, 1], px, py, tx, ty)
        lo_i, up_i = kappa_interval1(u, v, wt)
        lo = max(lo, lo_i)
        up = min(up, up_i)
        if lo > up:
            return i - k - 1
        n = i - k - 1
        if n < cap:
            lo_out[n] = lo
            up_out[n] = up
    return b - k


@njit(cache=True, nogil=True, error_model="numpy")
def piece_bounds(samples: FloatArray, px: float, py: float, tx: float, ty: float, k: int,
                 b: int, wt: float) -> tuple[FloatArray, FloatArray]:
    """Running curvature bounds ``(n,)`` of the longest feasible piece from ``(p, t)``
    at sample ``k``: samples ``k+1..k+n`` are reachable (see
    :meth:`zwcore.arcs._pieces.ToleranceBand.longest_piece_bounds`)."""
    empty = np.empty(0)
    n = _bounds_scan(samples, px, py, tx, ty, k, b, wt, empty, empty)
    lo = np.empty(n)
    up = np.empty(n)
    _bounds_scan(samples, px, py, tx, ty, k, b, wt, lo, up)
    return lo, up


@njit(cache=True, nogil=True, error_model="numpy")
def _pymod(a: float, b: float) -> float:
    """``numpy.mod`` of two numbers (the sign of the divisor)."""
    m = np.fmod(a, b)
    if m != 0.0:
        if (b < 0.0) != (m < 0.0):
            m += b
    else:
        m = math.copysign(0.0, b)
    return m


@njit(cache=True, nogil=True, error_model="numpy")
def foot_positions(u: FloatArray, v: FloatArray, kappa: float, sig: FloatArray) -> None:
    """``foot_positions`` of ``tests/arc_reference.py`` written to ``sig`` ``(n,)`` (the angles
    unwrapped as :func:`numpy.unwrap` does)."""
    n = len(u)
    if kappa == 0.0:
        for i in range(n):
            sig[i] = u[i]
        if n:
            sig[0] = 0.0
        return
    wrap = False
    for i in range(n):
        sig[i] = math.atan2(kappa * u[i], 1.0 - kappa * v[i]) if i else 0.0
        if i and not abs(sig[i] - sig[i - 1]) < math.pi:
            wrap = True
    if wrap:
        corr = 0.0
        prev = sig[0]
        for i in range(1, n):
            dd = sig[i] - prev
            prev = sig[i]
            ddmod = _pymod(dd + math.pi, _TWO_PI) - math.pi
            if ddmod == -math.pi and dd > 0.0:
                ddmod = math.pi
            if not abs(dd) < math.pi:
                corr += ddmod - dd
            else:
                corr += 0.0
            sig[i] = sig[i] + corr
    for i in range(n):
        sig[i] = sig[i] / kappa


@njit(cache=True, nogil=True, error_model="numpy")
def seg_dist(x: float, y: float, ax: float, ay: float, bx: float, by: float) -> float:
    """Distance of ``(x, y)`` to the segment ``a-b`` (as
    :func:`zwcore.arcs._geometry.points_to_segments_distance`)."""
    abx = bx - ax
    aby = by - ay
    den = abx * abx + aby * aby
    if not den > 0.0:
        den = 1.0
    apx = x - ax
    apy = y - ay
    s = min(max((apx * abx + apy * aby) / den, 0.0), 1.0)
    return math.hypot(apx - s * abx, apy - s * aby)


@njit(cache=True, nogil=True, error_model="numpy")
def arc_near_polyline(samples: FloatArray, px: float, py: float, tx: float, ty: float,
                      kappa: float, s0: float, s1: float, a: int, b: int, tol: float,
                      step0: float) -> bool:
    """Dense check of the arc portion ``[s0, s1]`` against polyline segments ``a..b``
    (``arc_near_polyline`` of ``tests/arc_reference.py``; ``step0``: the band's
    ``dense_step``)."""
    if s1 <= s0:
        return True
    n = math.ceil((s1 - s0) / step0) + 1
    if n > 4000:
        return False
    step = (s1 - s0) / (n - 1)
    a = max(a, 0)
    b = min(b, len(samples) - 1)
    lim = tol - 0.5 * step
    for i in range(n):
        sg = s1 if i == n - 1 else i * step + s0
        x, y = arc_xy(px, py, tx, ty, kappa, sg)
        if b <= a:
            d = math.hypot(x - samples[a, 0], y - samples[a, 1])
        else:
            d = np.inf
            for m in range(a, b):
                d = min(d, seg_dist(x, y, samples[m, 0], samples[m, 1], samples[m + 1, 0],
                                    samples[m + 1, 1]))
        if not d <= lim:
            return False
    return True


@njit(cache=True, nogil=True, error_model="numpy")
def _segments_within(u: FloatArray, v: FloatArray, sig: FloatArray, sig_end: float,
                     e0: float, e1: float, e2: float, e3: float, kappa: float, tol: float,
                     dense_first: bool) -> bool:
    """``segments_within`` of ``tests/arc_reference.py``; ``e0..e3``: the end point's offsets
    from the start times the tangent's components, ``(ex-px)tx, (ey-py)ty, (ey-py)tx,
    (ex-px)ty`` (the order of its arithmetic kept); a later foot within
    :data:`_END_SLACK` past ``sig_end`` counts as on the arc."""
    rk = 1.0 / kappa
    for i in range(len(u) - 1):
        if dense_first and i == 0:
            continue
        du = u[i + 1] - u[i]
        dv = v[i + 1] - v[i]
        den = du * du + dv * dv
        if not den > 0.0:
            den = 1.0
        ts = min(max((-u[i] * du + (rk - v[i]) * dv) / den, 0.0), 1.0)
        xu = u[i] + ts * du
        xv = v[i] + ts * dv
        gx = abs(circle_gap1(xu, xv, kappa))
        if sig[i] >= 0.0 and sig[i + 1] <= sig_end * (1.0 + _END_SLACK):
            dx = gx
        else:
            xe = math.hypot(xu - e0 - e1, xv - e2 + e3)
            dx = max(gx, min(math.hypot(xu, xv), xe))
        if not dx <= tol:
            return False
    return True


@njit(cache=True, nogil=True, error_model="numpy")
def _portions_within(samples: FloatArray, k: int, sig: FloatArray, sig_end: float,
                     g: FloatArray, de: FloatArray, e_k: float, kappa: float, tol: float,
                     px: float, py: float, tx: float, ty: float, dense_first: bool,
                     step0: float) -> tuple[bool, float]:
    """The arc portions between consecutive (running-max) foot points within ``tol`` of
    the polyline (``portion_bounds`` of ``tests/arc_reference.py``; with ``dense_first`` the
    first non-empty portion is checked densely instead), and the last clipped foot
    position."""
    n = len(sig)
    run = sig[0]
    arg = 0
    phi_prev = min(max(run, 0.0), sig_end)
    first = dense_first
    for i in range(n - 1):
        nxt = max(run, sig[i + 1])
        phi_next = min(max(nxt, 0.0), sig_end)
        dphi = phi_next - phi_prev
        if dphi > 0.0:
            if first:
                first = False
                if not arc_near_polyline(samples, px, py, tx, ty, kappa, 0.0, phi_next,
                                         k - 1, k + i + 2, tol, step0):
                    return False, phi_next
            else:
                a = arg
                ea = e_k if a == 0 else (g[a] if sig[a] <= sig_end else de[a])
                eb = g[i + 1] if sig[i + 1] <= sig_end else de[i + 1]
                jit = math.hypot(samples[k + a, 0] - samples[k + i, 0],
                                 samples[k + a, 1] - samples[k + i, 1])
                bound = max(ea, eb) + sagitta1(kappa, dphi) + jit
                if not bound <= tol:
                    return False, phi_next
        if sig[i + 1] >= nxt:
            arg = i + 1
        run = nxt
        phi_prev = phi_next
    return True, phi_prev


@njit(cache=True, nogil=True, error_model="numpy")
def verify_piece(samples: FloatArray, px: float, py: float, tx: float, ty: float,
                 kappa: float, k: int, j: int, e_k: float, sig_end: float, given: bool,
                 dense_first: bool, tol: float,
                 step0: float) -> tuple[bool, float, float, float, float]:
    """Two-sided check of the piece ``(p, t, kappa)`` covering samples ``k..j``:
    :meth:`zwcore.arcs._pieces.ToleranceBand.verify` (``given``: ``sig_end`` is the
    piece's length, else it ends at the foot point of sample ``j``; ``step0``: the
    band's ``dense_step``). Returns ``(ok, length, end x, end y, e_end)``."""
    n = j - k + 1
    u = np.empty(n)
    v = np.empty(n)
    g = np.empty(n)
    sig = np.empty(n)
    for i in range(n):
        u[i], v[i] = local1(samples[k + i, 0], samples[k + i, 1], px, py, tx, ty)
        g[i] = abs(circle_gap1(u[i], v[i], kappa))
    foot_positions(u, v, kappa, sig)
    if not given:
        sig_end = sig[n - 1]
    fail = (False, 0.0, 0.0, 0.0, 0.0)
    if not sig_end > 0.0 or abs(kappa * sig_end) > _TWO_PI + 1e-9:
        return fail
    ex, ey = arc_xy(px, py, tx, ty, kappa, sig_end)
    de = np.empty(n)
    for i in range(n):
        de[i] = math.hypot(samples[k + i, 0] - ex, samples[k + i, 1] - ey)
        if i:
            # the sample to the piece: its start, its end or the circle between
            d = math.hypot(u[i], v[i]) if sig[i] < 0.0 else (
                de[i] if sig[i] > sig_end else g[i])
            if not d <= tol:
                return fail
    if kappa != 0.0 and n > 1 and not _segments_within(
            u, v, sig, sig_end, (ex - px) * tx, (ey - py) * ty, (ey - py) * tx,
            (ex - px) * ty, kappa, tol, dense_first):
        return fail
    ok, tail0 = _portions_within(samples, k, sig, sig_end, g, de, e_k, kappa, tol, px, py,
                                 tx, ty, dense_first, step0)
    if not ok:
        return fail
    if given:
        if tail0 < sig_end and not arc_near_polyline(samples, px, py, tx, ty, kappa, tail0,
                                                     sig_end, j - 1, j + 2, tol, step0):
            return fail
    elif tail0 < sig_end * (1.0 - 1e-12):
        return fail
    return True, sig_end, ex, ey, g[n - 1]


@njit(cache=True, nogil=True, error_model="numpy")
def line_spread(samples: FloatArray, i0: int, i1: int, pinned: bool, qx: float,
                qy: float) -> float:
    """Largest distance of samples ``i0..i1`` from their least-squares line (through
    ``(qx, qy)`` when ``pinned``): the third figure of
    :func:`zwcore.arcs._geometry.line_fit`."""
    n = i1 - i0 + 1
    if n <= 0:
        return 0.0
    if pinned:
        cx, cy = qx, qy
    else:
        cx = 0.0
        cy = 0.0
        for i in range(i0, i1 + 1):
            cx += samples[i, 0]
            cy += samples[i, 1]
        cx /= n
        cy /= n
    m00 = m01 = m11 = 0.0
    for i in range(i0, i1 + 1):
        x = samples[i, 0] - cx
        y = samples[i, 1] - cy
        m00 += x * x
        m01 += x * y
        m11 += y * y
    # the principal axis of the 2x2 scatter matrix, in closed form
    th = 0.5 * math.atan2(2.0 * m01, m00 - m11)
    dx, dy = math.cos(th), math.sin(th)
    worst = 0.0
    for i in range(i0, i1 + 1):
        worst = max(worst, abs((samples[i, 1] - cy) * dx - (samples[i, 0] - cx) * dy))
    return worst


@njit(cache=True, nogil=True, error_model="numpy")
def kappa_fits(samples: FloatArray, px: float, py: float, tx: float, ty: float, k: int,
               b: int, wt: float, kappa: float, slack: float) -> bool:
    """True when the curvature ``kappa`` (within ``slack``) is in the interval of every
    sample ``k+1..b`` from the junction ``(p, t)`` at working half-width ``wt``."""
    for i in range(k + 1, b + 1):
        u, v = local1(samples[i, 0], samples[i, 1], px, py, tx, ty)
        den = u * u + v * v - wt * wt
        if den > 0.0 and not (
                2.0 * (v - wt) / den - slack <= kappa <= 2.0 * (v + wt) / den + slack):
            return False
    return True


@njit(cache=True, nogil=True, error_model="numpy")
def last_before(samples: FloatArray, px: float, py: float, tx: float, ty: float,
                kappa: float, k: int, hi: int, s_end: float) -> int:
    """Last sample in ``k..hi`` whose foot point on the piece ``(p, t, kappa)`` lies
    before arc length ``s_end`` (the angles unwrapped from sample ``k + 1`` on, as
    :func:`numpy.unwrap` does)."""
    prev = 0.0
    corr = 0.0
    for i in range(k + 1, hi + 1):
        u, v = local1(samples[i, 0], samples[i, 1], px, py, tx, ty)
        if kappa == 0.0:
            sig = u
        else:
            phi = math.atan2(kappa * u, 1.0 - kappa * v)
            if i > k + 1:
                dd = phi - prev
                if not abs(dd) < math.pi:
                    ddmod = _pymod(dd + math.pi, _TWO_PI) - math.pi
                    if ddmod == -math.pi and dd > 0.0:
                        ddmod = math.pi
                    corr += ddmod - dd
            prev = phi
            sig = (phi + corr) / kappa
        if sig > s_end:
            return i - 1
    return hi


@njit(cache=True, nogil=True, error_model="numpy")
def line_reaches(samples: FloatArray, px: float, py: float, ts: FloatArray, k: int, b: int,
                 wt: float) -> IntArray:
    """Last sample each straight piece from ``p`` (at sample ``k``) along ``ts[c]``
    ``(C, 2)`` keeps within ``wt`` (not behind its start), up to ``b``."""
    out = np.full(len(ts), b, dtype=np.int64)
    for c in range(len(ts)):
        tx, ty = ts[c, 0], ts[c, 1]
        for i in range(k + 1, b + 1):
            u, v = local1(samples[i, 0], samples[i, 1], px, py, tx, ty)
            if abs(v) > wt or u < -wt:
                out[c] = i - 1
                break
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def chord_circle_gap(samples: FloatArray, px: float, py: float, th: float, k: int,
                     b: int) -> float:
    """Largest distance of samples ``k+1..b`` from the circle through ``p`` along the
    direction ``th`` and through sample ``b`` (inf when ``b`` is ``p``)."""
    tx, ty = math.cos(th), math.sin(th)
    ub, vb = local1(samples[b, 0], samples[b, 1], px, py, tx, ty)
    q2 = ub * ub + vb * vb
    if q2 <= 0.0:
        return np.inf
    kap = 2.0 * vb / q2
    worst = 0.0
    for i in range(k + 1, b + 1):
        u, v = local1(samples[i, 0], samples[i, 1], px, py, tx, ty)
        worst = max(worst, abs(circle_gap1(u, v, kap)))
    return worst
