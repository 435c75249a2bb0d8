"""Compiled biarc of the tolerance band (:meth:`zwcore.arcs._pieces.ToleranceBand.biarc`):
two tangent arcs from a junction ``(p0, t0)`` to a point ``p1`` arriving along ``t1``,
the junction tried at several places along the chord, each pair verified two-sided with
:func:`zwcore.arcs._kernels.verify_piece`. Most tried junctions fail a cheap curvature
test first; in numpy each try cost some thirty small array operations.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from zwcore.arcs._kernels import _TWO_PI, _pymod, local1, verify_piece

FloatArray = NDArray[np.float64]

__all__ = ["arc_through", "biarc"]


@njit(cache=True, nogil=True, error_model="numpy")
def arc_through(px: float, py: float, tx: float, ty: float, qx: float, qy: float,
                dist: float, kmin: float, kcap: float) -> tuple[bool, float, float]:
    """Curvature and length of the arc from ``p`` along ``t`` through ``q``: ``(ok, kappa,
    length)``; ``dist`` is the scale below which a curvature counts as a line, ``ok`` false
    when ``q`` is ``p``, the arc is degenerate or its radius is not in
    ``1/kcap..1/kmin``."""
    u, v = local1(qx, qy, px, py, tx, ty)
    q2 = u * u + v * v
    if q2 <= 0.0:
        return False, 0.0, 0.0
    kap = 2.0 * v / q2
    if abs(kap) < 1e-15 * max(1.0 / dist, 1.0):
        kap = 0.0  # numerically straight: a line
    length = u if kap == 0.0 else math.atan2(kap * u, 1.0 - kap * v) / kap
    ok = length > 0.0 and (kap == 0.0 or (abs(kap) >= kmin and abs(kap) <= kcap))
    return ok, kap, length


@njit(cache=True, nogil=True, error_model="numpy")
def _biarc_junction(p0x: float, p0y: float, t0x: float, t0y: float, p1x: float, p1y: float,
                    t1x: float, t1y: float, f: float) -> tuple[bool, float, float]:
    """The junction of the biarc whose first tangent leg is ``f`` chords long: ``(ok, x, y)``."""
    vx = p1x - p0x
    vy = p1y - p0y
    dist2 = vx * vx + vy * vy
    dist = math.sqrt(dist2)
    vt0 = vx * t0x + vy * t0y
    vt1 = vx * t1x + vy * t1y
    t01 = t0x * t1x + t0y * t1y
    d1 = f * dist
    den = vt1 - d1 * (t01 - 1.0)
    if abs(den) < 1e-300:
        return False, 0.0, 0.0
    d2 = (0.5 * dist2 - d1 * vt0) / den
    if not (d2 > 0.0 and math.isfinite(d2)):
        return False, 0.0, 0.0
    return (True, (d2 * (p0x + d1 * t0x) + d1 * (p1x - d2 * t1x)) / (d1 + d2),
            (d2 * (p0y + d1 * t0y) + d1 * (p1y - d2 * t1y)) / (d1 + d2))


@njit(cache=True, nogil=True, error_model="numpy")
def _last_on_first_arc(uu: FloatArray, vv: FloatArray, k1: float, s1: float, k: int,
                       b: int, limit: int) -> int:
    """The last sample (in ``k..b-1``) whose foot point lies on the first arc of a biarc
    (``uu, vv``: samples ``k..b`` in its start frame): the foot positions of
    :func:`zwcore.arcs._kernels.foot_positions` (angles unwrapped as :func:`numpy.unwrap`
    does, a correction at each step of pi or more), computed only up to the first one
    past the arc's end ``s1`` (each depends on the earlier ones only), and only up to
    ``uu[limit]``: -1 when none up to there is past it (the answer is at least
    ``k + limit``, or ``b - 1``)."""
    m = b - 1
    if k1 == 0.0:
        for i in range(min(len(uu), limit + 1)):
            if uu[i] > s1:
                m = k + i - 1
                break
        else:
            if limit + 1 < len(uu):
                return -1
        return min(max(m, k), b - 1)
    prev = 0.0
    corr = 0.0
    for i in range(len(uu)):
        if i > limit:
            return -1
        val = 0.0
        if i:
            raw = math.atan2(k1 * uu[i], 1.0 - k1 * vv[i])
            dd = raw - prev
            prev = raw
            if not abs(dd) < math.pi:
                ddmod = _pymod(dd + math.pi, _TWO_PI) - math.pi
                if ddmod == -math.pi and dd > 0.0:
                    ddmod = math.pi
                corr += ddmod - dd
            val = raw + corr
        if val / k1 > s1:
            m = k + i - 1
            break
    return min(max(m, k), b - 1)


@njit(cache=True, nogil=True, error_model="numpy")
def _first_outside(lo_t: FloatArray, up_t: FloatArray, kappa: float) -> int:
    """The first index where ``kappa`` is not within the running bounds ``lo_t``
    (non-decreasing) and ``up_t`` (non-increasing) ``(n,)``, by bisection (``n``:
    never)."""
    lo, hi = 0, len(lo_t)
    while lo < hi:
        mid = (lo + hi) // 2
        if lo_t[mid] <= kappa <= up_t[mid]:
            lo = mid + 1
        else:
            hi = mid
    return lo


@njit(cache=True, nogil=True, error_model="numpy")
def _first_arc_table(samples: FloatArray, p0: FloatArray, t0: FloatArray, k: int, b: int,
                     tol: float) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Samples ``k..`` in the frame of ``(p0, t0)`` (``uu, vv``) and the running
    curvature bounds ``lo_t, up_t`` of a first arc from there (see :func:`biarc`)."""
    n = b - k + 1
    uu_all = np.empty(n)
    vv_all = np.empty(n)
    # the curvatures that keep samples k+1..i within (a hair more than) tol of the first
    # arc's circle: a first arc outside them fails verification, so it is not verified.
    # The table ends at the first empty interval (every curvature fails there and, the
    # bounds narrowing, beyond: :func:`_first_outside` answers the same), and the local
    # coordinates two samples past it (the foot scan stops one past the first failure)
    lo_t_all = np.empty(max(n - 1, 0))
    up_t_all = np.empty(max(n - 1, 0))
    wt = tol * (1.0 + 1e-6)
    lo, up = -np.inf, np.inf
    n_t = n - 1
    n_uv = n
    for i in range(n):
        dx = samples[k + i, 0] - p0[0]
        dy = samples[k + i, 1] - p0[1]
        uu_all[i] = dx * t0[0] + dy * t0[1]
        vv_all[i] = dy * t0[0] - dx * t0[1]
        if i == 0 or i > n_t:
            if i >= n_uv - 1:
                break
            continue
        den = uu_all[i] * uu_all[i] + vv_all[i] * vv_all[i] - wt * wt
        if den > 0.0:
            lo = max(lo, 2.0 * (vv_all[i] - wt) / den)
            up = min(up, 2.0 * (vv_all[i] + wt) / den)
        lo_t_all[i - 1] = lo
        up_t_all[i - 1] = up
        if lo > up:
            n_t = i
            n_uv = min(n, n_t + 2)
    uu, vv = uu_all[:n_uv], vv_all[:n_uv]
    lo_t, up_t = lo_t_all[:n_t], up_t_all[:n_t]
    return uu, vv, lo_t, up_t


