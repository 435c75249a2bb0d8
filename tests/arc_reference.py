"""Plain-numpy reference of the compiled arc kernels (``zwcore/arcs/_kernels.py``,
``zwcore/arcs/_dense.py``): the formulation the fit used before they were compiled, kept
for the property tests in ``tests/test_arc_kernels.py``.

The conservative two-sided bounds of :meth:`zwcore.arcs._pieces.ToleranceBand.verify`:

A piece starts at ``p`` with unit tangent ``t`` and signed curvature ``kappa``; the
samples it stands for are given in its local frame (``u`` along ``t``, ``v`` to the
left). Each function bounds one part of the two-sided distance: the samples to the
piece, the polyline segments' interiors to the piece, and the piece's portions between
consecutive foot points to the polyline.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from zwcore.arcs._geometry import (
    arc_point,
    arc_points,
    local_uv,
    points_to_segments_distance,
    rotate,
    rotate1,
    sagitta,
)
from zwcore.arcs._pieces import Piece
from zwcore.arcs.verify import _densify_idx

FloatArray = NDArray[np.float64]

#: Relative slack past a piece's end within which a segment's later foot is still on the
#: arc (:func:`segments_within`; ``_END_SLACK`` of :mod:`zwcore.arcs._kernels`).
END_SLACK = 1e-12

__all__ = [
    "END_SLACK",
    "biarc",
    "circle_gap",
    "deviations",
    "foot_positions",
    "junction",
    "kappa_bounds",
    "last_on_first_arc",
    "longest_piece_bounds",
    "point_to_arc_distance",
    "portion_bounds",
    "reach_with_lines",
    "samples_within",
    "segments_within",
    "unwrap",
    "verify",
]


# -- numpy geometry (the compiled kernels do these per point) ---------------


def circle_gap(u: FloatArray, v: FloatArray, kappa: float | FloatArray) -> FloatArray:
    """Signed distance of local points to the circle (or line) of curvature ``kappa``.

    Positive means right of the travel direction. The magnitude is the exact
    Euclidean distance to the full circle; the sign convention makes the value
    increase monotonically with ``kappa``, which is what turns each point into an
    interval of admissible curvatures (see :func:`kappa_bounds`).
    """
    w = kappa * (u * u + v * v) - 2.0 * v
    # 1 + kappa*w = (1 - kappa v)^2 + (kappa u)^2 >= 0; the clip only guards rounding.
    return w / (1.0 + np.sqrt(np.maximum(1.0 + kappa * w, 0.0)))


def kappa_bounds(u: FloatArray, v: FloatArray, tol: float) -> tuple[FloatArray, FloatArray]:
    """Curvature interval ``[lo, hi]`` that keeps each point within ``tol`` of the circle.

    Points closer than ``tol`` to the start point impose nothing (the start point
    is on every candidate circle), and get ``(-inf, inf)``.
    """
    den = u * u + v * v - tol * tol
    ok = den > 0.0
    safe = np.where(ok, den, 1.0)
    lo = np.where(ok, 2.0 * (v - tol) / safe, -np.inf)
    hi = np.where(ok, 2.0 * (v + tol) / safe, np.inf)
    return lo, hi


def unwrap(phi: FloatArray) -> FloatArray:
    """``numpy.unwrap(phi)`` (1-D), without its overhead when no step reaches pi."""
    dd = np.diff(phi)
    if dd.size and not float(np.abs(dd).max()) < math.pi:
        return np.unwrap(phi)
    out = np.array(phi, dtype=np.float64, copy=True)
    out[1:] += 0.0  # (as numpy.unwrap adds its zero corrections: -0.0 becomes 0.0)
    return out


def point_to_arc_distance(
    pts: FloatArray, p: FloatArray, t: FloatArray, kappa: float, length: float
) -> FloatArray:
    """Exact distance of ``pts`` ``(M, 2)`` to the piece of arc length ``length`` from ``p``."""
    u, v = local_uv(p, t, pts)
    end = arc_points(p, t, kappa, np.array([length]))[0]
    d_ends = np.minimum(np.hypot(u, v), np.hypot(pts[:, 0] - end[0], pts[:, 1] - end[1]))
    if kappa == 0.0:
        inside = (u >= 0.0) & (u <= length)
        return np.where(inside, np.abs(v), d_ends)
    phi = np.arctan2(kappa * u, 1.0 - kappa * v)
    sweep = abs(kappa * length)
    ang = np.mod(phi * np.sign(kappa), 2.0 * np.pi)
    # points at the centre itself: every arc point is at the radius
    inside = ang <= sweep
    gap = np.abs(circle_gap(u, v, kappa))
    return np.where(inside, np.minimum(gap, d_ends), d_ends)


def foot_positions(u: FloatArray, v: FloatArray, kappa: float) -> FloatArray:
    """Arc-length position ``(n,)`` of each sample's foot point on the piece (the first
    sample, the piece's start, at 0)."""
    if kappa != 0.0:
        phi = np.arctan2(kappa * u, 1.0 - kappa * v)
        phi[0] = 0.0
        return unwrap(phi) / kappa
    sig = u.copy()
    sig[0] = 0.0
    return sig


