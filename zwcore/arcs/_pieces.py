"""Single pieces of a C1 arc chain against the tolerance band of a sample polyline.

A piece starts at a junction with a known point ``P`` and tangent ``T`` and is
described by one number, its signed curvature ``kappa`` (0 is a line). For a
fixed ``(P, T)`` the signed distance of a sample to the circle is monotone in
``kappa``, so each sample admits an interval of curvatures and the pieces that
cover samples ``k+1..j`` form the running intersection of those intervals (one
vectorised ``cummax``/``cummin`` gives the longest piece).

:class:`ToleranceBand` answers the questions about one piece (or one biarc)
that the search in :mod:`zwcore.arcs._search` asks: how far pieces from given
junctions reach, which curvatures are feasible, and whether a piece stays within
the tolerance both ways (:meth:`~ToleranceBand.verify`: conservative analytic
bounds, samples to arc, polyline segments to arc, arc portions to polyline).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from zwcore.arcs import _biarc, _kernels
from zwcore.arcs._geometry import rotate1

FloatArray = NDArray[np.float64]

__all__ = ["Piece", "ToleranceBand", "merge_lines"]


@dataclass
class Piece:
    """One verified arc or line of a chain, in the samples' local frame.

    Start point ``p`` and unit tangent ``t``, signed curvature ``kappa`` (``> 0``
    turns left, 0 is a line), arc ``length``; it stands for samples ``k..j``, ends
    at ``end`` with unit tangent ``t_end``, and ``e_end`` is the distance of sample
    ``j`` from the piece (the next piece's start stands for that sample).
    """

    p: FloatArray
    t: FloatArray
    kappa: float
    length: float
    k: int
    j: int
    end: FloatArray
    t_end: FloatArray
    e_end: float


class ToleranceBand:
    """The band of half-width ``tol`` about a sample polyline, seen by single pieces.

    Parameters
    ----------
    samples : ndarray, shape (M, 2)
        The sample polyline (local frame).
    tol : float
        Tolerance every verified piece keeps, both ways.
    work : float
        Share of ``tol`` the feasibility scans use (room for conservative bounds).
    max_radius : float or None
        Largest arc radius allowed (larger ones must be lines); None: no limit.
    cum : ndarray, shape (M,), optional
        The cumulative polyline length at each sample, when known.
    """

    def __init__(
        self, samples: FloatArray, tol: float, work: float, max_radius: float | None,
        cum: FloatArray | None = None,
    ) -> None:
        self.samples = samples
        self.tol = tol
        #: working half-width of the feasibility scans
        self.work_tol = work * tol
        #: smallest curvature of an arc (0: any radius)
        self.kmin = 0.0 if max_radius is None else 1.0 / max_radius
        #: curvature cap: radius >= tol / 200 (tighter arcs are within tol of their centre)
        self.kcap = 200.0 / tol
        #: cumulative polyline length at each sample (given: another band's, of the same
        #: samples)
        self.cum = cum if cum is not None else np.concatenate(
            [[0.0], np.cumsum(np.hypot(*(np.diff(samples, axis=0).T)))])
        #: arc-length step of the dense checks
        self.dense_step = 0.1 * tol
        n_seg = max(len(samples) - 1, 1)
        spacing = float(self.cum[-1]) / n_seg
        #: sample stride of the look-ahead scans (about a quarter tolerance)
        self.reach_stride = max(1, int(0.25 * tol / spacing)) if spacing > 0 else 1
        #: the biarc splits tried, as arrays for the kernel
        self._splits: dict[tuple[float, ...], FloatArray] = {}

    # -- feasibility scans -------------------------------------------------

    def reach(self, ps: FloatArray, ts: FloatArray, k: int, b: int) -> NDArray[np.int64]:
        """Last sample index each junction ``(C,)`` at sample ``k`` covers with one piece.

        Interval test only (no verification), every sample scanned.
        """
        ks = np.full(len(ps), k, dtype=np.int64)
        return _kernels.reach_lines(self.samples, np.ascontiguousarray(ps),
                                    np.ascontiguousarray(ts), ks, b, 1, self.work_tol)[0]

    def reach_with_lines(
        self, ps: FloatArray, ts: FloatArray, ks: NDArray[np.int64], b: int
    ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """Last sample each junction ``(C,)`` covers with one piece, and with one line.

        Junction ``c`` starts at ``ps[c]`` with tangent ``ts[c]`` standing for sample
        ``ks[c]``. The figures only rank candidates (every piece is verified on all
        samples), so densely sampled curves are scanned at :attr:`reach_stride`: the
        work no longer grows with the sampling density. Each junction scans the samples
        of the grid ``k0+1, k0+1+stride, ...`` (``k0 = ks.min()``) after its own sample
        and stops where its curvature interval empties; a line is reported while the
        arc scan still runs (beyond, a line never reaches further than the arcs: a line
        is one of the circles).
        """
        return _kernels.reach_lines(self.samples, np.ascontiguousarray(ps),
                                    np.ascontiguousarray(ts), np.asarray(ks, dtype=np.int64),
                                    b, self.reach_stride, self.work_tol)

    def line_reach(self, p: FloatArray, ths: FloatArray, k: int, b: int) -> tuple[int, float]:
        """Longest straight piece from ``p`` (at sample ``k``) over directions ``ths``.

        Returns the last sample index it covers and its direction (radians, the
        middle of the best range of ``ths``).
        """
        ts = np.stack([np.cos(ths), np.sin(ths)], axis=1)
        r = _kernels.line_reaches(self.samples, float(p[0]), float(p[1]), ts, k, b,
                                  self.work_tol)
        top = np.flatnonzero(r == r.max())
        mid = int(top[len(top) // 2])
        return int(r[mid]), float(ths[mid])

    def longest_piece_bounds(
        self, p: FloatArray, t: FloatArray, k: int, b: int
    ) -> tuple[FloatArray, FloatArray]:
        """Running curvature bounds of the longest feasible piece from ``(p, t)``.

        Scans samples ``k+1..b`` and cuts the bounds where they become empty:
        ``len(lo)`` samples after ``k`` are reachable.
        """
        return _kernels.piece_bounds(self.samples, float(p[0]), float(p[1]), float(t[0]),
                                     float(t[1]), k, b, self.work_tol)

    # -- candidate curvatures ----------------------------------------------

    #: where in a feasible curvature interval candidates are taken (0 = low end)
    K_FRACTIONS = (0.5, 0.25, 0.75, 0.08, 0.92)

    def candidate_kappas(self, lo: float, hi: float) -> list[float]:
        """A few curvatures inside ``[lo, hi]`` (a line first when allowed), radius-capped."""
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

    def radius_ok(self, kappa: float) -> bool:
        """True for a line or an arc whose radius is within the allowed range."""
        return kappa == 0.0 or (abs(kappa) >= self.kmin and abs(kappa) <= self.kcap)

    # -- verification ------------------------------------------------------

    def verify(
        self, p: FloatArray, t: FloatArray, kappa: float, k: int, j: int, e_k: float,
        sig_end: float | None = None, dense_first: bool = False,
    ) -> tuple[float, FloatArray, float] | None:
        """Verify the piece ``(p, t, kappa)`` covering samples ``k..j`` two-sided.

        ``e_k`` is the distance of sample ``k`` from ``p`` (the piece's start stands
        for it). Without ``sig_end`` (the arc length) the piece ends at the foot
        point of sample ``j``. ``dense_first`` checks the first arc portion densely
        instead of bounding it (a biarc's second arc, whose start is off sample ``k``).

        Returns ``(length, end, e_end)``, or None when a bound exceeds ``tol``. All
        bounds are conservative: a piece that passes is within ``tol`` of the
        polyline both ways over its extent. The bounds: every sample to the piece,
        the interiors of the polyline segments to the arc (the farthest point of a
        segment from a circle is an end or the point nearest the centre), and the
        arc's portions between consecutive foot points to the polyline (the larger
        end distance plus the portion's sagitta plus the jitter of the foot points);
        the part of the arc past the last foot point, and with ``dense_first`` the
        first portion, are measured densely at :attr:`dense_step`
        (:func:`zwcore.arcs._kernels.verify_piece`).
        """
        ok, length, ex, ey, e_end = _kernels.verify_piece(
            self.samples, float(p[0]), float(p[1]), float(t[0]), float(t[1]), float(kappa),
            k, j, float(e_k), 0.0 if sig_end is None else float(sig_end),
            sig_end is not None, dense_first, self.tol, self.dense_step)
        if not ok:
            return None
        return length, np.array([ex, ey]), e_end

    def make_piece(
        self, p: FloatArray, t: FloatArray, kappa: float, k: int, j: int,
        verified: tuple[float, FloatArray, float],
    ) -> Piece:
        """The :class:`Piece` of a passed :meth:`verify` (its ``(length, end, e_end)``)."""
        length, end, e_end = verified
        return Piece(p, t, kappa, length, k, j, end, rotate1(t, kappa * length), e_end)

    # -- pieces with a fixed end -------------------------------------------

    def piece_to_sample(
        self, p: FloatArray, t: FloatArray, k: int, e: float, b: int
    ) -> Piece | None:
        """The verified piece from ``(p, t)`` (sample ``k``, distance ``e``) to sample ``b``."""
        # (local_uv's arithmetic for one point, on floats)
        ex = float(self.samples[b, 0]) - float(p[0])
        ey = float(self.samples[b, 1]) - float(p[1])
        tx, ty = float(t[0]), float(t[1])
        u = ex * tx + ey * ty
        v = ey * tx - ex * ty
        q2 = u**2 + v**2
        if q2 <= 0.0:
            return None
        kap = 2.0 * v / q2
        if abs(kap) * math.sqrt(q2) < 1e-13:
            kap = 0.0
        if not self.radius_ok(kap):
            return None
        # cheap interval test first: every sample's curvature interval holds kap (most
        # states are far from b and fail within the first few samples)
        if not _kernels.kappa_fits(self.samples, float(p[0]), float(p[1]), tx, ty, k, b,
                                   self.work_tol, kap, 1e-12 * abs(kap)):
            return None
        res = self.verify(p, t, kap, k, b, e)
        if res is None:
            return None
        piece = self.make_piece(p, t, kap, k, b, res)
        piece.end = self.samples[b].copy()
        return piece

    #: where between start and end the biarc's junction is tried (share of the chord)
    BIARC_SPLITS = (0.5, 0.4, 0.6, 0.3, 0.7, 0.2, 0.8, 0.12, 0.9, 0.06, 0.94)

    def biarc(
        self, p0: FloatArray, t0: FloatArray, k: int, e: float, b: int, t1: FloatArray,
        p1: FloatArray | None = None, splits: tuple[float, ...] = BIARC_SPLITS,
    ) -> list[Piece] | None:
        """Two verified pieces from ``(p0, t0)`` to sample ``b`` arriving with tangent ``t1``.

        ``p0`` stands for sample ``k`` at distance ``e``. The pair ends at ``p1`` when
        given (it then stands for sample ``b``: the second piece's ``e_end`` is their
        distance), else at sample ``b``. The junction is tried at several places
        (``splits``: lengths of the first tangent leg as shares of the chord, by default
        :attr:`BIARC_SPLITS`); the first verified pair is returned. The first arc stands
        for the samples whose foot points lie on it (up to sample ``m``); the second
        starts at the junction, which stands for sample ``m`` at its distance, and its
        first portion is checked densely (:func:`zwcore.arcs._biarc.biarc`).
        """
        at_sample = p1 is None
        p1 = self.samples[b] if p1 is None else p1
        got, f, m = _biarc.biarc(
            self.samples, np.asarray(p0, dtype=np.float64), np.asarray(t0, dtype=np.float64),
            k, float(e), b, np.asarray(t1, dtype=np.float64),
            np.asarray(p1, dtype=np.float64), self.splits_array(splits), self.tol,
            self.dense_step, self.kmin, self.kcap)
        if got < 0:
            return None
        return self.biarc_pieces(p0, t0, k, b, t1, p1, at_sample, f, m)

    def splits_array(self, splits: tuple[float, ...]) -> FloatArray:
        """The biarc splits ``splits`` as an array for the kernel (built once)."""
        key = splits if splits is self.BIARC_SPLITS else tuple(splits)
        arr = self._splits.get(key)
        if arr is None:
            arr = self._splits[key] = np.array(key, dtype=np.float64)
        return arr

    def biarc_pieces(
        self, p0: FloatArray, t0: FloatArray, k: int, b: int, t1: FloatArray, p1: FloatArray,
        at_sample: bool, f: FloatArray, m: int,
    ) -> list[Piece]:
        """The two pieces of a biarc the kernel found (its figures ``f`` ``(10,)`` and the
        first arc's last sample ``m``; see :meth:`biarc`)."""
        k1, s1, jx, jy, tjx, tjy, e1, k2, s2, e2 = f.tolist()
        jn = np.array([jx, jy])
        tj = np.array([tjx, tjy])
        a1 = Piece(p0, t0, k1, s1, k, m, jn, tj, e1)
        a2 = Piece(jn, tj, k2, s2, m, b, p1.copy(), t1.copy(), e2)
        if not at_sample:
            a2.e_end = float(np.hypot(*(self.samples[b] - p1)))
        return [a1, a2]


def merge_lines(pieces: list[Piece]) -> list[Piece]:
    """``pieces`` with consecutive lines merged (at a C1 junction two lines are collinear:
    their union is one line covering the same samples)."""
    out: list[Piece] = []
    for pc in pieces:
        prev = out[-1] if out else None
        if prev is not None and prev.kappa == 0.0 and pc.kappa == 0.0:
            out[-1] = Piece(prev.p, prev.t, 0.0, prev.length + pc.length, prev.k, pc.j,
                            pc.end, prev.t.copy(), pc.e_end)
        else:
            out.append(pc)
    return out