@njit(cache=True, nogil=True, error_model="numpy")
def biarc(samples: FloatArray, p0: FloatArray, t0: FloatArray, k: int, e: float, b: int,
          t1: FloatArray, p1: FloatArray, splits: FloatArray, tol: float, step0: float,
          kmin: float, kcap: float) -> tuple[int, FloatArray, int]:
    """:meth:`zwcore.arcs._pieces.ToleranceBand.biarc` from ``(p0, t0)`` (sample ``k``,
    distance ``e``) to ``p1`` (standing for sample ``b``) arriving along ``t1``.

    Returns the index of the first split that gave a verified pair (-1: none), the
    pair's figures ``(k1, s1, jx, jy, tjx, tjy, e1, k2, s2, e2)`` (curvature and length
    of both arcs, the junction, its tangent, each arc's ``e_end``) and the last sample
    of the first arc.
    """
    out = np.zeros(10)
    vx = p1[0] - p0[0]
    vy = p1[1] - p0[1]
    dist2 = vx * vx + vy * vy
    if dist2 <= 0.0:
        return -1, out, 0
    dist = math.sqrt(dist2)
    n = b - k + 1
    uu, vv, lo_t, up_t = _first_arc_table(samples, p0, t0, k, b, tol)
    for si in range(len(splits)):
        ok, jx, jy = _biarc_junction(p0[0], p0[1], t0[0], t0[1], p1[0], p1[1], t1[0], t1[1],
                                     splits[si])
        if not ok:
            continue
        ok, k1, s1 = arc_through(p0[0], p0[1], t0[0], t0[1], jx, jy, dist, kmin, kcap)
        if not ok:
            continue
        c, s = math.cos(k1 * s1), math.sin(k1 * s1)
        tjx, tjy = c * t0[0] - s * t0[1], s * t0[0] + c * t0[1]
        # (None also when the junction fell on the end point: no second arc)
        ok, k2, s2 = arc_through(jx, jy, tjx, tjy, p1[0], p1[1], dist, kmin, kcap)
        if not ok:
            continue
        c, s = math.cos(k2 * s2), math.sin(k2 * s2)
        tex, tey = c * tjx - s * tjy, s * tjx + c * tjy
        if abs(tex * t1[1] - tey * t1[0]) > 1e-9 or tex * t1[0] + tey * t1[1] < 0.0:
            continue
        # the running bounds narrow: k1 leaves them at index ``fail`` for good, so the
        # first arc fails their test exactly when its last sample ``m`` has
        # ``m - k - 1 >= fail``, and the foot scan stops there (most tried splits fail
        # this way)
        fail = _first_outside(lo_t, up_t, k1)
        limit = fail + 1 if fail <= n - 3 else n
        m = _last_on_first_arc(uu, vv, k1, s1, k, b, limit)
        if m < 0 or m - k > fail:
            continue
        r1 = verify_piece(samples, p0[0], p0[1], t0[0], t0[1], k1, k, m, e, s1, True, False,
                          tol, step0)
        if not r1[0]:
            continue
        # the second arc starts at the junction, which stands for sample m
        e_m = math.hypot(samples[m, 0] - jx, samples[m, 1] - jy)
        r2 = verify_piece(samples, jx, jy, tjx, tjy, k2, m, b, e_m, s2, True, True, tol,
                          step0)
        if not r2[0]:
            continue
        out[0], out[1], out[2], out[3], out[4], out[5] = k1, s1, jx, jy, tjx, tjy
        out[6], out[7], out[8], out[9] = r1[4], k2, s2, r2[4]
        return si, out, m
    return -1, out, 0