def samples_within(
    u: FloatArray, v: FloatArray, g: FloatArray, sig: FloatArray, sig_end: float,
    de: FloatArray, tol: float,
) -> bool:
    """True when every sample after the first is within ``tol`` of the piece: its gap
    ``g`` to the circle, or its distance to the start (foot before it) or to the end
    (``de``, foot after it)."""
    q = np.hypot(u, v)
    before = sig < 0.0
    after = sig > sig_end
    d = np.where(before, q, np.where(after, de, g))
    return not (d.size > 1 and d[1:].max() > tol)


def segments_within(
    u: FloatArray, v: FloatArray, sig: FloatArray, sig_end: float, p: FloatArray,
    t: FloatArray, end: FloatArray, kappa: float, tol: float, dense_first: bool,
    end_slack: float = END_SLACK,
) -> bool:
    """True when the interiors of the polyline segments are within ``tol`` of the arc
    (``kappa != 0``): the farthest point from a circle on a segment is an end point or
    the point closest to the centre. The piece starts at ``p`` along ``t`` and ends at
    ``end``; ``dense_first`` skips the first segment (checked densely by the caller).

    A segment counts as inside the arc when its later foot is at most ``sig_end * (1 +
    end_slack)``: the bound of a segment reaching past the end is far coarser, so the
    decision jumps where a foot lies at the end (a sample the piece ends on), and which
    side of it an ulp of ``arctan2`` puts the foot on is rounding, not geometry: the
    default :data:`END_SLACK` takes such feet as on the arc, as the kernel does."""
    du = np.diff(u)
    dv = np.diff(v)
    den = du * du + dv * dv
    den = np.where(den > 0.0, den, 1.0)
    ts = np.clip((-u[:-1] * du + (1.0 / kappa - v[:-1]) * dv) / den, 0.0, 1.0)
    xu = u[:-1] + ts * du
    xv = v[:-1] + ts * dv
    gx = np.abs(circle_gap(xu, xv, kappa))
    inside = (sig[:-1] >= 0.0) & (sig[1:] <= sig_end * (1.0 + end_slack))
    xe = np.hypot(
        xu - (end[0] - p[0]) * t[0] - (end[1] - p[1]) * t[1],
        xv - (end[1] - p[1]) * t[0] + (end[0] - p[0]) * t[1],
    )
    dx = np.where(inside, gx, np.maximum(gx, np.minimum(np.hypot(xu, xv), xe)))
    if dense_first:
        dx[0] = 0.0
    return not dx.max() > tol


