"""C1 arc-and-line chains fitted to an ordered 2-D point curve (design section 5, seed 004).

Method
------
Each piece starts at a junction with a known point ``P`` and tangent ``T`` and is
described by one number, its signed curvature ``kappa`` (0 is a line). For a fixed
``(P, T)`` the signed distance of a sample to the circle is monotone in ``kappa``,
so each sample admits an interval of curvatures and the pieces that cover samples
``k+1..j`` form the running intersection of those intervals: one vectorised
``cummax``/``cummin`` gives the longest piece.

The seed's sequential least-squares fit fails because it hands each arc's end
tangent to the next arc without asking whether the next arc can live with it:
a long arc that just fits ends with its junction near the edge of the band and
its tangent off the curve's, and the next arc has no room left. Here the end of
each piece (where it stops and which curvature it uses inside the feasible
interval) is chosen by a two-step look-ahead: among candidate ends, the one from
which the *next* piece reaches furthest wins. That keeps junctions near the
middle of the band with tangents along the curve, without needing a (noisy)
tangent estimate of the input.

Every accepted piece is verified two-sided with conservative analytic bounds
(samples to arc, polyline segments to arc, arc portions to polyline), so the
fit never relies on luck; if a choice fails, shorter pieces are tried, then a
tighter working tolerance; the last resort is a corner at a junction, reported
in ``forced_corners`` (never seen on valid curves in the test-suite).

Real corners (turning angle over ``corner_angle_deg`` measured over +-3 tolerances
of arc length, so noise does not make corners) split the curve into runs that are
fitted separately; closed curves without corners close with a biarc (or a single
full circle), so the closing junction is C1 too.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from zwcore.arcgeom import (
    arc_length_position,
    arc_points,
    circle_gap,
    kappa_bounds,
    local_uv,
    point_to_arc_distance,
    points_to_segments_distance,
    rotate,
    sagitta,
)
from zwcore.errors import InvalidInputError

FloatArray = NDArray[np.float64]

__all__ = ["ArcChain", "Segment", "chain_tangents", "fit_arcs", "segment_points"]

#: Default corner angle: turning sharper than this (over the tolerance scale) stays sharp.
DEFAULT_CORNER_ANGLE_DEG = 30.0


@dataclass(frozen=True)
class Segment:
    """One piece of a chain, in input coordinates (mm).

    ``sweep`` is signed (radians, ``> 0`` when ``ccw``); lines carry ``None`` in
    the arc-only fields.
    """

    kind: Literal["arc", "line"]
    start: tuple[float, float]
    end: tuple[float, float]
    center: tuple[float, float] | None = None
    radius: float | None = None
    ccw: bool | None = None
    sweep: float | None = None

    @property
    def length(self) -> float:
        """Arc length of the segment (mm)."""
        if self.kind == "line":
            return math.hypot(self.end[0] - self.start[0], self.end[1] - self.start[1])
        assert self.radius is not None and self.sweep is not None
        return abs(self.radius * self.sweep)

    def start_tangent(self) -> tuple[float, float]:
        """Unit tangent at the start."""
        return _tangent_at(self, self.start)

    def end_tangent(self) -> tuple[float, float]:
        """Unit tangent at the end."""
        return _tangent_at(self, self.end)


def _tangent_at(seg: Segment, pt: tuple[float, float]) -> tuple[float, float]:
    if seg.kind == "line":
        dx = seg.end[0] - seg.start[0]
        dy = seg.end[1] - seg.start[1]
        n = math.hypot(dx, dy)
        return (dx / n, dy / n) if n > 0 else (1.0, 0.0)
    assert seg.center is not None and seg.radius is not None
    rx = pt[0] - seg.center[0]
    ry = pt[1] - seg.center[1]
    n = math.hypot(rx, ry)
    # ccw: tangent is the radius vector turned +90 degrees
    if seg.ccw:
        return (-ry / n, rx / n)
    return (ry / n, -rx / n)


@dataclass(frozen=True)
class ArcChain:
    """A fitted chain of arcs and lines.

    Junction ``i`` joins segment ``i`` to ``i + 1``; for closed chains junction
    ``len(segments) - 1`` joins the last segment to the first.
    """

    segments: tuple[Segment, ...]
    closed: bool
    corners: tuple[int, ...]
    max_deviation_points: float
    max_deviation_chain: float
    max_kink_smooth: float
    tolerance: float = 0.0
    forced_corners: tuple[int, ...] = field(default=())

    @property
    def n_arcs(self) -> int:
        """Number of arc segments."""
        return sum(1 for s in self.segments if s.kind == "arc")

    @property
    def n_lines(self) -> int:
        """Number of line segments."""
        return sum(1 for s in self.segments if s.kind == "line")

    @property
    def n_junctions(self) -> int:
        """Number of junctions (the closing one included for closed chains)."""
        n = len(self.segments)
        return n if self.closed else max(n - 1, 0)

    def kinks(self) -> FloatArray:
        """Tangent turn (radians, in [0, pi]) at every junction, ``(n_junctions,)``."""
        return chain_tangents(self.segments, self.closed)


def chain_tangents(segments: Sequence[Segment], closed: bool) -> FloatArray:
    """Tangent kink (radians) at each junction of ``segments``."""
    n = len(segments)
    m = n if closed else n - 1
    out = np.zeros(max(m, 0))
    for i in range(max(m, 0)):
        a = segments[i].end_tangent()
        b = segments[(i + 1) % n].start_tangent()
        out[i] = abs(math.atan2(a[0] * b[1] - a[1] * b[0], a[0] * b[0] + a[1] * b[1]))
    return out


def segment_points(seg: Segment, step: float) -> FloatArray:
    """Points ``(K, 2)`` along ``seg`` at spacing at most ``step``, both ends included."""
    n = max(math.ceil(seg.length / step), 1) + 1
    f = np.linspace(0.0, 1.0, n)
    s = np.array(seg.start)
    if seg.kind == "line":
        e = np.array(seg.end)
        return s[None, :] + f[:, None] * (e - s)[None, :]
    assert seg.center is not None and seg.radius is not None and seg.sweep is not None
    c = np.array(seg.center)
    a0 = math.atan2(s[1] - c[1], s[0] - c[0])
    ang = a0 + f * seg.sweep
    pts = c[None, :] + seg.radius * np.stack([np.cos(ang), np.sin(ang)], axis=1)
    pts[0] = s
    pts[-1] = seg.end
    return pts


# ---------------------------------------------------------------------------
# validation and preprocessing


def _validate(
    points: ArrayLike,
    tolerance: float,
    corner_angle_deg: float,
    max_radius: float | None,
) -> FloatArray:
    try:
        pts = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError("points", f"not a numeric (N, 2) array: {exc}") from None
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise InvalidInputError("points", f"expected shape (N, 2), got {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise InvalidInputError("points", "contains non-finite values")
    if not (isinstance(tolerance, int | float) and math.isfinite(tolerance) and tolerance > 0):
        raise InvalidInputError("tolerance", "must be a finite number > 0")
    if not (
        isinstance(corner_angle_deg, int | float)
        and math.isfinite(corner_angle_deg)
        and 0 < corner_angle_deg <= 180
    ):
        raise InvalidInputError("corner_angle_deg", "must be in (0, 180]")
    if max_radius is not None and not (
        isinstance(max_radius, int | float) and math.isfinite(max_radius) and max_radius > 0
    ):
        raise InvalidInputError("max_radius", "must be a finite number > 0 or null")
    return pts


def _dedupe(x: FloatArray, closed: bool, eps: float) -> FloatArray:
    """Drop points closer than ``eps`` to their kept predecessor (and a repeated closing point)."""
    keep = [0]
    last = x[0]
    d = np.hypot(*(np.diff(x, axis=0).T))
    if np.all(d > eps):
        out = x
    else:
        for i in range(1, len(x)):
            if math.hypot(x[i, 0] - last[0], x[i, 1] - last[1]) > eps:
                keep.append(i)
                last = x[i]
        out = x[keep]
    if closed:
        while len(out) > 1 and math.hypot(*(out[-1] - out[0])) <= eps:
            out = out[:-1]
    return out


def _interp_polyline(x: FloatArray, s: FloatArray, at: FloatArray) -> FloatArray:
    return np.stack([np.interp(at, s, x[:, 0]), np.interp(at, s, x[:, 1])], axis=1)


def _find_corners(x: FloatArray, closed: bool, tol: float, angle: float) -> list[int]:
    """Input indices where the curve turns by more than ``angle`` at the tolerance scale."""
    n = len(x)
    if n < 3 and not closed:
        return []
    d_probe = 3.0 * tol
    if closed:
        xx = np.vstack([x, x[:1]])
        seg = np.hypot(*(np.diff(xx, axis=0).T))
        total = float(seg.sum())
        s = np.concatenate([[0.0], np.cumsum(seg)])
        # three laps so that probes wrap around
        x3 = np.vstack([xx[:-1], xx[:-1], xx])
        s3 = np.concatenate([s[:-1] - total, s[:-1], s + total])
        si = s[:-1]
        before = _interp_polyline(x3, s3, si - min(d_probe, 0.25 * total))
        after = _interp_polyline(x3, s3, si + min(d_probe, 0.25 * total))
        idx = np.arange(n)
    else:
        seg = np.hypot(*(np.diff(x, axis=0).T))
        s = np.concatenate([[0.0], np.cumsum(seg)])
        si = s[1:-1]
        before = _interp_polyline(x, s, np.maximum(si - d_probe, 0.0))
        after = _interp_polyline(x, s, np.minimum(si + d_probe, s[-1]))
        idx = np.arange(1, n - 1)
    pc = x[idx]
    a = pc - before
    b = after - pc
    turn = np.abs(np.arctan2(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0], (a * b).sum(axis=1)))
    # a corner must also stand out of the chord between the probes by a visible amount
    # (half of what a corner of exactly `angle` shows at full probe length), so curves
    # that are small at the tolerance scale get no corners from their tiny wiggles
    chord = after - before
    clen = np.maximum(np.hypot(chord[:, 0], chord[:, 1]), 1e-300)
    height = np.abs(chord[:, 0] * a[:, 1] - chord[:, 1] * a[:, 0]) / clen
    hot = np.flatnonzero((turn > angle) & (height > 0.5 * d_probe * math.sin(0.5 * angle)))
    if hot.size == 0:
        return []
    # one corner per cluster of hot points (closer than two probe lengths): its sharpest point
    corners: list[int] = []
    start = 0
    for m in range(1, hot.size + 1):
        if m == hot.size or si[hot[m]] - si[hot[m - 1]] > 2.0 * d_probe:
            grp = hot[start:m]
            corners.append(int(idx[grp[np.argmax(turn[grp])]]))
            start = m
    if closed and len(corners) > 1:
        # the cluster may wrap around the start of the loop
        total = float(s[-1])
        first, last = corners[0], corners[-1]
        if total - si[last] + si[first] <= 2.0 * d_probe:
            keep = first if turn[first] >= turn[last] else last
            corners = [c for c in corners if c not in (first, last)] + [keep]
            corners.sort()
    return corners


# ---------------------------------------------------------------------------
# the fitter


@dataclass
class _Piece:
    p: FloatArray
    t: FloatArray
    kappa: float
    length: float
    k: int
    j: int
    end: FloatArray
    t_end: FloatArray
    e_end: float


class _Stuck(Exception):
    """No verified piece could be placed from the current junction."""


class _Fitter:
    """Fits runs of the sample polyline ``S`` (local frame, ``(M, 2)``)."""

    J_FRACTIONS = (1.0, 0.94, 0.87, 0.78, 0.66, 0.52, 0.36)
    K_FRACTIONS = (0.5, 0.25, 0.75, 0.08, 0.92)

    def __init__(
        self, samples: FloatArray, tol: float, work: float, max_radius: float | None
    ) -> None:
        self.S = samples
        self.tol = tol
        self.tw = work * tol
        self.kmin = 0.0 if max_radius is None else 1.0 / max_radius
        # curvature cap: radius >= tol / 4 (tighter arcs are within tol of their centre)
        self.kcap = 4.0 / tol
        seg = np.hypot(*(np.diff(samples, axis=0).T))
        self.cum = np.concatenate([[0.0], np.cumsum(seg)])
        self.ds = 0.1 * tol

    # -- feasibility scans -------------------------------------------------

    def _intervals(
        self, ps: FloatArray, ts: FloatArray, k: int, hi: int
    ) -> tuple[FloatArray, FloatArray]:
        """Running curvature bounds ``(C, hi-k)`` for samples ``k+1..hi`` from states ``C``."""
        pts = self.S[k + 1 : hi + 1]
        u, v = local_uv(ps[:, None, :], ts[:, None, :], pts[None, :, :])
        lo, up = kappa_bounds(u, v, self.tw)
        return np.maximum.accumulate(lo, axis=1), np.minimum.accumulate(up, axis=1)

    def _reach(self, ps: FloatArray, ts: FloatArray, k: int, b: int, w0: int) -> NDArray[np.int64]:
        """Last sample index each state ``(C,)`` can cover with one piece (interval test)."""
        c = len(ps)
        out = np.full(c, b, dtype=np.int64)
        todo = np.arange(c)
        w = max(w0, 32)
        lo_i = k
        while todo.size and lo_i < b:
            hi = min(b, k + w)
            # keep memory bounded: at most ~4e6 entries per block
            step = max(1, int(4e6 // max(hi - k, 1)))
            done_now = []
            for s0 in range(0, todo.size, step):
                sub = todo[s0 : s0 + step]
                lo_c, up_c = self._intervals(ps[sub], ts[sub], k, hi)
                bad = lo_c > up_c
                anyb = bad.any(axis=1)
                first = np.argmax(bad, axis=1)
                out[sub[anyb]] = k + first[anyb]
                done_now.append(sub[anyb])
            done = np.concatenate(done_now) if done_now else np.zeros(0, dtype=np.int64)
            todo = np.setdiff1d(todo, done)
            if hi == b:
                break
            w *= 2
            lo_i = hi
        return out

    def _scan(self, p: FloatArray, t: FloatArray, k: int, b: int) -> tuple[FloatArray, FloatArray]:
        """Running bounds for the longest feasible piece from ``(p, t)`` (doubling window)."""
        w = 64
        while True:
            hi = min(b, k + w)
            lo_c, up_c = self._intervals(p[None, :], t[None, :], k, hi)
            lo1, up1 = lo_c[0], up_c[0]
            bad = np.flatnonzero(lo1 > up1)
            if bad.size:
                return lo1[: bad[0]], up1[: bad[0]]
            if hi == b:
                return lo1, up1
            w *= 4

    # -- verification ------------------------------------------------------

    def _dense_ok(
        self, p: FloatArray, t: FloatArray, kappa: float, s0: float, s1: float, a: int, b: int
    ) -> bool:
        """Exact check of the arc portion ``[s0, s1]`` against polyline segments ``a..b``."""
        if s1 <= s0:
            return True
        n = math.ceil((s1 - s0) / self.ds) + 1
        if n > 4000:
            return False
        step = (s1 - s0) / (n - 1)
        pts = arc_points(p, t, kappa, np.linspace(s0, s1, n))
        a = max(a, 0)
        b = min(b, len(self.S) - 1)
        if b <= a:
            d = np.hypot(pts[:, 0] - self.S[a, 0], pts[:, 1] - self.S[a, 1])
        else:
            d = points_to_segments_distance(pts, self.S[a:b], self.S[a + 1 : b + 1]).min(axis=1)
        return bool(d.max() <= self.tol - 0.5 * step)

    def _check(
        self,
        p: FloatArray,
        t: FloatArray,
        kappa: float,
        k: int,
        j: int,
        e_k: float,
        sig_end: float | None = None,
        dense_first: bool = False,
    ) -> tuple[float, FloatArray, float] | None:
        """Verify the piece covering samples ``k..j``; return ``(length, end, e_end)`` or None.

        Without ``sig_end`` the piece ends at the foot point of sample ``j``.
        ``e_k`` is the distance of sample ``k`` from ``p`` (the piece's start
        stands for sample ``k``). All bounds are conservative: a piece that
        passes is within ``tol`` of the polyline both ways over its extent.
        """
        tol = self.tol
        pts = self.S[k : j + 1]
        u, v = local_uv(p, t, pts)
        g = np.abs(circle_gap(u, v, kappa))
        if kappa != 0.0:
            phi = np.arctan2(kappa * u, 1.0 - kappa * v)
            phi[0] = 0.0
            sig = np.unwrap(phi) / kappa
        else:
            sig = u.copy()
            sig[0] = 0.0
        given_end = sig_end is not None
        if sig_end is None:
            sig_end = float(sig[-1])
        if not sig_end > 0.0 or abs(kappa * sig_end) > 2.0 * math.pi + 1e-9:
            return None
        end = arc_points(p, t, kappa, np.array([sig_end]))[0]
        q = np.hypot(u, v)
        de = np.hypot(pts[:, 0] - end[0], pts[:, 1] - end[1])
        before = sig < 0.0
        after = sig > sig_end
        d = np.where(before, q, np.where(after, de, g))
        if d.size > 1 and d[1:].max() > tol:
            return None
        # polyline segment interiors: the farthest point from a circle on a segment is an
        # end point or the point closest to the centre
        if kappa != 0.0 and len(pts) > 1:
            du = np.diff(u)
            dv = np.diff(v)
            den = du * du + dv * dv
            den = np.where(den > 0.0, den, 1.0)
            ts = np.clip((-u[:-1] * du + (1.0 / kappa - v[:-1]) * dv) / den, 0.0, 1.0)
            xu = u[:-1] + ts * du
            xv = v[:-1] + ts * dv
            gx = np.abs(circle_gap(xu, xv, kappa))
            inside = (sig[:-1] >= 0.0) & (sig[1:] <= sig_end)
            xe = np.hypot(
                xu - (end[0] - p[0]) * t[0] - (end[1] - p[1]) * t[1],
                xv - (end[1] - p[1]) * t[0] + (end[0] - p[0]) * t[1],
            )
            dx = np.where(inside, gx, np.maximum(gx, np.minimum(np.hypot(xu, xv), xe)))
            if dense_first:
                dx[0] = 0.0
            if dx.max() > tol:
                return None
        # arc portions between consecutive (running-max) foot points, against the polyline
        run = np.maximum.accumulate(sig)
        phi_c = np.clip(run, 0.0, sig_end)
        idx = np.arange(len(sig))
        arg = np.maximum.accumulate(np.where(sig >= run, idx, 0))
        e_at = np.where(sig <= sig_end, g, de)
        e_at[0] = e_k
        dphi = np.diff(phi_c)
        if dphi.size:
            a_idx = arg[:-1]
            jit = np.hypot(pts[a_idx, 0] - pts[:-1, 0], pts[a_idx, 1] - pts[:-1, 1])
            bound = np.maximum(e_at[a_idx], e_at[1:]) + sagitta(kappa, dphi) + jit
            mask = dphi > 0.0
            if dense_first:
                first = np.flatnonzero(mask)
                if first.size:
                    f0 = int(first[0])
                    mask[f0] = False
                    if not self._dense_ok(
                        p, t, kappa, 0.0, float(phi_c[f0 + 1]), k - 1, k + f0 + 2
                    ):
                        return None
            if np.any(bound[mask] > tol):
                return None
        tail0 = float(phi_c[-1])
        if given_end:
            if tail0 < sig_end and not self._dense_ok(p, t, kappa, tail0, sig_end, j - 1, j + 2):
                return None
        elif tail0 < sig_end * (1.0 - 1e-12):
            return None
        return sig_end, end, float(g[-1])

    def _make(
        self,
        p: FloatArray,
        t: FloatArray,
        kappa: float,
        k: int,
        j: int,
        res: tuple[float, FloatArray, float],
    ) -> _Piece:
        length, end, e_end = res
        return _Piece(p, t, kappa, length, k, j, end, rotate(t, kappa * length), e_end)

    # -- candidate curvatures ----------------------------------------------

    def _kappas(self, lo: float, hi: float) -> list[float]:
        lo = max(lo, -self.kcap)
        hi = min(hi, self.kcap)
        if lo > hi:
            return []
        out: list[float] = []
        if lo <= 0.0 <= hi:
            out.append(0.0)
        for f in self.K_FRACTIONS:
            out.append(lo + f * (hi - lo))
        if self.kmin > 0.0:
            out = [x for x in out if x == 0.0 or abs(x) >= self.kmin]
            for edge in (self.kmin, -self.kmin):
                if lo <= edge <= hi:
                    out.append(edge)
        return out

    def _radius_ok(self, kappa: float) -> bool:
        return kappa == 0.0 or (abs(kappa) >= self.kmin and abs(kappa) <= self.kcap)

    # -- free start: the tangent is not given ------------------------------

    def _free_start(self, p: FloatArray, k: int, b: int) -> tuple[FloatArray, int]:
        """Tangent at a run start that lets the first piece reach furthest."""
        d = np.hypot(self.S[k + 1 : b + 1, 0] - p[0], self.S[k + 1 : b + 1, 1] - p[1])
        far = np.flatnonzero(d >= 3.0 * self.tol)
        i0 = k + 1 + (int(far[0]) if far.size else len(d) - 1)
        th0 = math.atan2(self.S[i0, 1] - p[1], self.S[i0, 0] - p[0])
        span, n = 1.4, 57
        best_th, best_r = th0, k
        for _ in range(3):
            ths = best_th + np.linspace(-span, span, n)
            ts = np.stack([np.cos(ths), np.sin(ths)], axis=1)
            r = self._reach(np.repeat(p[None, :], n, axis=0), ts, k, b, 64)
            top = np.flatnonzero(r == r.max())
            # the middle of the best range: robust to the grid and to noise
            mid = int(top[len(top) // 2])
            best_th, best_r = float(ths[mid]), int(r[mid])
            span = 2.0 * span / (n - 1)
            n = 21
        # a straight start is preferred when a line reaches nearly as far as the best arc
        ths = best_th + np.linspace(-0.2, 0.2, 81)
        lr, lth = self._line_reach(p, ths, k, b)
        if lr > k and self.cum[lr] - self.cum[k] >= 0.9 * (self.cum[best_r] - self.cum[k]):
            return np.array([math.cos(lth), math.sin(lth)]), best_r
        return np.array([math.cos(best_th), math.sin(best_th)]), best_r

    def _line_reach_states(
        self, ps: FloatArray, ts: FloatArray, k: int, b: int
    ) -> NDArray[np.int64]:
        """Longest straight piece from each state ``(C,)``: last covered sample index."""
        w = 64
        while True:
            hi = min(b, k + w)
            pts = self.S[k + 1 : hi + 1]
            u, v = local_uv(ps[:, None, :], ts[:, None, :], pts[None, :, :])
            bad = (np.abs(v) > self.tw) | (u < -self.tw)
            anyb = bad.any(axis=1)
            r = np.where(anyb, k + np.argmax(bad, axis=1), hi)
            if anyb.all() or hi == b:
                return r.astype(np.int64)
            w *= 4

    def _line_reach(self, p: FloatArray, ths: FloatArray, k: int, b: int) -> tuple[int, float]:
        """Longest straight piece from ``p`` over directions ``ths``: (last index, direction)."""
        ts = np.stack([np.cos(ths), np.sin(ths)], axis=1)
        w = 64
        while True:
            hi = min(b, k + w)
            pts = self.S[k + 1 : hi + 1]
            u, v = local_uv(p[None, None, :], ts[:, None, :], pts[None, :, :])
            bad = (np.abs(v) > self.tw) | (u < -self.tw)
            anyb = bad.any(axis=1)
            r = np.where(anyb, k + np.argmax(bad, axis=1), hi)
            if anyb.all() or hi == b:
                top = np.flatnonzero(r == r.max())
                mid = int(top[len(top) // 2])
                return int(r[mid]), float(ths[mid])
            w *= 4

    def _finish_free(self, p: FloatArray, k: int, b: int, th_guess: float) -> _Piece | None:
        """One piece from ``p`` (free tangent) ending exactly at sample ``b``."""
        pts = self.S[k + 1 : b + 1]
        dx, dy = self.S[b] - p
        chord = math.atan2(dy, dx)

        def worst(th: float) -> float:
            t = np.array([math.cos(th), math.sin(th)])
            ub, vb = local_uv(p, t, self.S[b : b + 1])
            kap = float(2.0 * vb[0] / (ub[0] ** 2 + vb[0] ** 2))
            u, v = local_uv(p, t, pts)
            return float(np.abs(circle_gap(u, v, kap)).max())

        cands = [chord]
        # golden-section search for the minimax circle through both ends
        rel = math.remainder(th_guess - chord, 2.0 * math.pi)
        lo, hi = min(rel, 0.0) - 0.3, max(rel, 0.0) + 0.3
        lo, hi = max(lo, -1.5), min(hi, 1.5)
        gr = (math.sqrt(5.0) - 1.0) / 2.0
        a, c = lo, hi
        x1, x2 = c - gr * (c - a), a + gr * (c - a)
        f1, f2 = worst(chord + x1), worst(chord + x2)
        for _ in range(48):
            if f1 < f2:
                c, x2, f2 = x2, x1, f1
                x1 = c - gr * (c - a)
                f1 = worst(chord + x1)
            else:
                a, x1, f1 = x1, x2, f2
                x2 = a + gr * (c - a)
                f2 = worst(chord + x2)
        cands.append(chord + 0.5 * (a + c))
        for th in cands:
            t = np.array([math.cos(th), math.sin(th)])
            ub, vb = local_uv(p, t, self.S[b : b + 1])
            kap = 0.0 if th == chord else float(2.0 * vb[0] / (ub[0] ** 2 + vb[0] ** 2))
            if not self._radius_ok(kap):
                continue
            res = self._check(p, t, kap, k, b, float(np.hypot(*(self.S[k] - p))))
            if res is not None:
                piece = self._make(p, t, kap, k, b, res)
                piece.end = self.S[b].copy()
                return piece
        return None

    # -- one step with a given tangent --------------------------------------

    def _step(
        self, p: FloatArray, t: FloatArray, k: int, e: float, b: int, jlimit: int
    ) -> _Piece | None:
        if jlimit <= k:
            return None
        lo1, up1 = self._scan(p, t, k, b)
        jm = min(k + len(lo1), jlimit)
        if jm <= k:
            return self._shrink(p, t, k, e, max(jlimit, k + 1), lo1, up1)
        span = self.cum[jm] - self.cum[k]
        js = sorted(
            {
                int(
                    min(
                        max(
                            np.searchsorted(self.cum, self.cum[k] + f * span, side="right") - 1,
                            k + 1,
                        ),
                        jm,
                    )
                )
                for f in self.J_FRACTIONS
            },
            reverse=True,
        )
        cands: list[tuple[float, int, int, float, FloatArray, FloatArray]] = []
        for j in js:
            kap = self._kappas(float(lo1[j - k - 1]), float(up1[j - k - 1]))
            if not kap:
                continue
            ka = np.array(kap)
            uj, vj = local_uv(p, t, self.S[j : j + 1])
            ends, tends = [], []
            for kk in ka:
                sj = arc_length_position(uj, vj, float(kk))
                ends.append(arc_points(p, t, float(kk), sj)[0])
                tends.append(rotate(t, float(kk) * float(sj[0])))
            ep = np.array(ends)
            et = np.array(tends)
            if j >= b:
                reach = np.full(len(ka), b)
                lreach = reach
            else:
                reach = self._reach(ep, et, j, b, max(64, j - k))
                lreach = self._line_reach_states(ep, et, j, b)
            # a next piece that can be a long line is worth more than its reach alone
            lscore = self.cum[lreach] + 0.3 * (self.cum[lreach] - self.cum[j])
            score = np.maximum(self.cum[reach], lscore)
            for m in range(len(ka)):
                # lines get credit for part of their own length: a straight run should come
                # out as one line even when a slightly bent arc would reach a bit further
                bonus = 0.3 * float(self.cum[j] - self.cum[k]) if ka[m] == 0.0 else 0.0
                cands.append(
                    (float(score[m]) + bonus, int(ka[m] != 0.0), j, float(ka[m]), ep[m], et[m])
                )
        cands.sort(key=lambda c: (-c[0], c[1], -c[2]))
        for _, _, j, kap_c, _, _ in cands[:24]:
            res = self._check(p, t, kap_c, k, j, e)
            if res is not None:
                return self._make(p, t, kap_c, k, j, res)
        return self._shrink(p, t, k, e, jm, lo1, up1)

    def _shrink(
        self,
        p: FloatArray,
        t: FloatArray,
        k: int,
        e: float,
        jm: int,
        lo1: FloatArray,
        up1: FloatArray,
    ) -> _Piece | None:
        """Fallback: ever shorter pieces with several curvatures."""
        j = jm
        while j > k:
            if j - k - 1 < len(lo1):
                kap = self._kappas(float(lo1[j - k - 1]), float(up1[j - k - 1]))
            else:
                u, v = local_uv(p, t, self.S[j : j + 1])
                q2 = float(u[0] ** 2 + v[0] ** 2)
                kap = [2.0 * float(v[0]) / q2] if q2 > 0 else [0.0]
            for kk in kap:
                if not self._radius_ok(kk):
                    continue
                res = self._check(p, t, kk, k, j, e)
                if res is not None:
                    return self._make(p, t, kk, k, j, res)
            if j == k + 1:
                break
            j = k + max(1, (j - k) // 2)
        return None

    # -- closing a loop with a biarc ----------------------------------------

    def _biarc(
        self, p0: FloatArray, t0: FloatArray, k: int, e: float, b: int, t1: FloatArray
    ) -> list[_Piece] | None:
        p1 = self.S[b]
        vv = p1 - p0
        dist2 = float(vv @ vv)
        if dist2 <= 0.0:
            return None
        dist = math.sqrt(dist2)
        vt0 = float(vv @ t0)
        vt1 = float(vv @ t1)
        t01 = float(t0 @ t1)
        for f in (0.5, 0.4, 0.6, 0.3, 0.7, 0.2, 0.8, 0.12, 0.9):
            d1 = f * dist
            den = vt1 - d1 * (t01 - 1.0)
            if abs(den) < 1e-300:
                continue
            d2 = (0.5 * dist2 - d1 * vt0) / den
            if not (d2 > 0.0 and math.isfinite(d2)):
                continue
            jn = (d2 * (p0 + d1 * t0) + d1 * (p1 - d2 * t1)) / (d1 + d2)
            u, v = local_uv(p0, t0, jn[None, :])
            q2 = float(u[0] ** 2 + v[0] ** 2)
            if q2 <= 0.0:
                continue
            k1 = 2.0 * float(v[0]) / q2
            if abs(k1) < 1e-15 * max(1.0 / dist, 1.0):
                k1 = 0.0
            s1 = float(arc_length_position(u, v, k1)[0])
            if not s1 > 0.0 or not self._radius_ok(k1):
                continue
            tj = rotate(t0, k1 * s1)
            u2, v2 = local_uv(jn, tj, p1[None, :])
            q22 = float(u2[0] ** 2 + v2[0] ** 2)
            k2 = 2.0 * float(v2[0]) / q22
            if abs(k2) < 1e-15 * max(1.0 / dist, 1.0):
                k2 = 0.0
            s2 = float(arc_length_position(u2, v2, k2)[0])
            if not s2 > 0.0 or not self._radius_ok(k2):
                continue
            te = rotate(tj, k2 * s2)
            if abs(te[0] * t1[1] - te[1] * t1[0]) > 1e-9 or te @ t1 < 0:
                continue
            # split the samples: those whose foot point lies on the first arc
            uu, vv2 = local_uv(p0, t0, self.S[k : b + 1])
            if k1 != 0.0:
                ph = np.arctan2(k1 * uu, 1.0 - k1 * vv2)
                ph[0] = 0.0
                sg = np.unwrap(ph) / k1
            else:
                sg = uu
            over = np.flatnonzero(sg > s1)
            m = k + (int(over[0]) - 1 if over.size else b - k - 1)
            m = min(max(m, k), b - 1)
            r1 = self._check(p0, t0, k1, k, m, e, sig_end=s1)
            if r1 is None:
                continue
            r2 = self._check(jn, tj, k2, m, b, 0.0, sig_end=s2, dense_first=True)
            if r2 is None:
                continue
            a1 = self._make(p0, t0, k1, k, m, r1)
            a1.end = jn
            a1.t_end = tj
            a2 = self._make(jn, tj, k2, m, b, r2)
            a2.end = p1.copy()
            a2.t_end = t1.copy()
            return [a1, a2]
        return None

    def _full_circle(self, a: int, b: int) -> _Piece | None:
        """A whole closed run as one full circle through its first sample (if it fits)."""
        pts = self.S[a:b]
        if len(pts) < 3:
            return None
        c0 = pts.mean(axis=0)
        x = pts - c0
        mat = np.column_stack([x[:, 0], x[:, 1], np.ones(len(x))])
        rhs = (x * x).sum(axis=1)
        sol, *_ = np.linalg.lstsq(mat, rhs, rcond=None)
        c = c0 + 0.5 * sol[:2]
        p = self.S[a]
        r = float(np.hypot(*(p - c)))
        if not (r > 0 and math.isfinite(r)):
            return None
        xx = self.S[a : b + 1]
        area = float(np.sum(xx[:-1, 0] * xx[1:, 1] - xx[1:, 0] * xx[:-1, 1]))
        kap = 1.0 / r if area > 0 else -1.0 / r
        rv = (p - c) / r
        t = np.array([-rv[1], rv[0]]) if kap > 0 else np.array([rv[1], -rv[0]])
        if not self._radius_ok(kap):
            return None
        res = self._check(p, t, kap, a, b, 0.0)
        if res is None or abs(abs(kap * res[0]) - 2.0 * math.pi) > 1e-6:
            return None
        piece = self._make(p, t, kap, a, b, (2.0 * math.pi / abs(kap), p.copy(), 0.0))
        piece.t_end = t.copy()
        return piece

    # -- a run between two fixed points --------------------------------------

    def run(self, a: int, b: int, loop: bool, allow_forced: bool) -> tuple[list[_Piece], list[int]]:
        """Fit samples ``a..b``. ``loop``: the run is a whole closed curve (C1 closure).

        Returns the pieces and the piece indices after which a forced corner sits.
        Raises :class:`_Stuck` when no verified piece exists and forcing is not allowed.
        """
        pieces: list[_Piece] = []
        forced: list[int] = []
        if loop:
            circ = self._full_circle(a, b)
            if circ is not None:
                return [circ], []
        p = self.S[a].copy()
        k, e = a, 0.0
        t: FloatArray | None = None
        t_first: FloatArray | None = None
        fresh = False
        jcap = b
        backtracks = 0
        while True:
            fresh = t is None
            if t is None:
                t, r = self._free_start(p, k, b)
                if t_first is None:
                    t_first = t.copy()
                if r >= b and not loop:
                    fin = self._finish_free(p, k, b, math.atan2(t[1], t[0]))
                    if fin is not None:
                        pieces.append(fin)
                        return pieces, forced
            if not loop:
                fin2 = self._finish(p, t, k, e, b)
                if fin2 is not None:
                    pieces.append(fin2)
                    return pieces, forced
            else:
                assert t_first is not None
                if pieces:
                    clo = self._try_close(p, t, k, e, b, t_first)
                    if clo is not None:
                        pieces.extend(clo)
                        return pieces, forced
            piece = self._step(p, t, k, e, b, min(b - 1, jcap))
            jcap = b
            if piece is None and not loop and pieces and backtracks < 64:
                # backtrack: the previous piece left a junction nothing can start from;
                # redo it shorter (its end state then differs)
                backtracks += 1
                last = pieces.pop()
                forced = [f for f in forced if f < len(pieces) - 1]
                p, t, k = last.p, last.t, last.k
                e = float(np.hypot(*(self.S[k] - p)))
                jcap = last.j - 1
                continue
            if piece is None:
                if loop:
                    # backtrack: close from earlier junctions
                    assert t_first is not None
                    while pieces:
                        last = pieces.pop()
                        clo = self._biarc(
                            last.p,
                            last.t,
                            last.k,
                            float(np.hypot(*(self.S[last.k] - last.p))),
                            b,
                            t_first,
                        )
                        if clo is not None:
                            pieces.extend(clo)
                            return pieces, forced
                    raise _Stuck
                if not allow_forced:
                    raise _Stuck
                if fresh:
                    # cannot fail: the straight line to the next sample (its start is
                    # within tol of sample k, so the segment k..k+1 stays in the band)
                    nxt = self.S[k + 1].copy()
                    dv = nxt - p
                    ln = float(np.hypot(*dv))
                    tl = dv / ln if ln > 0 else t
                    pieces.append(_Piece(p, tl, 0.0, ln, k, k + 1, nxt, tl, 0.0))
                    p, t, k, e = nxt, tl, k + 1, 0.0
                    if k >= b:
                        return pieces, forced
                    continue
                # last resort: a corner here, restart with a free tangent
                if pieces:
                    forced.append(len(pieces) - 1)
                t = None
                continue
            pieces.append(piece)
            p, t, k, e = piece.end, piece.t_end, piece.j, piece.e_end

    def _finish(self, p: FloatArray, t: FloatArray, k: int, e: float, b: int) -> _Piece | None:
        """The piece from ``(p, t)`` that ends exactly at sample ``b``, if it is valid."""
        u, v = local_uv(p, t, self.S[b : b + 1])
        q2 = float(u[0] ** 2 + v[0] ** 2)
        if q2 <= 0.0:
            return None
        kap = 2.0 * float(v[0]) / q2
        if abs(kap) * math.sqrt(q2) < 1e-13:
            kap = 0.0
        if not self._radius_ok(kap):
            return None
        # cheap interval test first
        lo, up = self._intervals(p[None, :], t[None, :], k, b)
        if not (lo[0, -1] - 1e-12 * abs(kap) <= kap <= up[0, -1] + 1e-12 * abs(kap)):
            return None
        res = self._check(p, t, kap, k, b, e)
        if res is None:
            return None
        piece = self._make(p, t, kap, k, b, res)
        piece.end = self.S[b].copy()
        return piece

    def _try_close(
        self, p: FloatArray, t: FloatArray, k: int, e: float, b: int, t1: FloatArray
    ) -> list[_Piece] | None:
        lo, up = self._intervals(p[None, :], t[None, :], k, b)
        if np.any(lo[0] > up[0]):
            return None
        return self._biarc(p, t, k, e, b, t1)


# ---------------------------------------------------------------------------
# deviations


def _densify(x: FloatArray, step: float) -> FloatArray:
    seg = np.hypot(*(np.diff(x, axis=0).T))
    n = np.maximum(np.ceil(seg / step).astype(np.int64), 1)
    if np.all(n == 1):
        return x
    f = np.concatenate([np.arange(m) / m for m in n])
    i = np.repeat(np.arange(len(seg)), n)
    out = x[i] + f[:, None] * (x[i + 1] - x[i])
    return np.vstack([out, x[-1:]])


def _piece_points(pc: _Piece, step: float) -> FloatArray:
    n = max(math.ceil(pc.length / step), 1) + 1
    pts = arc_points(pc.p, pc.t, pc.kappa, np.linspace(0.0, pc.length, n))
    pts[-1] = pc.end
    return pts


def _deviations(poly: FloatArray, pieces: list[_Piece], tol: float) -> tuple[float, float]:
    """Dense two-sided deviation ``(polyline -> chain, chain -> polyline)``."""
    length = float(np.hypot(*(np.diff(poly, axis=0).T)).sum())
    total = length + sum(pc.length for pc in pieces)
    step = max(tol / 20.0, total / 2e6)
    dpoly = _densify(poly, step)
    chain_pts = [_piece_points(pc, step) for pc in pieces]
    owner = np.concatenate([np.full(len(c), i) for i, c in enumerate(chain_pts)])
    cpts = np.vstack(chain_pts)
    # chain -> polyline: nearest dense polyline point, refined on adjacent segments
    tree_p = cKDTree(dpoly)
    d_c, _i_c = tree_p.query(cpts)
    hot = np.flatnonzero(d_c > 0.25 * tol)
    if hot.size:
        _, nn = tree_p.query(cpts[hot], k=min(4, len(dpoly)))
        nn = np.atleast_2d(nn).reshape(len(hot), -1)
        best = d_c[hot].copy()
        for col in range(nn.shape[1]):
            for off in (-1, 0):
                ia = np.clip(nn[:, col] + off, 0, len(dpoly) - 2)
                a = dpoly[ia]
                bb = dpoly[ia + 1]
                ab = bb - a
                den = np.maximum((ab * ab).sum(axis=1), 1e-300)
                s = np.clip(((cpts[hot] - a) * ab).sum(axis=1) / den, 0.0, 1.0)
                dd = np.hypot(*(cpts[hot] - a - s[:, None] * ab).T)
                best = np.minimum(best, dd)
        d_c[hot] = best
    # polyline -> chain: nearest chain sample, refined exactly on the owning pieces
    tree_c = cKDTree(cpts)
    d_p, _i_p = tree_c.query(dpoly)
    hot = np.flatnonzero(d_p > 0.25 * tol)
    if hot.size:
        _, nn = tree_c.query(dpoly[hot], k=min(4, len(cpts)))
        nn = np.atleast_2d(nn).reshape(len(hot), -1)
        best = d_p[hot].copy()
        own = np.unique(owner[nn])
        for o in own:
            pc = pieces[int(o)]
            sel = np.any(owner[nn] == o, axis=1)
            dd = point_to_arc_distance(dpoly[hot][sel], pc.p, pc.t, pc.kappa, pc.length)
            best[sel] = np.minimum(best[sel], dd)
        d_p[hot] = best
    return float(d_p.max()), float(d_c.max())


# ---------------------------------------------------------------------------
# public entry point


def fit_arcs(
    points: ArrayLike,
    tolerance: float = 0.1,
    *,
    closed: bool = False,
    corner_angle_deg: float = DEFAULT_CORNER_ANGLE_DEG,
    max_radius: float | None = None,
) -> ArcChain:
    """Fit a tangent-continuous chain of arcs and lines to an ordered point curve.

    Parameters
    ----------
    points : (N, 2) float64
        The curve, in order (mm). Consecutive repeated points are dropped; for
        ``closed`` a repeated closing point is dropped too. N >= 2 distinct.
    tolerance : float
        Two-sided band (mm): every point of the input polyline is within
        ``tolerance`` of the chain and every point of the chain within
        ``tolerance`` of the polyline.
    closed : bool
        Treat the points as a loop; the chain closes on itself (C1 at the closing
        junction unless the input has a corner there).
    corner_angle_deg : float
        Where the input turns by more than this (measured over +-3 tolerances of
        arc length, so noise does not count) the chain keeps a sharp corner at
        that input point; everywhere else it is C1.
    max_radius : float or None
        Arcs of larger radius are not used (such pieces are lines or shorter
        arcs); ``None`` means no cap (lines are still preferred whenever a line
        fits).

    Returns
    -------
    ArcChain
        Segments in input coordinates with the two-sided deviations measured by
        dense sampling, the largest tangent kink at smooth junctions and the
        corner junctions.

    Raises
    ------
    InvalidInputError
        Bad ``points`` (shape, non-finite, fewer than two distinct), or an
        option out of range.
    """
    raw = _validate(points, tolerance, corner_angle_deg, max_radius)
    tol = float(tolerance)
    closed = bool(closed)
    if len(raw) < 2:
        raise InvalidInputError("points", "need at least two points")
    origin = raw[0].copy()
    # work relative to the first point so large coordinates keep their precision
    x = raw - origin
    scale = float(np.abs(x).max())
    eps = max(1e-9 * tol, 1e-14 * scale)
    x = _dedupe(x, closed, eps)
    if len(x) < 2:
        raise InvalidInputError("points", "fewer than two distinct points")
    corners_in = _find_corners(x, closed, tol, math.radians(corner_angle_deg))
    if closed and corners_in:
        # start the loop at a corner: the closing junction is then that corner
        sh = corners_in[0]
        x = np.roll(x, -sh, axis=0)
        corners_in = sorted((c - sh) % len(x) for c in corners_in)
    poly = np.vstack([x, x[:1]]) if closed else x
    # densify long polyline segments so junctions can sit between sparse input points
    seg = np.hypot(*(np.diff(poly, axis=0).T))
    nsub = np.maximum(np.ceil(seg / (6.0 * tol)).astype(np.int64), 1)
    if np.any(nsub > 1):
        samples = _densify(poly, 6.0 * tol)
    else:
        samples = poly
    sample_of_input = np.concatenate([[0], np.cumsum(nsub)])
    m_last = len(samples) - 1

    if closed and corners_in:
        bounds = [int(sample_of_input[c]) for c in corners_in] + [m_last]
    elif closed:
        bounds = [0, m_last]
    else:
        bounds = [0] + [int(sample_of_input[c]) for c in corners_in] + [m_last]
    loop = closed and not corners_in

    pieces: list[_Piece] = []
    corner_j: list[int] = []
    forced_j: list[int] = []
    for r in range(len(bounds) - 1):
        a, b = bounds[r], bounds[r + 1]
        got: tuple[list[_Piece], list[int]] | None = None
        for work in (0.95, 0.8, 0.6, 0.4):
            try:
                got = _Fitter(samples, tol, work, max_radius).run(a, b, loop, allow_forced=False)
                break
            except _Stuck:
                continue
        if got is None:
            if loop:
                # a loop that cannot close smoothly: close it with a corner at the start
                loop_r = False
                got = _Fitter(samples, tol, 0.9, max_radius).run(a, b, loop_r, allow_forced=True)
                forced_j.append(-1)
            else:
                got = _Fitter(samples, tol, 0.9, max_radius).run(a, b, False, allow_forced=True)
        run_pieces, run_forced = got
        base = len(pieces)
        forced_j.extend(base + f for f in run_forced)
        pieces.extend(run_pieces)
        if r < len(bounds) - 2 or (closed and corners_in):
            corner_j.append(len(pieces) - 1)
    n_seg = len(pieces)
    forced_j = [n_seg - 1 if f == -1 else f for f in forced_j]
    all_corners = sorted(set(corner_j) | set(forced_j))

    segments = tuple(_to_segment(pc, origin) for pc in pieces)
    if closed:
        # the loop closes exactly on its first point
        last = segments[-1]
        segments = (*segments[:-1], _replace_end(last, segments[0].start))
    kinks = chain_tangents(segments, closed)
    smooth = np.ones(len(kinks), dtype=bool)
    for c in all_corners:
        if 0 <= c < len(kinks):
            smooth[c] = False
    max_kink = float(kinks[smooth].max()) if np.any(smooth) else 0.0
    dev_p, dev_c = _deviations(poly, pieces, tol)
    return ArcChain(
        segments=segments,
        closed=closed,
        corners=tuple(all_corners),
        max_deviation_points=dev_p,
        max_deviation_chain=dev_c,
        max_kink_smooth=max_kink,
        tolerance=tol,
        forced_corners=tuple(sorted(set(forced_j))),
    )


def _replace_end(seg: Segment, end: tuple[float, float]) -> Segment:
    return Segment(seg.kind, seg.start, end, seg.center, seg.radius, seg.ccw, seg.sweep)


def _to_segment(pc: _Piece, origin: FloatArray) -> Segment:
    start = (float(pc.p[0] + origin[0]), float(pc.p[1] + origin[1]))
    end = (float(pc.end[0] + origin[0]), float(pc.end[1] + origin[1]))
    if pc.kappa == 0.0:
        return Segment("line", start, end)
    n = np.array([-pc.t[1], pc.t[0]])
    c = pc.p + n / pc.kappa
    return Segment(
        "arc",
        start,
        end,
        center=(float(c[0] + origin[0]), float(c[1] + origin[1])),
        radius=float(1.0 / abs(pc.kappa)),
        ccw=bool(pc.kappa > 0),
        sweep=float(pc.kappa * pc.length),
    )
