"""The per-run fitter of the C1 arc chain: curvature intervals and a beam of junction states.

Each piece starts at a junction with a known point ``P`` and tangent ``T`` and is
described by one number, its signed curvature ``kappa`` (0 is a line). For a fixed
``(P, T)`` the signed distance of a sample to the circle is monotone in ``kappa``,
so each sample admits an interval of curvatures and the pieces that cover samples
``k+1..j`` form the running intersection of those intervals (one vectorised
``cummax``/``cummin`` gives the longest piece).

The seed's sequential least-squares fit fails because it hands each arc's end
tangent to the next arc without asking whether the next arc can live with it.
Here the chain is grown level by level (level = number of pieces) as a *beam* of
junction states ``(P, T, sample index)``: every state proposes candidate pieces
(several ends and several curvatures inside the feasible interval), each
candidate is scored by how far the *next* piece can reach from its end state
(two-step look-ahead), and the best few verified candidates form the next level.
The first level from which a state finishes the run gives the chain. Keeping
several states alive means one unlucky junction (near the edge of the band, or
with a tangent off the curve's) does not end the fit.

Every accepted piece is verified two-sided with conservative analytic bounds
(samples to arc, polyline segments to arc, arc portions to polyline). When no
state of a level can place a verified piece the caller retries with a tighter
working tolerance; the last resort is a corner at a junction (``forced``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from zwcore.arcgeom import (
    arc_length_position,
    arc_points,
    circle_gap,
    kappa_bounds,
    local_uv,
    points_to_segments_distance,
    rotate,
    sagitta,
)

FloatArray = NDArray[np.float64]

__all__ = ["Fitter", "Piece", "Stuck"]

# ---------------------------------------------------------------------------
# the fitter


@dataclass
class Piece:
    p: FloatArray
    t: FloatArray
    kappa: float
    length: float
    k: int
    j: int
    end: FloatArray
    t_end: FloatArray
    e_end: float


class Stuck(Exception):
    """No verified piece could be placed from the current junction."""


class Fitter:
    """Fits runs of the sample polyline ``S`` (local frame, ``(M, 2)``)."""

    J_FRACTIONS = (1.0, 0.97, 0.94, 0.9, 0.87, 0.83, 0.78, 0.72, 0.66, 0.6, 0.52, 0.44, 0.36)
    K_FRACTIONS = (0.5, 0.25, 0.75, 0.08, 0.92)

    def __init__(
        self, samples: FloatArray, tol: float, work: float, max_radius: float | None
    ) -> None:
        self.S = samples
        self.tol = tol
        self.tw = work * tol
        self.kmin = 0.0 if max_radius is None else 1.0 / max_radius
        # curvature cap: radius >= tol / 4 (tighter arcs are within tol of their centre)
        self.kcap = 200.0 / tol
        seg = np.hypot(*(np.diff(samples, axis=0).T))
        self.cum = np.concatenate([[0.0], np.cumsum(seg)])
        self.ds = 0.1 * tol
        n_seg = max(len(samples) - 1, 1)
        spacing = float(self.cum[-1]) / n_seg
        self.reach_stride = max(1, int(0.25 * tol / spacing)) if spacing > 0 else 1

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
    ) -> Piece:
        length, end, e_end = res
        return Piece(p, t, kappa, length, k, j, end, rotate(t, kappa * length), e_end)

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

    def _finish_free(self, p: FloatArray, k: int, b: int, th_guess: float) -> Piece | None:
        """One piece from ``p`` (free tangent) ending exactly at sample ``b``."""
        pts = self.S[k + 1 : b + 1]
        dx, dy = self.S[b] - p
        chord = math.atan2(dy, dx)

        def worst(th: float) -> float:
            t = np.array([math.cos(th), math.sin(th)])
            ub, vb = local_uv(p, t, self.S[b : b + 1])
            q2 = float(ub[0] ** 2 + vb[0] ** 2)
            if q2 <= 0.0:
                return math.inf
            kap = float(2.0 * vb[0] / q2)
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
            q2 = float(ub[0] ** 2 + vb[0] ** 2)
            if q2 <= 0.0:
                continue
            kap = 0.0 if th == chord else float(2.0 * vb[0] / q2)
            if not self._radius_ok(kap):
                continue
            res = self._check(p, t, kap, k, b, float(np.hypot(*(self.S[k] - p))))
            if res is not None:
                piece = self._make(p, t, kap, k, b, res)
                piece.end = self.S[b].copy()
                return piece
        return None

    # -- one step with a given tangent --------------------------------------

    def _shrink(
        self,
        p: FloatArray,
        t: FloatArray,
        k: int,
        e: float,
        jm: int,
        lo1: FloatArray,
        up1: FloatArray,
    ) -> Piece | None:
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
    ) -> list[Piece] | None:
        p1 = self.S[b]
        vv = p1 - p0
        dist2 = float(vv @ vv)
        if dist2 <= 0.0:
            return None
        dist = math.sqrt(dist2)
        vt0 = float(vv @ t0)
        vt1 = float(vv @ t1)
        t01 = float(t0 @ t1)
        for f in (0.5, 0.4, 0.6, 0.3, 0.7, 0.2, 0.8, 0.12, 0.9, 0.06, 0.94):
            d1 = f * dist
            den = vt1 - d1 * (t01 - 1.0)
            if abs(den) < 1e-300:
                continue
            d2 = (0.5 * dist2 - d1 * vt0) / den
            if not (d2 > 0.0 and math.isfinite(d2)):
                continue
            jn = (d2 * (p0 + d1 * t0) + d1 * (p1 - d2 * t1)) / (d1 + d2)
            first = self._arc_through(p0, t0, jn, dist)
            if first is None:
                continue
            k1, s1 = first
            tj = rotate(t0, k1 * s1)
            # None also when the junction fell on the end point: no second arc.
            second = self._arc_through(jn, tj, p1, dist)
            if second is None:
                continue
            k2, s2 = second
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
            # the second arc starts at the junction, which stands for sample m
            e_m = float(np.hypot(*(self.S[m] - jn)))
            r2 = self._check(jn, tj, k2, m, b, e_m, sig_end=s2, dense_first=True)
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

    def _arc_through(self, p: FloatArray, t: FloatArray, q: FloatArray, dist: float,
                     ) -> tuple[float, float] | None:
        """Curvature and length of the arc from ``p`` along ``t`` through ``q``, or None
        when ``q`` is ``p``, the arc is degenerate or its radius is not allowed."""
        u, v = local_uv(p, t, q[None, :])
        q2 = float(u[0] ** 2 + v[0] ** 2)
        if q2 <= 0.0:
            return None
        k = 2.0 * float(v[0]) / q2
        if abs(k) < 1e-15 * max(1.0 / dist, 1.0):
            k = 0.0  # numerically straight: a line
        length = float(arc_length_position(u, v, k)[0])
        if not length > 0.0 or not self._radius_ok(k):
            return None
        return k, length

    def _full_circle(self, a: int, b: int) -> Piece | None:
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
        if abs(kap) < self.kmin:  # any small radius: the whole loop is one circle
            return None
        res = self._check(p, t, kap, a, b, 0.0)
        if res is None or abs(abs(kap * res[0]) - 2.0 * math.pi) > 1e-6:
            return None
        piece = self._make(p, t, kap, a, b, (2.0 * math.pi / abs(kap), p.copy(), 0.0))
        piece.t_end = t.copy()
        return piece

    # -- a run between two fixed points --------------------------------------

    # -- the beam -----------------------------------------------------------

    BEAM = 4
    #: biarc bridges out of stuck states (off: the caller's fallback after a failed check)
    use_bridge = True

    def _reach_multi(self, ps: FloatArray, ts: FloatArray, ks: NDArray[np.int64],
                     b: int) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """Last sample each state ``(C,)`` covers with one piece, and with one line.

        State ``c`` starts at ``ps[c]`` with tangent ``ts[c]`` standing for sample ``ks[c]``.
        """
        c = len(ps)
        reach = np.full(c, b, dtype=np.int64)
        lreach = np.full(c, b, dtype=np.int64)
        if c == 0:
            return reach, lreach
        k0 = int(ks.min())
        todo = np.arange(c)
        ltodo = np.ones(c, dtype=bool)
        # the reach only ranks candidates (every piece is verified on all samples), so
        # densely sampled curves are scanned at a stride of about a quarter tolerance:
        # the work per level no longer grows with the sampling density
        stride = self.reach_stride
        w = 64
        while todo.size:
            hi = min(b, int(ks[todo].max()) + w)
            if hi <= k0:
                break
            idx = np.arange(k0 + 1, hi + 1, stride)
            step = max(1, int(3e6 // max(len(idx), 1)))
            still = []
            for s0 in range(0, todo.size, step):
                sub = todo[s0 : s0 + step]
                win = self.S[None, k0 + 1 : hi + 1 : stride, :]
                u, v = local_uv(ps[sub, None, :], ts[sub, None, :], win)
                mask = idx[None, :] <= ks[sub, None]
                lo, up = kappa_bounds(u, v, self.tw)
                lo = np.maximum.accumulate(np.where(mask, -np.inf, lo), axis=1)
                up = np.minimum.accumulate(np.where(mask, np.inf, up), axis=1)
                bad = lo > up
                anyb = bad.any(axis=1)
                reach[sub[anyb]] = idx[np.argmax(bad[anyb], axis=1)] - 1
                lb = ((np.abs(v) > self.tw) | (u < -self.tw)) & ~mask
                lany = lb.any(axis=1)
                lsel = lany & ltodo[sub]
                lreach[sub[lsel]] = idx[np.argmax(lb[lsel], axis=1)] - 1
                ltodo[sub[lsel]] = False
                still.append(sub[~anyb])
            todo = np.concatenate(still)
            if hi == b:
                break
            w *= 2
        # lines are only reported while the arc scan was still running; beyond, a line
        # never reaches further than the arcs (a line is one of the circles)
        lreach = np.minimum(lreach, reach)
        return reach, lreach

    def _free_tangents(self, p: FloatArray, k: int, b: int) -> list[FloatArray]:
        """A few start tangents at a run start (no tangent given), best first."""
        t0, _r0 = self._free_start(p, k, b)
        out = [t0]
        th0 = math.atan2(t0[1], t0[0])
        for d in (0.04, -0.04, 0.12, -0.12):
            out.append(np.array([math.cos(th0 + d), math.sin(th0 + d)]))
        return out

    def _candidates(
        self, st: _State, b: int
    ) -> list[tuple[int, float, FloatArray, FloatArray, float]]:
        """Candidate pieces ``(j, kappa, end, t_end, own_bonus)`` from a state (unverified)."""
        p, t, k = st.p, st.t, st.k
        assert t is not None
        jlimit = b - 1
        if jlimit <= k:
            return []
        lo1, up1 = self._scan(p, t, k, b)
        jm = min(k + len(lo1), jlimit)
        if jm <= k:
            return []
        span = self.cum[jm] - self.cum[k]
        js = sorted(
            {
                int(min(max(np.searchsorted(self.cum, self.cum[k] + f * span, side="right") - 1,
                            k + 1), jm))
                for f in self.J_FRACTIONS
            },
            reverse=True,
        )
        out = []
        for j in js:
            kap = self._kappas(float(lo1[j - k - 1]), float(up1[j - k - 1]))
            uj, vj = local_uv(p, t, self.S[j : j + 1])
            for kk in kap:
                sj = arc_length_position(uj, vj, float(kk))
                end = arc_points(p, t, float(kk), sj)[0]
                tend = rotate(t, float(kk) * float(sj[0]))
                bonus = 0.3 * float(self.cum[j] - self.cum[k]) if kk == 0.0 else 0.0
                out.append((j, float(kk), end, tend, bonus))
        return out

    def run(
        self, a: int, b: int, loop: bool, allow_forced: bool, t_start: FloatArray | None = None
    ) -> tuple[list[Piece], list[int]]:
        """Fit samples ``a..b``. ``loop``: the run is a whole closed curve (C1 closure).

        ``t_start``: the tangent the first piece must start with (free when None).

        Returns the pieces and the piece indices after which a forced corner sits.
        Raises :class:`Stuck` when no verified piece exists and forcing is not allowed.
        """
        if loop:
            circ = self._full_circle(a, b)
            if circ is not None:
                return [circ], []
        p0 = self.S[a].copy()
        if not loop and t_start is None:
            t0, r0 = self._free_start(p0, a, b)
            if r0 >= b:
                fin = self._finish_free(p0, a, b, math.atan2(t0[1], t0[0]))
                if fin is not None:
                    return [fin], []
        starts = [t_start] if t_start is not None else self._free_tangents(p0, a, b)
        level: list[_State] = [_State(p0, t, a, 0.0, None, None, t, 0) for t in starts]
        forced_at: list[int] = []
        while True:
            # finish from any state of this level
            for st in level:
                assert st.t is not None
                if not loop:
                    fin2 = self._finish(st.p, st.t, st.k, st.e, b)
                    if fin2 is not None:
                        return [*_unwind(st), fin2], forced_at
                elif st.parent is not None:
                    assert st.t_first is not None
                    clo = self._try_close(st.p, st.t, st.k, st.e, b, st.t_first)
                    if clo is not None:
                        return _unwind(st) + clo, forced_at
            nxt = self._expand(level, b)
            if nxt:
                level = nxt
                continue
            # a biarc bridge from a stuck state onto a sample with the polyline's direction
            for st in level if self.use_bridge else []:
                br = self._bridge(st, b, loop)
                if br is None:
                    continue
                if br.k >= b:
                    return _unwind(br), forced_at
                nxt = [br]
                break
            if nxt:
                level = nxt
                continue
            # nothing placed from any state of this level
            if loop:
                # close from earlier junctions of the best states
                for st in level:
                    node: _State | None = st
                    while node is not None and node.parent is not None:
                        par = node.parent
                        assert par.t is not None and st.t_first is not None
                        clo = self._biarc(par.p, par.t, par.k, par.e, b, st.t_first)
                        if clo is not None:
                            return _unwind(par) + clo, forced_at
                        node = par
            if not allow_forced:
                raise Stuck
            # valid by construction: a filleted polyline over a short stretch ahead
            fb = self._fallback(level[0], b, loop)
            if fb[1] is None:
                return fb[0], forced_at
            level = [fb[1]]
            continue

    #: arc length (in tolerances) a fallback stretch covers before the beam resumes
    FALLBACK_SPAN = 5.0

    def _fallback(self, st: _State, b: int, loop: bool) -> tuple[list[Piece], _State | None]:
        """A filleted-polyline stretch from ``st``: the whole chain, or the state after it."""
        assert st.t is not None
        k = st.k
        m = int(np.searchsorted(self.cum, self.cum[k] + self.FALLBACK_SPAN * self.tol))
        m = max(m, k + 2)
        if m >= b - 1:
            m = b
        if m == b:
            mode = "tangent" if loop else "sample"
        else:
            mode = "state"
        from zwcore.arcfallback import fillet_stretch  # (import cycle: arcfallback uses Piece)

        pieces, end = fillet_stretch(self.S, self.tol, st.p, st.t, k, m, mode,
                                     st.t_first if loop else None)
        node = st
        for pc in pieces:
            node = _State(pc.end, pc.t_end, pc.j, 0.0, node, pc, st.t_first, node.depth + 1)
        if end is None:
            return _unwind(node), None
        ep, et, ee = end
        return [], _State(ep, et, m, ee, node, None, st.t_first, node.depth, fresh=True)

    def _bridge(self, st: _State, b: int, loop: bool) -> _State | None:
        """Two verified arcs from ``st`` to a sample just ahead, ending along the polyline.

        The end state lies on the polyline with the direction of one of its segments
        (or their bisector), from which progress is always possible.
        """
        assert st.t is not None
        for m in range(st.k + 1, min(st.k + 12, b) + 1):
            if m == b and loop:
                continue
            dirs = []
            for i0, i1 in ((m - 1, m), (m, m + 1)):
                if 0 <= i0 and i1 <= b:
                    dv = self.S[i1] - self.S[i0]
                    n = float(np.hypot(*dv))
                    if n > 0.0:
                        dirs.append(dv / n)
            if len(dirs) == 2:
                bis = dirs[0] + dirs[1]
                nb = float(np.hypot(*bis))
                if nb > 1e-9:
                    dirs.append(bis / nb)
            for t1 in dirs:
                got = self._biarc(st.p, st.t, st.k, st.e, m, t1)
                if got is None:
                    continue
                a1, a2 = got
                mid = _State(a1.end, a1.t_end, a1.j, 0.0, st, a1, st.t_first, st.depth + 1)
                return _State(a2.end, a2.t_end, m, 0.0, mid, a2, st.t_first, st.depth + 2)
        return None

    def _expand(self, level: list[_State], b: int) -> list[_State]:
        """The next level: the best verified pieces from all states, by look-ahead reach."""
        rows: list[tuple[int, int, float, FloatArray, FloatArray, float]] = []
        for si, st in enumerate(level):
            for j, kk, end, tend, bonus in self._candidates(st, b):
                rows.append((si, j, kk, end, tend, bonus))
        out: list[_State] = []
        if rows:
            ep = np.array([r[3] for r in rows])
            et = np.array([r[4] for r in rows])
            js = np.array([r[1] for r in rows], dtype=np.int64)
            reach, lreach = self._reach_multi(ep, et, js, b)
            reach = np.where(js >= b, b, reach)
            lreach = np.where(js >= b, b, lreach)
            lscore = self.cum[lreach] + 0.3 * (self.cum[lreach] - self.cum[js])
            score = np.maximum(self.cum[reach], lscore) + np.array([r[5] for r in rows])
            isarc = np.array([r[2] != 0.0 for r in rows])
            order = np.lexsort((-js, isarc, -score))
            seen: set[tuple[int, int, int]] = set()
            checks = 0
            for i in order:
                if len(out) >= self.BEAM or checks >= 12 * self.BEAM:
                    break
                si, j, kk, _end, _tend, _ = rows[int(i)]
                st = level[si]
                key = (int(reach[i]), j, round(math.atan2(et[i][1], et[i][0]) * 1e3))
                if key in seen:
                    continue
                checks += 1
                assert st.t is not None
                res = self._check(st.p, st.t, kk, st.k, j, st.e)
                if res is None:
                    continue
                seen.add(key)
                pc = self._make(st.p, st.t, kk, st.k, j, res)
                out.append(_State(pc.end, pc.t_end, j, pc.e_end, st, pc, st.t_first,
                                  st.depth + 1))
        if not out:
            for st in level:
                assert st.t is not None
                lo1, up1 = self._scan(st.p, st.t, st.k, b)
                jm = min(st.k + len(lo1), b - 1)
                if jm <= st.k:
                    continue
                sh = self._shrink(st.p, st.t, st.k, st.e, jm, lo1, up1)
                if sh is not None:
                    out.append(_State(sh.end, sh.t_end, sh.j, sh.e_end, st, sh, st.t_first,
                                      st.depth + 1))
                    break
        return out

    def _finish(self, p: FloatArray, t: FloatArray, k: int, e: float, b: int) -> Piece | None:
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
    ) -> list[Piece] | None:
        # a biarc can span about two pieces' worth: it is tried once the rest is within
        # CLOSE_SPAN single-piece reaches of this state
        lo1, _up1 = self._scan(p, t, k, b)
        reach = self.cum[min(k + len(lo1), b)] - self.cum[k]
        if self.cum[b] - self.cum[k] > self.CLOSE_SPAN * max(reach, 1e-300):
            return None
        return self._biarc(p, t, k, e, b, t1)

    #: a closing biarc is tried when the rest is within this many single-piece reaches
    CLOSE_SPAN = 2.2


@dataclass
class _State:
    """A junction of a partial chain: the next piece starts at ``p`` with tangent ``t``."""

    p: FloatArray
    t: FloatArray | None
    k: int
    e: float
    parent: _State | None
    piece: Piece | None
    t_first: FloatArray | None
    depth: int
    fresh: bool = False


def _unwind(st: _State) -> list[Piece]:
    out: list[Piece] = []
    node: _State | None = st
    while node is not None:
        if node.piece is not None:
            out.append(node.piece)
        node = node.parent
    out.reverse()
    return out
