"""The per-run search of the C1 arc chain: a beam of junction states.

The pieces themselves (curvature intervals from a junction, reach scans,
two-sided verification, biarcs) are in :mod:`zwcore.arcpieces`; this module
decides which pieces make the chain.

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

When no state of a level can place a verified piece, a biarc bridge onto a
nearby sample is tried; failing that the caller retries with a tighter working
tolerance, and the last resort is a filleted-polyline stretch
(:mod:`zwcore.arcfallback`, valid by construction).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from zwcore.arcfallback import fillet_stretch
from zwcore.arcgeom import (
    arc_length_position,
    arc_points,
    circle_gap,
    local_uv,
    points_to_segments_distance,
    rotate,
)
from zwcore.arcpieces import Anchor, Piece, ToleranceBand, is_flat

FloatArray = NDArray[np.float64]

__all__ = ["Fitter", "Piece", "Stuck"]


class Stuck(Exception):
    """No verified piece could be placed from the current junction."""


@dataclass
class _State:
    """A junction of a partial chain: the next piece starts at ``p`` with tangent ``t``.

    ``p`` stands for sample ``k`` at distance ``e``; ``piece`` is the piece that
    ended here (None at the run start), ``parent`` the state it started from,
    ``t_first`` the chain's first tangent (a loop must close onto it).
    """

    p: FloatArray
    t: FloatArray | None
    k: int
    e: float
    parent: _State | None
    piece: Piece | None
    t_first: FloatArray | None
    depth: int
    fresh: bool = False


@dataclass
class _Cand:
    """A candidate piece from a state: it ends at ``end`` with tangent ``t_end`` standing
    for sample ``j``; ``sig_end`` is its length when given (else the foot point of
    ``j``), ``special`` marks anchor pieces, ``bonus`` is added to its rank score."""

    j: int
    kappa: float
    end: FloatArray
    t_end: FloatArray
    bonus: float
    sig_end: float | None = None
    special: bool = False


def _unwind(st: _State) -> list[Piece]:
    """The pieces of the chain that ends at ``st``, first to last."""
    out: list[Piece] = []
    node: _State | None = st
    while node is not None:
        if node.piece is not None:
            out.append(node.piece)
        node = node.parent
    out.reverse()
    return out


class Fitter:
    """Fits runs of the sample polyline (local frame, ``(M, 2)``) by a beam search.

    Parameters
    ----------
    samples : ndarray, shape (M, 2)
        The sample polyline (local frame).
    tol : float
        Tolerance of every piece, both ways.
    work : float
        Share of ``tol`` the feasibility scans use (see :class:`ToleranceBand`).
    max_radius : float or None
        Largest arc radius allowed; None: no limit.
    """

    #: ends of candidate pieces, as shares of the longest feasible piece's length: dense
    #: near the longest piece, where the junctions that let the next piece reach furthest
    #: usually are (coarser steps there cost the spiral and the die edge a piece each)
    J_FRACTIONS = (1.0, 0.99, 0.98, 0.97, 0.96, 0.94, 0.92, 0.9, 0.87, 0.83, 0.78, 0.72, 0.66,
                   0.56, 0.44)
    #: junction states kept per level
    BEAM = 4
    #: biarc bridges out of stuck states (off: the caller's fallback after a failed check)
    use_bridge = True
    #: arc length (in tolerances) a fallback stretch covers before the beam resumes
    FALLBACK_SPAN = 5.0
    #: a closing biarc is tried when the rest is within this many single-piece reaches
    CLOSE_SPAN = 2.2

    def __init__(
        self, samples: FloatArray, tol: float, work: float, max_radius: float | None
    ) -> None:
        self.band = ToleranceBand(samples, tol, work, max_radius)
        self.samples = samples
        self.tol = tol
        self.cum = self.band.cum
        #: straight runs the chain should follow with lines (see :meth:`_anchor_candidates`);
        #: when set, arcs over them or flat arcs (:meth:`_over_anchor`) rank last
        self.anchors: list[Anchor] = []

    # -- the start of a run: the tangent is not given ------------------------

    def free_start(self, p: FloatArray, k: int, b: int) -> tuple[FloatArray, int]:
        """Tangent at a run start that lets the first piece reach furthest.

        Returns the unit tangent and the last sample the first piece can cover
        from it (interval test).
        """
        band, samples = self.band, self.samples
        d = np.hypot(samples[k + 1 : b + 1, 0] - p[0], samples[k + 1 : b + 1, 1] - p[1])
        far = np.flatnonzero(d >= 3.0 * self.tol)
        i0 = k + 1 + (int(far[0]) if far.size else len(d) - 1)
        th0 = math.atan2(samples[i0, 1] - p[1], samples[i0, 0] - p[0])
        span, n = 1.4, 57
        best_th, best_r = th0, k
        for _ in range(3):
            ths = best_th + np.linspace(-span, span, n)
            ts = np.stack([np.cos(ths), np.sin(ths)], axis=1)
            r = band.reach(np.repeat(p[None, :], n, axis=0), ts, k, b, 64)
            top = np.flatnonzero(r == r.max())
            # the middle of the best range: robust to the grid and to noise
            mid = int(top[len(top) // 2])
            best_th, best_r = float(ths[mid]), int(r[mid])
            span = 2.0 * span / (n - 1)
            n = 21
        # a straight start is preferred when a line reaches nearly as far as the best arc
        ths = best_th + np.linspace(-0.2, 0.2, 81)
        lr, lth = band.line_reach(p, ths, k, b)
        if lr > k and self.cum[lr] - self.cum[k] >= 0.9 * (self.cum[best_r] - self.cum[k]):
            return np.array([math.cos(lth), math.sin(lth)]), best_r
        return np.array([math.cos(best_th), math.sin(best_th)]), best_r

    def _free_tangents(self, p: FloatArray, k: int, b: int) -> list[FloatArray]:
        """A few start tangents at a run start (no tangent given), best first."""
        t0, _r0 = self.free_start(p, k, b)
        out = [t0]
        th0 = math.atan2(t0[1], t0[0])
        for d in (0.04, -0.04, 0.12, -0.12):
            out.append(np.array([math.cos(th0 + d), math.sin(th0 + d)]))
        return out

    # -- whole runs as one piece -----------------------------------------------

    def _finish_free(self, p: FloatArray, k: int, b: int, th_guess: float) -> Piece | None:
        """One piece from ``p`` (free tangent) ending exactly at sample ``b``.

        The start tangent is the chord's or the one of the minimax circle through
        both ends (golden-section search about ``th_guess``).
        """
        band, samples = self.band, self.samples
        pts = samples[k + 1 : b + 1]
        dx, dy = samples[b] - p
        chord = math.atan2(dy, dx)

        def worst(th: float) -> float:
            t = np.array([math.cos(th), math.sin(th)])
            ub, vb = local_uv(p, t, samples[b : b + 1])
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
            ub, vb = local_uv(p, t, samples[b : b + 1])
            q2 = float(ub[0] ** 2 + vb[0] ** 2)
            if q2 <= 0.0:
                continue
            kap = 0.0 if th == chord else float(2.0 * vb[0] / q2)
            if not band.radius_ok(kap):
                continue
            res = band.verify(p, t, kap, k, b, float(np.hypot(*(samples[k] - p))))
            if res is not None:
                piece = band.make_piece(p, t, kap, k, b, res)
                piece.end = samples[b].copy()
                return piece
        return None

    def _full_circle(self, a: int, b: int) -> Piece | None:
        """A whole closed run as one full circle through its first sample (if it fits)."""
        pts = self.samples[a:b]
        if len(pts) < 3:
            return None
        c0 = pts.mean(axis=0)
        x = pts - c0
        mat = np.column_stack([x[:, 0], x[:, 1], np.ones(len(x))])
        rhs = (x * x).sum(axis=1)
        sol, *_ = np.linalg.lstsq(mat, rhs, rcond=None)
        c = c0 + 0.5 * sol[:2]
        p = self.samples[a]
        r = float(np.hypot(*(p - c)))
        if not (r > 0 and math.isfinite(r)):
            return None
        xx = self.samples[a : b + 1]
        area = float(np.sum(xx[:-1, 0] * xx[1:, 1] - xx[1:, 0] * xx[:-1, 1]))
        kap = 1.0 / r if area > 0 else -1.0 / r
        rv = (p - c) / r
        t = np.array([-rv[1], rv[0]]) if kap > 0 else np.array([rv[1], -rv[0]])
        if abs(kap) < self.band.kmin:  # any small radius: the whole loop is one circle
            return None
        res = self.band.verify(p, t, kap, a, b, 0.0)
        if res is None or abs(abs(kap * res[0]) - 2.0 * math.pi) > 1e-6:
            return None
        piece = self.band.make_piece(p, t, kap, a, b, (2.0 * math.pi / abs(kap), p.copy(), 0.0))
        piece.t_end = t.copy()
        return piece

    # -- the beam ---------------------------------------------------------------

    def run(
        self, a: int, b: int, loop: bool, allow_forced: bool, t_start: FloatArray | None = None
    ) -> tuple[list[Piece], list[int]]:
        """Fit samples ``a..b``.

        ``loop``: the run is a whole closed curve (C1 closure onto the first
        tangent). ``allow_forced``: where the beam is stuck, cover a stretch by a
        filleted polyline instead of raising :class:`Stuck`. ``t_start``: the
        tangent the first piece must start with (free when None).

        Returns the pieces and the piece indices after which a forced corner sits
        (empty in practice: the fallback joins C1).
        """
        band = self.band
        if loop:
            circ = self._full_circle(a, b)
            if circ is not None:
                return [circ], []
        p0 = self.samples[a].copy()
        if not loop and t_start is None:
            t0, r0 = self.free_start(p0, a, b)
            if r0 >= b:
                fin = self._finish_free(p0, a, b, math.atan2(t0[1], t0[0]))
                if fin is not None:
                    return [fin], []
        starts = [t_start] if t_start is not None else self._free_tangents(p0, a, b)
        if t_start is None and not loop:
            for an in self.anchors:
                if an.i0 == a and np.array_equal(an.q, p0):
                    # a straight run from the start: its line first
                    starts = [an.d.copy(), *starts]
        level: list[_State] = [_State(p0, t, a, 0.0, None, None, t, 0) for t in starts]
        forced_at: list[int] = []
        flat_fin: tuple[list[Piece], int] | None = None
        while True:
            if flat_fin is not None:
                if flat_fin[1] == 0:
                    return flat_fin[0], forced_at
                flat_fin = (flat_fin[0], flat_fin[1] - 1)
            # finish from any state of this level (with anchors: a flat last arc only
            # when no state of this level or the next two finishes otherwise)
            for st in level:
                assert st.t is not None
                if not loop:
                    fin2 = band.piece_to_sample(st.p, st.t, st.k, st.e, b)
                    if fin2 is not None:
                        if self.anchors and self._over_anchor(st.k, b, fin2.kappa,
                                                              fin2.length):
                            if flat_fin is None:
                                flat_fin = ([*_unwind(st), fin2], 2)
                            continue
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
            if flat_fin is not None:
                return flat_fin[0], forced_at
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
                        clo = band.biarc(par.p, par.t, par.k, par.e, b, st.t_first)
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

    def _candidates(self, st: _State, b: int) -> list[_Cand]:
        """Candidate pieces from a state (unverified)."""
        band = self.band
        p, t, k = st.p, st.t, st.k
        assert t is not None
        jlimit = b - 1
        if jlimit <= k:
            return []
        lo1, up1 = band.longest_piece_bounds(p, t, k, b)
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
            kap = band.candidate_kappas(float(lo1[j - k - 1]), float(up1[j - k - 1]))
            uj, vj = local_uv(p, t, self.samples[j : j + 1])
            for kk in kap:
                sj = arc_length_position(uj, vj, float(kk))
                end = arc_points(p, t, float(kk), sj)[0]
                tend = rotate(t, float(kk) * float(sj[0]))
                bonus = 0.3 * float(self.cum[j] - self.cum[k]) if kk == 0.0 else 0.0
                out.append(_Cand(j, float(kk), end, tend, bonus))
        if self.anchors:
            out.extend(self._anchor_candidates(st, b))
        return out

    def _anchor_candidates(self, st: _State, b: int) -> list[_Cand]:
        """Pieces that make the chain follow the next straight run with a line.

        From any state: the arc that lands tangentially on the next anchor's line
        (its curvature follows from the state and the line in closed form). From a
        state on an anchor's line: the line up to the tangent point of the fillet onto
        the next anchor (radius from the input's distance to the lines' intersection),
        from where the landing arc is that fillet.
        """
        p, t, k = st.p, st.t, st.k
        assert t is not None
        tol = self.tol
        here: Anchor | None = None
        nxt: Anchor | None = None
        for an in self.anchors:
            if an.i1 <= k:
                continue
            on = (abs(float(t[0] * an.d[1] - t[1] * an.d[0])) <= 1e-12
                  and float(t @ an.d) > 0.0
                  and abs(float((p - an.q) @ np.array([-an.d[1], an.d[0]])))
                  <= 1e-9 * tol + 1e-13 * float(np.abs(p).max()))
            if on and an.i0 <= k + 1:
                here = an
                continue
            nxt = an
            break
        if nxt is None:
            return []
        out: list[_Cand] = []
        d = nxt.d
        nd = np.array([-d[1], d[0]])
        n = np.array([-t[1], t[0]])
        delta = math.atan2(float(t[0] * d[1] - t[1] * d[0]), float(t @ d))
        if 1e-9 < abs(delta) < math.pi - 1e-3:
            # landing arc: nd . (p + (sin D t + (1 - cos D) n) / kappa - q) = 0
            h0 = float(nd @ (p - nxt.q))
            w = float(nd @ (math.sin(delta) * t + (1.0 - math.cos(delta)) * n))
            if h0 != 0.0:
                kap = -w / h0
                if kap * delta > 0.0 and self.band.radius_ok(kap):
                    s_end = delta / kap
                    j = self._last_before(p, t, kap, k, min(nxt.i1, b - 1), s_end)
                    if j > k:
                        end = arc_points(p, t, kap, np.array([s_end]))[0]
                        out.append(_Cand(j, kap, end, d.copy(), 0.0, s_end, True))
        if here is not None:
            # the fillet between this line and the next one
            dh = here.d
            cr = float(dh[0] * d[1] - dh[1] * d[0])
            turn = math.atan2(cr, float(dh @ d))
            if 1e-6 < abs(turn) < math.pi - 1e-3:
                # intersection V = q_here + a dh = q_next + c d
                rhs = nxt.q - here.q
                alpha = float(rhs[0] * d[1] - rhs[1] * d[0]) / cr
                vtx = here.q + alpha * dh
                hi = min(nxt.i1, b)
                seg_d = points_to_segments_distance(
                    vtx[None, :], self.samples[k:hi], self.samples[k + 1 : hi + 1])
                m = float(seg_d.min()) if seg_d.size else 0.0
                half = 0.5 * abs(turn)
                den = 1.0 / math.cos(half) - 1.0
                for f in (1.0, 0.97, 1.03):
                    rad = f * m / den if den > 0.0 else 0.0
                    s_line = float(dh @ (vtx - p)) - rad * math.tan(half)
                    if not s_line > 0.0 or rad <= 0.0:
                        continue
                    j = self._last_before(p, dh, 0.0, k, min(nxt.i1, b - 1), s_line)
                    if j > k:
                        out.append(_Cand(j, 0.0, p + s_line * dh, dh.copy(), 0.0, s_line,
                                         True))
        return out

    def _last_before(
        self, p: FloatArray, t: FloatArray, kap: float, k: int, hi: int, s_end: float
    ) -> int:
        """Last sample in ``k..hi`` whose foot point on the piece lies before ``s_end``."""
        if hi <= k:
            return k
        u, v = local_uv(p, t, self.samples[k + 1 : hi + 1])
        if kap != 0.0:
            sig = np.unwrap(np.arctan2(kap * u, 1.0 - kap * v)) / kap
        else:
            sig = u
        over = np.flatnonzero(sig > s_end)
        return k + (int(over[0]) if over.size else len(sig))

    def _expand(self, level: list[_State], b: int) -> list[_State]:
        """The next level: the best verified pieces from all states, by look-ahead reach.

        With anchors, anchor pieces (:meth:`_anchor_candidates`) take up to half the
        beam first, and flat arcs rank after every other candidate.
        """
        band = self.band
        rows: list[tuple[int, _Cand]] = []
        for si, st in enumerate(level):
            for c in self._candidates(st, b):
                rows.append((si, c))
        out: list[_State] = []
        if rows:
            ep = np.array([r[1].end for r in rows])
            et = np.array([r[1].t_end for r in rows])
            js = np.array([r[1].j for r in rows], dtype=np.int64)
            reach, lreach = band.reach_with_lines(ep, et, js, b)
            reach = np.where(js >= b, b, reach)
            lreach = np.where(js >= b, b, lreach)
            lscore = self.cum[lreach] + 0.3 * (self.cum[lreach] - self.cum[js])
            score = np.maximum(self.cum[reach], lscore) + np.array([r[1].bonus for r in rows])
            isarc = np.array([r[1].kappa != 0.0 for r in rows])
            if self.anchors:
                flat = np.array([
                    r[1].kappa != 0.0 and self._over_anchor(
                        level[r[0]].k, r[1].j, r[1].kappa,
                        self._approx_len(level[r[0]], r[1]))
                    for r in rows])
                special = np.array([r[1].special for r in rows])
                order = np.lexsort((-js, isarc, -score, flat))
                order = np.concatenate([order[special[order]], order[~special[order]]])
                n_special_max = self.BEAM // 2
            else:
                order = np.lexsort((-js, isarc, -score))
                n_special_max = 0
            seen: set[tuple[int, int, int]] = set()
            checks = 0
            n_special = 0
            for i in order:
                if len(out) >= self.BEAM or checks >= 12 * self.BEAM:
                    break
                si, c = rows[int(i)]
                if c.special and n_special >= n_special_max:
                    continue
                st = level[si]
                key = (int(reach[i]), c.j, round(math.atan2(et[i][1], et[i][0]) * 1e3))
                if key in seen:
                    continue
                checks += 1
                assert st.t is not None
                res = band.verify(st.p, st.t, c.kappa, st.k, c.j, st.e, sig_end=c.sig_end)
                if res is None:
                    continue
                seen.add(key)
                pc = band.make_piece(st.p, st.t, c.kappa, st.k, c.j, res)
                if c.special:
                    n_special += 1
                    pc.t_end = c.t_end.copy()  # exactly the anchor's direction
                out.append(_State(pc.end, pc.t_end, c.j, pc.e_end, st, pc, st.t_first,
                                  st.depth + 1))
        if not out:
            for st in level:
                assert st.t is not None
                lo1, up1 = band.longest_piece_bounds(st.p, st.t, st.k, b)
                jm = min(st.k + len(lo1), b - 1)
                if jm <= st.k:
                    continue
                sh = self._shrink(st.p, st.t, st.k, st.e, jm, lo1, up1)
                if sh is not None:
                    out.append(_State(sh.end, sh.t_end, sh.j, sh.e_end, st, sh, st.t_first,
                                      st.depth + 1))
                    break
        return out

    def _shrink(
        self, p: FloatArray, t: FloatArray, k: int, e: float, jm: int, lo1: FloatArray,
        up1: FloatArray,
    ) -> Piece | None:
        """Fallback of :meth:`_expand`: ever shorter pieces with several curvatures.

        ``lo1, up1`` are the running curvature bounds from ``(p, t)`` up to sample ``jm``.
        """
        band = self.band
        j = jm
        while j > k:
            if j - k - 1 < len(lo1):
                kap = band.candidate_kappas(float(lo1[j - k - 1]), float(up1[j - k - 1]))
            else:
                u, v = local_uv(p, t, self.samples[j : j + 1])
                q2 = float(u[0] ** 2 + v[0] ** 2)
                kap = [2.0 * float(v[0]) / q2] if q2 > 0 else [0.0]
            for kk in kap:
                if not band.radius_ok(kk):
                    continue
                res = band.verify(p, t, kk, k, j, e)
                if res is not None:
                    return band.make_piece(p, t, kk, k, j, res)
            if j == k + 1:
                break
            j = k + max(1, (j - k) // 2)
        return None

    def _over_anchor(self, k: int, j: int, kappa: float, length: float) -> bool:
        """True for an arc over samples ``k..j`` that is flat or covers more than half of
        an anchor (a straight run the chain should follow with a line)."""
        if kappa == 0.0:
            return False
        if is_flat(kappa, length, self.tol):
            return True
        for an in self.anchors:
            over = self.cum[min(j, an.i1)] - self.cum[max(k, an.i0)]
            if over > 0.5 * (self.cum[an.i1] - self.cum[an.i0]):
                return True
        return False

    def _approx_len(self, st: _State, c: _Cand) -> float:
        """Length of candidate ``c`` from ``st`` (its given length, or the chord's arc)."""
        if c.sig_end is not None:
            return c.sig_end
        chord = float(np.hypot(*(c.end - st.p)))
        x = 0.5 * c.kappa * chord
        return chord * (math.asin(min(abs(x), 1.0)) / abs(x) if x != 0.0 else 1.0)

    # -- ways out of a stuck level ---------------------------------------------

    def _bridge(self, st: _State, b: int, loop: bool) -> _State | None:
        """Two verified arcs from ``st`` to a sample just ahead, ending along the polyline.

        The end state lies on the polyline with the direction of one of its segments
        (or their bisector), from which progress is always possible.
        """
        assert st.t is not None
        samples = self.samples
        for m in range(st.k + 1, min(st.k + 12, b) + 1):
            if m == b and loop:
                continue
            dirs = []
            for i0, i1 in ((m - 1, m), (m, m + 1)):
                if 0 <= i0 and i1 <= b:
                    dv = samples[i1] - samples[i0]
                    n = float(np.hypot(*dv))
                    if n > 0.0:
                        dirs.append(dv / n)
            if len(dirs) == 2:
                bis = dirs[0] + dirs[1]
                nb = float(np.hypot(*bis))
                if nb > 1e-9:
                    dirs.append(bis / nb)
            for t1 in dirs:
                got = self.band.biarc(st.p, st.t, st.k, st.e, m, t1)
                if got is None:
                    continue
                a1, a2 = got
                mid = _State(a1.end, a1.t_end, a1.j, 0.0, st, a1, st.t_first, st.depth + 1)
                return _State(a2.end, a2.t_end, m, 0.0, mid, a2, st.t_first, st.depth + 2)
        return None

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
        pieces, end = fillet_stretch(self.samples, self.tol, st.p, st.t, k, m, mode,
                                     st.t_first if loop else None)
        node = st
        for pc in pieces:
            node = _State(pc.end, pc.t_end, pc.j, 0.0, node, pc, st.t_first, node.depth + 1)
        if end is None:
            return _unwind(node), None
        ep, et, ee = end
        return [], _State(ep, et, m, ee, node, None, st.t_first, node.depth, fresh=True)

    # -- closing a loop ----------------------------------------------------------

    def _try_close(
        self, p: FloatArray, t: FloatArray, k: int, e: float, b: int, t1: FloatArray
    ) -> list[Piece] | None:
        """A closing biarc from ``(p, t)`` onto sample ``b`` with tangent ``t1``.

        A biarc can span about two pieces' worth: it is tried once the rest is within
        :attr:`CLOSE_SPAN` single-piece reaches of this state.
        """
        lo1, _up1 = self.band.longest_piece_bounds(p, t, k, b)
        reach = self.cum[min(k + len(lo1), b)] - self.cum[k]
        if self.cum[b] - self.cum[k] > self.CLOSE_SPAN * max(reach, 1e-300):
            return None
        return self.band.biarc(p, t, k, e, b, t1)
