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
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from zwcore.arcs._anchors import AnchorPiece, StraightRuns
from zwcore.arcs._geometry import arc_points, local_uv, rotate
from zwcore.arcs._pieces import Piece, ToleranceBand
from zwcore.arcs._ranking import rank_level
from zwcore.arcs._select import candidates, candidates_level, select_verified
from zwcore.arcs._start import free_start, free_start_tangents, full_circle, one_piece_to_end
from zwcore.arcs._states import Behind, Cands, State, Stuck, level_arrays, unwind
from zwcore.arcs._unstick import bridge, fallback

FloatArray = NDArray[np.float64]

__all__ = ["Behind", "Fitter", "Piece", "Stuck"]


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
    cum : ndarray, shape (M,), optional
        The samples' cumulative polyline length, when known (:class:`ToleranceBand`).
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

    def __init__(self, samples: FloatArray, tol: float, work: float,
                 max_radius: float | None, cum: FloatArray | None = None) -> None:
        self.band = ToleranceBand(samples, tol, work, max_radius, cum)
        self.samples = samples
        self.tol = tol
        self.cum = self.band.cum
        self._j_fractions = np.array(self.J_FRACTIONS)
        self._k_fractions = np.array(self.band.K_FRACTIONS)
        #: straight runs the chain should follow with lines; when set, pieces onto them
        #: are proposed and chains with fewer arcs over them rank and finish first
        self.straight: StraightRuns | None = None
        #: landing biarcs found at the last level, joining the beam one level later
        self._landed: list[State] = []
        #: given a new level, True when the chains it continues cannot be worth
        #: finishing (the run then raises :class:`Stuck`; the loop start sweep)
        self.cutoff: Callable[[list[State]], bool] | None = None
        #: the levels of the last :meth:`run`, first to last, when recording (a list)
        self.levels: list[list[State]] | None = None
        #: free run starts found so far (:func:`zwcore.arcs._start.free_start`)
        self.starts: dict[tuple[int, int], tuple[FloatArray, int]] = {}

    # -- the beam ---------------------------------------------------------------

    def run(
        self, a: int, b: int, loop: bool, allow_forced: bool, t_start: FloatArray | None = None,
        resume: list[State] | None = None,
    ) -> tuple[list[Piece], list[int]]:
        """Fit samples ``a..b``.

        ``loop``: the run is a whole closed curve (C1 closure onto the first
        tangent). ``allow_forced``: where the beam is stuck, cover a stretch by a
        filleted polyline instead of raising :class:`Stuck`. ``t_start``: the
        tangent the first piece must start with (free when None). ``resume``: a level
        of an earlier run of the same samples to go on from (see
        :func:`resume_level`) instead of the run's start.

        Returns the pieces and the piece indices after which a forced corner sits
        (empty in practice: the fallback joins C1).
        """
        if resume is None:
            fin = self._one_piece(a, b, loop, t_start)
            if fin is not None:
                return [fin], []
        level = self._start_level(a, b, loop, t_start) if resume is None else resume
        forced_at: list[int] = []
        # (chain, levels left, its arcs over straight runs)
        flat_fin: tuple[list[Piece], int, int] | None = None
        while True:
            if self.levels is not None:
                self.levels.append(level)
            if flat_fin is not None:
                if flat_fin[1] == 0:
                    return flat_fin[0], forced_at
                flat_fin = (flat_fin[0], flat_fin[1] - 1, flat_fin[2])
            done, flat_fin = self._finish(level, b, loop, flat_fin)
            if done is not None:
                return done, forced_at
            nxt = self._expand(level, b)
            if nxt and self.cutoff is not None and self.cutoff(nxt):
                raise Behind
            if nxt:
                level = nxt
                continue
            if flat_fin is not None:
                return flat_fin[0], forced_at
            done, level = self._unstick(level, b, loop, allow_forced)
            if done is not None:
                return done, forced_at

    def _one_piece(
        self, a: int, b: int, loop: bool, t_start: FloatArray | None
    ) -> Piece | None:
        """The one piece (a loop: the full circle) that covers the whole run, if any."""
        if loop and self.one_piece_runs:
            circ = full_circle(self.band, a, b)
            if circ is not None:
                return circ
        if not loop and t_start is None:
            p0 = self.samples[a].copy()
            t0, r0 = free_start(self.band, p0, a, b, self.starts)
            if r0 >= b and self.one_piece_runs:
                return one_piece_to_end(self.band, p0, a, b, math.atan2(t0[1], t0[0]))
        return None

    def _start_level(
        self, a: int, b: int, loop: bool, t_start: FloatArray | None
    ) -> list[State]:
        """The first level: the run's start with the given tangent, else a few free ones."""
        p0 = self.samples[a].copy()
        starts = [t_start] if t_start is not None else free_start_tangents(self.band, p0, a,
                                                                           b, self.starts)
        sr = self.straight
        if t_start is None and not loop and sr is not None:
            d0 = sr.start_direction(a, p0)
            if d0 is not None:
                starts = [d0, *starts]  # a straight run from the start: its line first
        return [State(p0, t, a, 0.0, None, None, t, 0) for t in starts]

    def _finish(
        self, level: list[State], b: int, loop: bool,
        flat_fin: tuple[list[Piece], int, int] | None,
    ) -> tuple[list[Piece] | None, tuple[list[Piece], int, int] | None]:
        """The chain when a state of ``level`` finishes the run, and the best finish so
        far that lays arcs over straight runs (``flat_fin``: chain, levels it waits for
        a better one, its count of such arcs).

        With anchors the chain with the fewest arcs over straight runs wins; one with
        such arcs only when no state of this level or the next two finishes without.
        """
        band = self.band
        sr = self.straight
        fins: list[tuple[int, list[Piece]]] = []
        for st in level:
            assert st.t is not None
            if not loop:
                fin2 = band.piece_to_sample(st.p, st.t, st.k, st.e, b)
                if fin2 is not None:
                    if sr is None:
                        return [*unwind(st), fin2], flat_fin
                    fins.append((self._n_over(st) + sr.is_over(
                        fin2.k, fin2.j, fin2.kappa, fin2.length), [*unwind(st), fin2]))
            elif st.parent is not None:
                assert st.t_first is not None
                clo = self._try_close(st, b, st.t_first)
                if clo is not None:
                    return unwind(st) + clo, flat_fin
        if fins:
            n_over, best = min(fins, key=lambda f: f[0])
            if n_over == 0:
                return best, flat_fin
            if flat_fin is None:
                flat_fin = (best, 2, n_over)
            elif n_over < flat_fin[2]:
                flat_fin = (best, flat_fin[1], n_over)
        return None, flat_fin

    def _unstick(
        self, level: list[State], b: int, loop: bool, allow_forced: bool
    ) -> tuple[list[Piece] | None, list[State]]:
        """Nothing verified could be placed from ``level``: a bridge, a loop closed from
        earlier junctions, or (``allow_forced``) the fallback; the chain when one of them
        finishes the run, else the next level. Raises :class:`Stuck` when none helps."""
        # a biarc bridge from a stuck state onto a sample with the polyline's direction
        for st in level if self.use_bridge else []:
            br = bridge(self.band, st, b, loop)
            if br is None:
                continue
            if br.k >= b:
                return unwind(br), []
            return None, [br]
        if loop:
            # close from earlier junctions of the best states
            for st in level:
                node: State | None = st
                while node is not None and node.parent is not None:
                    par = node.parent
                    assert par.t is not None and st.t_first is not None
                    clo = self.band.biarc(par.p, par.t, par.k, par.e, b, st.t_first)
                    if clo is not None:
                        return unwind(par) + clo, []
                    node = par
        if not allow_forced:
            raise Stuck
        # valid by construction: a filleted polyline over a short stretch ahead
        fb = fallback(self.band, level[0], b, loop, self.FALLBACK_SPAN)
        if fb[1] is None:
            return fb[0], []
        return None, [fb[1]]

    def _candidates(self, si: int, st: State, b: int) -> list[Cands]:
        """Candidate pieces from state ``si`` of the level, ``st`` (unverified)."""
        p, t, k = st.p, st.t, st.k
        assert t is not None
        jlimit = b - 1
        if jlimit <= k:
            return []
        lo1, up1 = self._bounds(st, b)
        jm = min(k + len(lo1), jlimit)
        if jm <= k:
            return []
        band = self.band
        if band.kmin > 0.0:
            span = self.cum[jm] - self.cum[k]
            at = np.searchsorted(self.cum, self.cum[k] + self._j_fractions * span,
                                 side="right")
            js = np.unique(np.clip(at - 1, k + 1, jm))[::-1].tolist()
            jj, kk = self._capped_kappas(js, k, lo1, up1)
            # the foot point of sample j on each piece, its end point and end tangent
            u, v = local_uv(p, t, self.samples[jj])
            line = kk == 0.0
            sj = np.where(line, u, np.arctan2(kk * u, 1.0 - kk * v) / np.where(line, 1.0, kk))
            ends, tends = arc_points(p, t, kk, sj), rotate(t, kk * sj)
            bonus = np.where(line, 0.3 * (self.cum[jj] - self.cum[k]), 0.0)
        else:
            jj, kk, ends, tends, bonus = candidates(
                self.samples, self.cum, float(p[0]), float(p[1]), float(t[0]), float(t[1]),
                k, jm, lo1, up1, self._j_fractions, self._k_fractions, band.kcap)
        n = len(jj)
        out = [Cands(np.full(n, si, dtype=np.int64), jj, kk, ends, tends, bonus,
                     np.full(n, np.nan), np.zeros(n, dtype=bool))]
        if self.straight is not None:
            extra = self.straight.candidates(p, t, k, b)
            if extra:
                out.append(Cands.anchored(si, extra))
        return out

    def _level_candidates(
        self, level: list[State], b: int
    ) -> tuple[list[Cands], tuple[FloatArray, FloatArray, NDArray[np.int64]]]:
        """:meth:`_candidates` of all of ``level`` (no radius cap) in one kernel call, the
        pieces onto straight runs after them (the ranking keeps them apart: same order;
        all states' in one part), and the states' points, tangents and samples as
        arrays (for the ranking and the verification of the same level)."""
        sp, stt, sk, sjm, lo_all, up_all, b_off = level_arrays(level, b, self._bounds)
        si, jj, kk, ends, tends, bonus = candidates_level(
            self.samples, self.cum, sp, stt, sk, sjm, lo_all, up_all, b_off,
            self._j_fractions, self._k_fractions, self.band.kcap)
        n = len(jj)
        out = [Cands(si, jj, kk, ends, tends, bonus, np.full(n, np.nan),
                     np.zeros(n, dtype=bool))] if n else []
        if self.straight is not None:
            extra: list[tuple[int, AnchorPiece]] = []
            for i, st in enumerate(level):
                if sjm[i] > st.k:
                    assert st.t is not None
                    extra.extend((i, x) for x in self.straight.candidates(st.p, st.t, st.k, b))
            if extra:
                out.append(Cands.anchored_level(extra))
        return out, (sp, stt, sk)

    def _capped_kappas(
        self, js: list[int], k: int, lo1: FloatArray, up1: FloatArray
    ) -> tuple[NDArray[np.int64], FloatArray]:
        """The ends and curvatures of the candidates from a state at sample ``k`` with a
        radius cap: :meth:`ToleranceBand.candidate_kappas` for each end ``j`` of ``js``
        (running bounds ``lo1, up1``), in that order, as flat arrays (without a cap:
        :func:`zwcore.arcs._kernels.candidates`)."""
        band = self.band
        pairs = [(j, kap) for j in js for kap in band.candidate_kappas(
            float(lo1[j - k - 1]), float(up1[j - k - 1]))]
        return (np.array([q[0] for q in pairs], dtype=np.int64).reshape(-1),
                np.array([q[1] for q in pairs], dtype=np.float64).reshape(-1))

    def _expand(self, level: list[State], b: int) -> list[State]:
        """The next level: the best verified pieces from all states, by look-ahead reach.

        With straight runs to follow, pieces onto them take up to half the beam first,
        then candidates rank by the arcs over straight runs in their chain, and landing
        biarcs (:meth:`StraightRuns.landing_biarc`) join one level later.
        """
        arrays = None
        if self.band.kmin > 0.0:
            parts = [c for si, st in enumerate(level) for c in self._candidates(si, st, b)
                     if len(c)]
        else:
            parts, arrays = self._level_candidates(level, b)
        out: list[State] = self._verified(level, Cands.join(parts), b, arrays) if parts else []
        if self.straight is not None:
            out.extend(self._landings(level, b))
        if not out:
            out = self._shrunk(level, b)
        return out

    def _rank(
        self, level: list[State], c: Cands, b: int, sp_all: FloatArray,
        sk_all: NDArray[np.int64],
    ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """The order in which the candidates ``c`` are verified, and their reach
        (:func:`~zwcore.arcs._ranking.rank_level`; ``sp_all, sk_all``: the states' points
        and samples as arrays)."""
        before = None if self.straight is None else np.array(
            [self._n_over(st) for st in level], dtype=np.int64)
        return rank_level(self.band, c, b, sp_all, sk_all, self.straight, before)

    def _verified(
        self, level: list[State], c: Cands, b: int,
        arrays: tuple[FloatArray, FloatArray, NDArray[np.int64]] | None = None,
    ) -> list[State]:
        """The best verified candidates, in the order of :meth:`_rank`, at most
        :attr:`BEAM` of them (pieces onto straight runs at most half of them), one per
        end state (reach, end sample, end direction)
        (:func:`zwcore.arcs._select.select_verified`). ``arrays``: the states' points,
        tangents and samples as arrays, when built already (:meth:`_level_candidates`).
        """
        band = self.band
        if arrays is None:
            assert all(st.t is not None for st in level)
            arrays = (np.array([st.p for st in level]),
                      np.array([st.t for st in level], dtype=np.float64),
                      np.array([st.k for st in level], dtype=np.int64))
        sp, stt, sk = arrays
        order, reach = self._rank(level, c, b, sp, sk)
        n_special_max = self.BEAM // 2 if self.straight is not None else 0
        got, figs = select_verified(
            self.samples, order, c.si, c.j, c.kappa, c.sig_end, c.special, reach,
            c.t_end, sp, stt, sk,
            np.array([st.e for st in level], dtype=np.float64), self.BEAM, n_special_max,
            band.tol, band.dense_step)
        out: list[State] = []
        for i, (length, ex, ey, e_end) in zip(got.tolist(), figs.tolist(), strict=True):
            st = level[int(c.si[i])]
            j = int(c.j[i])
            assert st.t is not None
            pc = band.make_piece(st.p, st.t, float(c.kappa[i]), st.k, j,
                                 (length, np.array([ex, ey]), e_end))
            if c.special[i]:
                pc.t_end = c.t_end[i].copy()  # exactly the anchor's direction
            out.append(State(pc.end, pc.t_end, j, pc.e_end, st, pc, st.t_first,
                             st.depth + 1))
        return out

    def _landings(self, level: list[State], b: int) -> list[State]:
        """The landing biarcs found one level earlier; this level's are kept for the
        next (a landing biarc is two pieces: its end joins the level after next)."""
        assert self.straight is not None
        out = self._landed
        self._landed = []
        for st in level:
            assert st.t is not None
            got = self.straight.landing_biarc(st.p, st.t, st.k, st.e, b,
                                              len(self._bounds(st, b)[0]))
            if got is not None:
                a1, a2 = got
                mid = State(a1.end, a1.t_end, a1.j, a1.e_end, st, a1, st.t_first,
                            st.depth + 1)
                self._landed.append(State(a2.end, a2.t_end, a2.j, a2.e_end, mid, a2,
                                          st.t_first, st.depth + 2))
        return out

    def _shrunk(self, level: list[State], b: int) -> list[State]:
        """The first state's shorter piece (:meth:`_shrink`) when no candidate passed."""
        for st in level:
            assert st.t is not None
            lo1, up1 = self._bounds(st, b)
            jm = min(st.k + len(lo1), b - 1)
            if jm <= st.k:
                continue
            sh = self._shrink(st.p, st.t, st.k, st.e, jm, lo1, up1)
            if sh is not None:
                return [State(sh.end, sh.t_end, sh.j, sh.e_end, st, sh, st.t_first,
                              st.depth + 1)]
        return []

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

    def _bounds(self, st: State, b: int) -> tuple[FloatArray, FloatArray]:
        """The running curvature bounds of the longest piece from ``st`` (asked for by
        the candidates, the closing biarc and the landing biarc: computed once)."""
        if st.bounds is None:
            assert st.t is not None
            st.bounds = self.band.longest_piece_bounds(st.p, st.t, st.k, b)
        return st.bounds

    def _n_over(self, st: State) -> int:
        """Arcs over straight runs in the chain ending at ``st``
        (:meth:`StraightRuns.is_over`), carried along the states: each piece is looked at
        once, not once per candidate."""
        sr = self.straight
        assert sr is not None
        todo: list[State] = []
        node: State | None = st
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

    # -- closing a loop ----------------------------------------------------------

    def _try_close(self, st: State, b: int, t1: FloatArray) -> list[Piece] | None:
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
