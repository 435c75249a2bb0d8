"""The per-run search of the C1 arc chain: a beam of junction states.

The pieces themselves (curvature intervals from a junction, reach scans,
two-sided verification, biarcs) are in :mod:`zwcore.arcs._pieces`, run starts without a
given tangent and one-piece runs in :mod:`zwcore.arcs._start`, and the straight runs a
refit follows with lines in :mod:`zwcore.arcs._lines`; this module decides which pieces
make the chain.

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
(:mod:`zwcore.arcs._fallback`, valid by construction).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from zwcore.arcs._fallback import fillet_stretch
from zwcore.arcs._geometry import (
    arc_points,
    local_uv,
    rotate,
)
from zwcore.arcs._lines import StraightRuns
from zwcore.arcs._pieces import Piece, ToleranceBand
from zwcore.arcs._start import free_start, free_start_tangents, full_circle, one_piece_to_end

FloatArray = NDArray[np.float64]

__all__ = ["Fitter", "Piece", "Stuck"]


class Stuck(Exception):
    """No verified piece could be placed from the current junction."""


@dataclass
class _State:
    """A junction of a partial chain: the next piece starts at ``p`` with tangent ``t``.

    ``p`` stands for sample ``k`` at distance ``e``; ``piece`` is the piece that
    ended here (None at the run start), ``parent`` the state it started from,
    ``t_first`` the chain's first tangent (a loop must close onto it); ``n_over``
    counts the chain's arcs over straight runs once known (:meth:`Fitter._n_over`).
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
    n_over: int | None = None
    #: :meth:`ToleranceBand.longest_piece_bounds` from here, once asked (see
    #: :meth:`Fitter._bounds`)
    bounds: tuple[FloatArray, FloatArray] | None = None


@dataclass
class _Cand:
    """A candidate piece from a state: it ends at ``end`` with tangent ``t_end`` standing
    for sample ``j``; ``sig_end`` is its length when given (else the foot point of
    ``j``), ``special`` marks pieces onto straight runs (:class:`StraightRuns`),
    ``bonus`` is added to its rank score."""

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