def portion_bounds(
    pts: FloatArray, sig: FloatArray, sig_end: float, g: FloatArray, de: FloatArray,
    e_k: float, kappa: float,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Bounds on the distance of the arc portions between consecutive (running-max) foot
    points to the polyline.

    Returns ``(bound, dphi, phi_c)``: the bound per portion ``(n-1,)``, the portions'
    lengths (0: empty) and the clipped running foot positions ``(n,)``. ``e_k`` is the
    distance of the first sample from the piece's start.
    """
    run = np.maximum.accumulate(sig)
    phi_c = np.clip(run, 0.0, sig_end)
    idx = np.arange(len(sig))
    arg = np.maximum.accumulate(np.where(sig >= run, idx, 0))
    e_at = np.where(sig <= sig_end, g, de)
    e_at[0] = e_k
    dphi = np.diff(phi_c)
    a_idx = arg[:-1]
    jit = np.hypot(pts[a_idx, 0] - pts[:-1, 0], pts[a_idx, 1] - pts[:-1, 1])
    bound = np.maximum(e_at[a_idx], e_at[1:]) + sagitta(kappa, dphi) + jit
    return bound, dphi, phi_c


def arc_near_polyline(samples: FloatArray, tol: float, dense_step: float, p: FloatArray,
                      t: FloatArray, kappa: float, s0: float, s1: float, a: int,
                      b: int) -> bool:
    """Dense check of the arc portion ``[s0, s1]`` against polyline segments ``a..b``."""
    if s1 <= s0:
        return True
    n = math.ceil((s1 - s0) / dense_step) + 1
    if n > 4000:
        return False
    step = (s1 - s0) / (n - 1)
    pts = arc_points(p, t, kappa, np.linspace(s0, s1, n))
    a = max(a, 0)
    b = min(b, len(samples) - 1)
    if b <= a:
        d = np.hypot(pts[:, 0] - samples[a, 0], pts[:, 1] - samples[a, 1])
    else:
        d = points_to_segments_distance(pts, samples[a:b], samples[a + 1 : b + 1]).min(axis=1)
    return bool(d.max() <= tol - 0.5 * step)


def verify(samples: FloatArray, tol: float, dense_step: float, p: FloatArray,
           t: FloatArray, kappa: float, k: int, j: int, e_k: float,
           sig_end: float | None = None, dense_first: bool = False,
           end_slack: float = END_SLACK) -> tuple[float, FloatArray, float] | None:
    """:meth:`zwcore.arcs._pieces.ToleranceBand.verify` in numpy (``end_slack``: see
    :func:`segments_within`)."""
    pts = samples[k : j + 1]
    u, v = local_uv(p, t, pts)
    g = np.abs(circle_gap(u, v, kappa))
    sig = foot_positions(u, v, kappa)
    given_end = sig_end is not None
    if sig_end is None:
        sig_end = float(sig[-1])
    if not sig_end > 0.0 or abs(kappa * sig_end) > 2.0 * math.pi + 1e-9:
        return None
    end = arc_point(p, t, kappa, sig_end)
    de = np.hypot(pts[:, 0] - end[0], pts[:, 1] - end[1])
    if not samples_within(u, v, g, sig, sig_end, de, tol):
        return None
    if kappa != 0.0 and len(pts) > 1 and not segments_within(
            u, v, sig, sig_end, p, t, end, kappa, tol, dense_first, end_slack):
        return None
    bound, dphi, phi_c = portion_bounds(pts, sig, sig_end, g, de, e_k, kappa)
    if dphi.size:
        mask = dphi > 0.0
        if dense_first:
            first = np.flatnonzero(mask)
            if first.size:
                f0 = int(first[0])
                mask[f0] = False
                if not arc_near_polyline(samples, tol, dense_step, p, t, kappa, 0.0,
                                         float(phi_c[f0 + 1]), k - 1, k + f0 + 2):
                    return None
        if np.any(bound[mask] > tol):
            return None
    tail0 = float(phi_c[-1])
    if given_end:
        if tail0 < sig_end and not arc_near_polyline(samples, tol, dense_step, p, t, kappa,
                                                     tail0, sig_end, j - 1, j + 2):
            return None
    elif tail0 < sig_end * (1.0 - 1e-12):
        return None
    return sig_end, end, float(g[-1])


def reach_with_lines(samples: FloatArray, wt: float, stride: int, ps: FloatArray,
                     ts: FloatArray, ks: NDArray[np.int64], b: int,
                     ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """:meth:`zwcore.arcs._pieces.ToleranceBand.reach_with_lines` in numpy (windows of
    junctions and samples)."""
    c = len(ps)
    reach = np.full(c, b, dtype=np.int64)
    lreach = np.full(c, b, dtype=np.int64)
    if c == 0:
        return reach, lreach
    k0 = int(ks.min())
    pos = k0 + 1 + stride * ((ks - k0 - 1) // stride + 1)
    lo_run = np.full(c, -np.inf)
    up_run = np.full(c, np.inf)
    ltodo = np.ones(c, dtype=bool)
    todo = np.flatnonzero(pos <= b)
    w = 64
    while todo.size:
        n = max(16, min(max(1, w // stride), int(3e6 // todo.size)))
        cols = pos[todo, None] + stride * np.arange(n)[None, :]
        valid = cols <= b
        u, v = local_uv(ps[todo, None, :], ts[todo, None, :], samples[np.minimum(cols, b)])
        lo, up = kappa_bounds(u, v, wt)
        lo = np.maximum(lo_run[todo, None],
                        np.maximum.accumulate(np.where(valid, lo, -np.inf), axis=1))
        up = np.minimum(up_run[todo, None],
                        np.minimum.accumulate(np.where(valid, up, np.inf), axis=1))
        bad = lo > up
        anyb = bad.any(axis=1)
        reach[todo[anyb]] = cols[anyb, np.argmax(bad[anyb], axis=1)] - 1
        lb = ((np.abs(v) > wt) | (u < -wt)) & valid
        lsel = lb.any(axis=1) & ltodo[todo]
        lreach[todo[lsel]] = cols[lsel, np.argmax(lb[lsel], axis=1)] - 1
        ltodo[todo[lsel]] = False
        lo_run[todo] = lo[:, -1]
        up_run[todo] = up[:, -1]
        pos[todo] += stride * n
        todo = todo[~anyb & (pos[todo] <= b)]
        w *= 2
    return reach, np.minimum(lreach, reach)


def longest_piece_bounds(samples: FloatArray, wt: float, p: FloatArray, t: FloatArray,
                         k: int, b: int) -> tuple[FloatArray, FloatArray]:
    """:meth:`zwcore.arcs._pieces.ToleranceBand.longest_piece_bounds` in numpy."""
    u, v = local_uv(p, t, samples[k + 1 : b + 1])
    lo, up = kappa_bounds(u, v, wt)
    lo = np.maximum.accumulate(lo)
    up = np.minimum.accumulate(up)
    bad = np.flatnonzero(lo > up)
    n = int(bad[0]) if bad.size else len(lo)
    return lo[:n], up[:n]


def _piece_points(pc: Piece, step: float) -> tuple[FloatArray, FloatArray]:
    n = max(math.ceil(pc.length / step), 1) + 1
    sig = np.linspace(0.0, pc.length, n)
    pts = arc_points(pc.p, pc.t, pc.kappa, sig)
    pts[-1] = pc.end
    return pts, sig


def _foot_positions(pc: Piece, pts: FloatArray) -> FloatArray:
    """Arc-length positions along ``pc`` of ``pts`` (unwrapped from the first)."""
    u, v = local_uv(pc.p, pc.t, pts)
    if pc.kappa == 0.0:
        return u
    phi = np.arctan2(pc.kappa * u, 1.0 - pc.kappa * v)
    phi[0] = 0.0
    return np.asarray(np.unwrap(phi) / pc.kappa)


def _dist_all_segments(pts: FloatArray, poly: FloatArray) -> FloatArray:
    out = np.full(len(pts), np.inf)
    a, b = poly[:-1], poly[1:]
    chunk = max(1, int(2e6 // max(len(a), 1)))
    for i in range(0, len(pts), chunk):
        out[i : i + chunk] = points_to_segments_distance(pts[i : i + chunk], a, b).min(axis=1)
    return out


def deviations(samples: FloatArray, pieces: Sequence[Piece], tol: float) -> tuple[float, float]:
    """:func:`zwcore.arcs.verify.deviations` in numpy: the dense two-sided deviation
    ``(polyline -> chain, chain -> polyline)``.

    ``samples`` is the polyline the pieces were fitted to (piece ``k``/``j`` index it).
    """
    nseg = len(samples) - 1
    length = float(np.hypot(*(np.diff(samples, axis=0).T)).sum())
    total = length + sum(pc.length for pc in pieces)
    step = max(tol / 20.0, total / 2e6)
    # polyline -> chain
    dpoly, sid = _densify_idx(samples, step)
    d_p = np.full(len(dpoly), np.inf)
    for pc in pieces:
        lo = int(np.searchsorted(sid, max(pc.k - 2, 0), side="left"))
        hi = int(np.searchsorted(sid, min(pc.j + 2, nseg), side="right"))
        if hi > lo:
            dd = point_to_arc_distance(dpoly[lo:hi], pc.p, pc.t, pc.kappa, pc.length)
            np.minimum(d_p[lo:hi], dd, out=d_p[lo:hi])
    hot = np.flatnonzero(d_p > tol)
    if hot.size:
        best = np.full(hot.size, np.inf)
        for pc in pieces:
            best = np.minimum(best, point_to_arc_distance(dpoly[hot], pc.p, pc.t, pc.kappa,
                                                          pc.length))
        d_p[hot] = best
    # chain -> polyline (segment figures gathered from 1-D arrays: gathering rows of
    # the (M, 2) arrays per offset costs more than the arithmetic)
    d_c_max = 0.0
    ax, ay = samples[:-1, 0].copy(), samples[:-1, 1].copy()
    abx, aby = samples[1:, 0] - ax, samples[1:, 1] - ay
    den_all = np.maximum(abx * abx + aby * aby, 1e-300)
    for pc in pieces:
        cpts, sig = _piece_points(pc, step)
        k, j = max(pc.k, 0), min(pc.j, nseg)
        if nseg == 0:
            d = np.hypot(*(cpts - samples[0]).T)
        else:
            foot = np.maximum.accumulate(_foot_positions(pc, samples[k : j + 1]))
            m = k + np.searchsorted(foot, sig, side="right") - 1
            d = np.full(len(cpts), np.inf)
            cx, cy = cpts[:, 0], cpts[:, 1]
            for off in range(-3, 4):
                s = np.clip(m + off, 0, nseg - 1)
                sx, sy = abx[s], aby[s]
                apx, apy = cx - ax[s], cy - ay[s]
                f = np.clip((apx * sx + apy * sy) / den_all[s], 0.0, 1.0)
                np.minimum(d, np.hypot(apx - f * sx, apy - f * sy), out=d)
            hotc = np.flatnonzero(d > tol)
            if hotc.size:
                d[hotc] = _dist_all_segments(cpts[hotc], samples)
        d_c_max = max(d_c_max, float(d.max()))
    return float(d_p.max()), d_c_max


def junction(
    p0: FloatArray, t0: FloatArray, p1: FloatArray, t1: FloatArray, f: float
) -> FloatArray | None:
    """The junction of the biarc from ``(p0, t0)`` to ``(p1, t1)`` whose first tangent
    leg is ``f`` chords long, or None when that biarc does not exist."""
    vv = p1 - p0
    dist2 = float(vv @ vv)
    dist = math.sqrt(dist2)
    vt0 = float(vv @ t0)
    vt1 = float(vv @ t1)
    t01 = float(t0 @ t1)
    d1 = f * dist
    den = vt1 - d1 * (t01 - 1.0)
    if abs(den) < 1e-300:
        return None
    d2 = (0.5 * dist2 - d1 * vt0) / den
    if not (d2 > 0.0 and math.isfinite(d2)):
        return None
    p0x, p0y, t0x, t0y = float(p0[0]), float(p0[1]), float(t0[0]), float(t0[1])
    p1x, p1y, t1x, t1y = float(p1[0]), float(p1[1]), float(t1[0]), float(t1[1])
    # (per coordinate: numpy's overhead on two elements dominates)
    return np.array([
        (d2 * (p0x + d1 * t0x) + d1 * (p1x - d2 * t1x)) / (d1 + d2),
        (d2 * (p0y + d1 * t0y) + d1 * (p1y - d2 * t1y)) / (d1 + d2)])


def last_on_first_arc(
    uu: FloatArray, vv: FloatArray, k1: float, s1: float, k: int, b: int
) -> int:
    """The last sample (in ``k..b-1``) whose foot point lies on the first arc (curvature
    ``k1``, length ``s1``); ``uu, vv`` are samples ``k..b`` in the start frame."""
    if k1 != 0.0:
        ph = np.arctan2(k1 * uu, 1.0 - k1 * vv)
        ph[0] = 0.0
        sg = unwrap(ph) / k1
    else:
        sg = uu
    over = np.flatnonzero(sg > s1)
    m = k + (int(over[0]) - 1 if over.size else b - k - 1)
    return min(max(m, k), b - 1)


def _arc_through(kmin: float, kcap: float, p: FloatArray, t: FloatArray, q: FloatArray,
                 dist: float) -> tuple[float, float] | None:
    """The numpy reference of :func:`zwcore.arcs._biarc.arc_through` (radii ``1/kcap..1/kmin``)."""
    dx = float(q[0] - p[0])
    dy = float(q[1] - p[1])
    u = dx * float(t[0]) + dy * float(t[1])
    v = dy * float(t[0]) - dx * float(t[1])
    q2 = u * u + v * v
    if q2 <= 0.0:
        return None
    k = 2.0 * v / q2
    if abs(k) < 1e-15 * max(1.0 / dist, 1.0):
        k = 0.0
    length = u if k == 0.0 else math.atan2(k * u, 1.0 - k * v) / k
    if not length > 0.0 or not (k == 0.0 or kmin <= abs(k) <= kcap):
        return None
    return k, length


def biarc(samples: FloatArray, tol: float, dense_step: float, kmin: float, kcap: float,
          p0: FloatArray, t0: FloatArray, k: int, e: float, b: int, t1: FloatArray,
          p1: FloatArray | None, splits: tuple[float, ...],
          end_slack: float = END_SLACK) -> list[Piece] | None:
    """:meth:`zwcore.arcs._pieces.ToleranceBand.biarc` in numpy (with :func:`verify`;
    ``end_slack``: see :func:`segments_within`)."""

    def _verify(p, t, kappa, k, j, e_k, sig_end=None,  # type: ignore[no-untyped-def]
                dense_first=False):
        return verify(samples, tol, dense_step, p, t, kappa, k, j, e_k, sig_end, dense_first,
                      end_slack)

    def _make_piece(p, t, kappa, k, j, verified):  # type: ignore[no-untyped-def]
        length, end, e_end = verified
        return Piece(p, t, kappa, length, k, j, end, rotate1(t, kappa * length), e_end)

    at_sample = p1 is None
    p1 = samples[b] if p1 is None else p1
    vv = p1 - p0
    dist2 = float(vv @ vv)
    if dist2 <= 0.0:
        return None
    dist = math.sqrt(dist2)
    # the samples in the start frame, and the curvatures that keep samples k+1..i
    # within (a hair more than) tol of the first arc's circle: a first arc outside
    # them fails verification, so it is not verified (most tried splits end there)
    uu, vv2 = local_uv(p0, t0, samples[k : b + 1])
    lo_t, up_t = kappa_bounds(uu[1:], vv2[1:], tol * (1.0 + 1e-6))
    lo_t = np.maximum.accumulate(lo_t)
    up_t = np.minimum.accumulate(up_t)
    for f in splits:
        jn = junction(p0, t0, p1, t1, f)
        if jn is None:
            continue
        first = _arc_through(kmin, kcap, p0, t0, jn, dist)
        if first is None:
            continue
        k1, s1 = first
        tj = rotate1(t0, k1 * s1)
        # None also when the junction fell on the end point: no second arc.
        second = _arc_through(kmin, kcap, jn, tj, p1, dist)
        if second is None:
            continue
        k2, s2 = second
        te = rotate1(tj, k2 * s2)
        if abs(te[0] * t1[1] - te[1] * t1[0]) > 1e-9 or te @ t1 < 0:
            continue
        # split the samples: those whose foot point lies on the first arc
        m = last_on_first_arc(uu, vv2, k1, s1, k, b)
        if m > k and not lo_t[m - k - 1] <= k1 <= up_t[m - k - 1]:
            continue
        r1 = _verify(p0, t0, k1, k, m, e, sig_end=s1)
        if r1 is None:
            continue
        # the second arc starts at the junction, which stands for sample m
        e_m = float(np.hypot(*(samples[m] - jn)))
        r2 = _verify(jn, tj, k2, m, b, e_m, sig_end=s2, dense_first=True)
        if r2 is None:
            continue
        a1 = _make_piece(p0, t0, k1, k, m, r1)
        a1.end = jn
        a1.t_end = tj
        a2 = _make_piece(jn, tj, k2, m, b, r2)
        a2.end = p1.copy()
        a2.t_end = t1.copy()
        if not at_sample:
            a2.e_end = float(np.hypot(*(samples[b] - p1)))
        return [a1, a2]
    return None




def candidates(samples: FloatArray, cum: FloatArray, p: FloatArray, t: FloatArray, k: int,
               jm: int, lo1: FloatArray, up1: FloatArray, j_fractions: FloatArray,
               k_fractions: FloatArray, kcap: float,
               ) -> tuple[NDArray[np.int64], FloatArray, FloatArray, FloatArray, FloatArray]:
    """:func:`zwcore.arcs._kernels.candidates` in numpy (the beam's candidate pieces)."""
    span = cum[jm] - cum[k]
    at = np.searchsorted(cum, cum[k] + j_fractions * span, side="right")
    js = sorted({min(max(int(i) - 1, k + 1), jm) for i in at}, reverse=True)
    ja = np.array(js, dtype=np.int64)
    lo = np.maximum(lo1[ja - k - 1], -kcap)
    hi = np.minimum(up1[ja - k - 1], kcap)
    ok = lo <= hi
    vals = np.concatenate(
        [np.zeros((len(ja), 1)), lo[:, None] + k_fractions[None, :] * (hi - lo)[:, None]],
        axis=1)
    mask = np.concatenate(
        [(ok & (lo <= 0.0) & (hi >= 0.0))[:, None],
         np.repeat(ok[:, None], len(k_fractions), axis=1)], axis=1)
    jj = np.repeat(ja[:, None], vals.shape[1], axis=1)[mask]
    kk = vals[mask]
    u, v = local_uv(p, t, samples[jj])
    line = kk == 0.0
    sj = np.where(line, u, np.arctan2(kk * u, 1.0 - kk * v) / np.where(line, 1.0, kk))
    return (jj, kk, arc_points(p, t, kk, sj), rotate(t, kk * sj),
            np.where(line, 0.3 * (cum[jj] - cum[k]), 0.0))