def _approx_len(c: _Cand, chord: float) -> float:
    """Length of candidate ``c`` whose chord is ``chord`` long (its given length, or the
    chord's arc)."""
    if c.sig_end is not None:
        return c.sig_end
    x = 0.5 * c.kappa * chord
    return chord * (math.asin(min(abs(x), 1.0)) / abs(x) if x != 0.0 else 1.0)


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
    #: a run that one piece (or a loop that one full circle) covers is that piece
    #: (:mod:`zwcore.arcs._start`); off: the beam fits it (tests of the fallback)
    one_piece_runs = True
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
        self._j_fractions = np.array(self.J_FRACTIONS)
        self._k_fractions = np.array(self.band.K_FRACTIONS)
        #: straight runs the chain should follow with lines; when set, pieces onto them
        #: are proposed and chains with fewer arcs over them rank and finish first
        self.straight: StraightRuns | None = None
        #: landing biarcs found at the last level, joining the beam one level later
        self._landed: list[_State] = []

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
        if loop and self.one_piece_runs:
            circ = full_circle(self.band, a, b)
            if circ is not None:
                return [circ], []
        p0 = self.samples[a].copy()
        if not loop and t_start is None:
            t0, r0 = free_start(self.band, p0, a, b)
            if r0 >= b and self.one_piece_runs:
                fin = one_piece_to_end(self.band, p0, a, b, math.atan2(t0[1], t0[0]))
                if fin is not None:
                    return [fin], []
        starts = [t_start] if t_start is not None else free_start_tangents(self.band, p0, a, b)
        sr = self.straight
        if t_start is None and not loop and sr is not None:
            d0 = sr.start_direction(a, p0)
            if d0 is not None:
                starts = [d0, *starts]  # a straight run from the start: its line first
        level: list[_State] = [_State(p0, t, a, 0.0, None, None, t, 0) for t in starts]
        forced_at: list[int] = []
        # (chain, levels left, its arcs over straight runs)
        flat_fin: tuple[list[Piece], int, int] | None = None
        while True:
            if flat_fin is not None:
                if flat_fin[1] == 0:
                    return flat_fin[0], forced_at
                flat_fin = (flat_fin[0], flat_fin[1] - 1, flat_fin[2])
            # finish from any state of this level (with anchors: the chain with the fewest
            # arcs over straight runs; one with such arcs only when no state of this
            # level or the next two finishes without)
            fins: list[tuple[int, list[Piece]]] = []
            for st in level:
                assert st.t is not None
                if not loop:
                    fin2 = band.piece_to_sample(st.p, st.t, st.k, st.e, b)
                    if fin2 is not None:
                        if sr is None:
                            return [*_unwind(st), fin2], forced_at
                        fins.append((self._n_over(st) + sr.is_over(
                            fin2.k, fin2.j, fin2.kappa, fin2.length), [*_unwind(st), fin2]))
                elif st.parent is not None:
                    assert st.t_first is not None
                    clo = self._try_close(st, b, st.t_first)
                    if clo is not None:
                        return _unwind(st) + clo, forced_at
            if fins:
                assert sr is not None
                n_over, best = min(fins, key=lambda f: f[0])
                if n_over == 0:
                    return best, forced_at
                if flat_fin is None:
                    flat_fin = (best, 2, n_over)
                elif n_over < flat_fin[2]:
                    flat_fin = (best, flat_fin[1], n_over)
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
        p, t, k = st.p, st.t, st.k
        assert t is not None
        jlimit = b - 1
        if jlimit <= k:
            return []
        lo1, up1 = self._bounds(st, b)
        jm = min(k + len(lo1), jlimit)
        if jm <= k:
            return []
        span = self.cum[jm] - self.cum[k]
        at = np.searchsorted(self.cum, self.cum[k] + self._j_fractions * span, side="right")
        js = sorted({min(max(int(i) - 1, k + 1), jm) for i in at}, reverse=True)
        jj, kk = self._candidate_kappas(js, k, lo1, up1)
        out = []
        if jj.size:
            # all candidates at once (numpy's overhead per call dominates one-point calls):
            # the foot point of sample j on each piece, its end point and end tangent
            u, v = local_uv(p, t, self.samples[jj])
            line = kk == 0.0
            sj = np.where(line, u, np.arctan2(kk * u, 1.0 - kk * v) / np.where(line, 1.0, kk))
            ends = arc_points(p, t, kk, sj)
            tends = rotate(t, kk * sj)
            bonus = np.where(line, 0.3 * (self.cum[jj] - self.cum[k]), 0.0).tolist()
            for i, (j, kap) in enumerate(zip(jj.tolist(), kk.tolist(), strict=True)):
                out.append(_Cand(j, kap, ends[i], tends[i], bonus[i]))
        if self.straight is not None:
            for j, kap, end, tend, s_end in self.straight.candidates(p, t, k, b):
                out.append(_Cand(j, kap, end, tend, 0.0, s_end, True))
        return out

    def _candidate_kappas(
        self, js: list[int], k: int, lo1: FloatArray, up1: FloatArray
    ) -> tuple[NDArray[np.int64], FloatArray]:
        """The ends and curvatures of the candidates from a state at sample ``k``:
        :meth:`ToleranceBand.candidate_kappas` for each end ``j`` of ``js`` (running bounds
        ``lo1, up1``), in that order, as flat arrays."""
        band = self.band
        if band.kmin > 0.0:
            pairs = [(j, kap) for j in js for kap in band.candidate_kappas(
                float(lo1[j - k - 1]), float(up1[j - k - 1]))]
            return (np.array([q[0] for q in pairs], dtype=np.int64),
                    np.array([q[1] for q in pairs], dtype=np.float64))
        ja = np.array(js, dtype=np.int64)
        lo = np.maximum(lo1[ja - k - 1], -band.kcap)
        hi = np.minimum(up1[ja - k - 1], band.kcap)
        ok = lo <= hi
        # per end: a line first when allowed, then the fractions of the interval
        vals = np.concatenate(
            [np.zeros((len(ja), 1)),
             lo[:, None] + self._k_fractions[None, :] * (hi - lo)[:, None]], axis=1)
        mask = np.concatenate(
            [(ok & (lo <= 0.0) & (hi >= 0.0))[:, None],
             np.repeat(ok[:, None], len(self._k_fractions), axis=1)], axis=1)
        return np.repeat(ja[:, None], vals.shape[1], axis=1)[mask], vals[mask]

    def _expand(self, level: list[_State], b: int) -> list[_State]:
        """The next level: the best verified pieces from all states, by look-ahead reach.

        With straight runs to follow, pieces onto them take up to half the beam first,
        then candidates rank by the arcs over straight runs in their chain, and landing
        biarcs (:meth:`StraightRuns.landing_biarc`) join one level later.
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
            sr = self.straight
            if sr is not None:
                sp = np.array([level[r[0]].p for r in rows])
                chord = np.hypot(ep[:, 0] - sp[:, 0], ep[:, 1] - sp[:, 1]).tolist()
                flat = np.array([
                    c.kappa != 0.0 and sr.is_over(level[si].k, c.j, c.kappa,
                                                  _approx_len(c, chord[i]))
                    for i, (si, c) in enumerate(rows)])
                special = np.array([r[1].special for r in rows])
                # arcs over straight runs in the chain so far, this candidate's included
                before = [self._n_over(st) for st in level]
                n_over = np.array([before[r[0]] for r in rows]) + flat
                order = np.lexsort((-js, isarc, -score, n_over))
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
        if self.straight is not None:
            # a landing biarc is two pieces: its end joins the level after next
            out.extend(self._landed)
            self._landed = []
            for st in level:
                assert st.t is not None
                got = self.straight.landing_biarc(st.p, st.t, st.k, st.e, b,
                                                  len(self._bounds(st, b)[0]))
                if got is not None:
                    a1, a2 = got
                    mid = _State(a1.end, a1.t_end, a1.j, a1.e_end, st, a1, st.t_first,
                                 st.depth + 1)
                    self._landed.append(_State(a2.end, a2.t_end, a2.j, a2.e_end, mid, a2,
                                               st.t_first, st.depth + 2))
        if not out:
            for st in level:
                assert st.t is not None
                lo1, up1 = self._bounds(st, b)
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

    def _bounds(self, st: _State, b: int) -> tuple[FloatArray, FloatArray]:
        """The running curvature bounds of the longest piece from ``st`` (asked for by
        the candidates, the closing biarc and the landing biarc: computed once)."""
        if st.bounds is None:
            assert st.t is not None
            st.bounds = self.band.longest_piece_bounds(st.p, st.t, st.k, b)
        return st.bounds

    def _n_over(self, st: _State) -> int:
        """Arcs over straight runs in the chain ending at ``st``
        (:meth:`StraightRuns.is_over`), carried along the states: each piece is looked at
        once, not once per candidate."""
        sr = self.straight
        assert sr is not None
        todo: list[_State] = []
        node: _State | None = st
        while node is not None and node.n_over is None:
            todo.append(node)
            node = node.parent
        count = node.n_over if node is not None and node.n_over is not None else 0
        for nd in reversed(todo):
            pc = nd.piece
            if pc is not None:
                count += sr.is_over(pc.k, pc.j, pc.kappa, pc.length)
            nd.n_over = count
        return count

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

    def _try_close(self, st: _State, b: int, t1: FloatArray) -> list[Piece] | None:
        """A closing biarc from ``(p, t)`` onto sample ``b`` with tangent ``t1``.

        A biarc can span about two pieces' worth: it is tried once the rest is within
        :attr:`CLOSE_SPAN` single-piece reaches of this state.
        """
        assert st.t is not None
        k = st.k
        lo1, _up1 = self._bounds(st, b)
        reach = self.cum[min(k + len(lo1), b)] - self.cum[k]
        if self.cum[b] - self.cum[k] > self.CLOSE_SPAN * max(reach, 1e-300):
            return None
        return self.band.biarc(st.p, st.t, k, st.e, b, t1)
