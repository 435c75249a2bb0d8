"""The anchors of a refit (straight runs to follow with lines) as the beam of
:mod:`zwcore.arcs._search` sees them: pieces landing on them, landing biarcs, and which
arcs lie over them."""

from __future__ import annotations

import bisect
import itertools
import math

import numpy as np
from numpy.typing import NDArray

from zwcore.arcs import _kernels
from zwcore.arcs._anchor_kernels import anchors_hit, landing_pair, min_segment_distance
from zwcore.arcs._geometry import (
    arc_point,
    sagitta,
)
from zwcore.arcs._pieces import Piece, ToleranceBand
from zwcore.arcs._straight import FLAT_MIN_LEN, FLAT_SAGITTA, Anchor, is_flat

FloatArray = NDArray[np.float64]

__all__ = ["AnchorPiece", "StraightRuns"]


#: a candidate piece onto an anchor: last sample, curvature, end point, end tangent,
#: length
AnchorPiece = tuple[int, float, FloatArray, FloatArray, float]


class StraightRuns:
    """The anchors of one run (straight runs to follow with lines), for the beam.

    Parameters
    ----------
    band : ToleranceBand
        The band the run is fitted in (its samples, tolerance and verification).
    anchors : list of Anchor
        The straight runs, in order along the run.
    """

    #: where a landing biarc meets the next anchor's line: arc length past the
    #: anchor's first sample, in tolerances
    LANDING_OFFSETS = (0.0, 5.0, 10.0, 20.0, 40.0)
    #: a landing biarc is tried when the anchor starts within this many single-piece
    #: reaches of the state (a biarc spans about two pieces' worth)
    LANDING_SPAN = 2.2
    #: first tangent legs of a landing biarc (shares of its chord): besides the usual
    #: ones, the long legs of a landing that turns by much (a fillet of 150 degrees has a
    #: leg of 1.7 chords)
    LANDING_SPLITS = (*ToleranceBand.BIARC_SPLITS, 1.0, 1.15, 1.35, 1.6, 2.0, 2.6, 3.5)

    def __init__(self, band: ToleranceBand, anchors: list[Anchor]) -> None:
        self.band = band
        self.anchors = anchors
        self.samples = band.samples
        self.cum = band.cum
        self.tol = band.tol
        # anchors in order along the run (last samples increasing, first samples not
        # decreasing): :meth:`is_over` looks only at those overlapping the piece
        self._i1 = [an.i1 for an in anchors]
        self._ordered = all(
            a1.i1 > a0.i1 and a1.i0 >= a0.i0 for a0, a1 in itertools.pairwise(anchors))
        # per anchor, asked per state and level: its direction as floats (the products
        # of numpy's scalars, the same figures) and its normal (the array the closed
        # forms dot with); the anchors as arrays for :func:`anchors_hit`
        self._dxy = [(float(an.d[0]), float(an.d[1])) for an in anchors]
        self._nrm = [np.array([-an.d[1], an.d[0]]) for an in anchors]
        self._i0s = np.array([an.i0 for an in anchors], dtype=np.int64)
        self._i1s = np.array(self._i1, dtype=np.int64)
        self._qs = np.array([an.q for an in anchors], dtype=np.float64).reshape(-1, 2)
        #: the landing offsets, as an array (:meth:`landing_biarc`)
        self._offsets = np.array(self.LANDING_OFFSETS, dtype=np.float64)

    def on_line(self, p: FloatArray, t: FloatArray, an: Anchor) -> bool:
        """True when the junction ``(p, t)`` lies on the anchor's line, along it."""
        return (abs(float(t[0] * an.d[1] - t[1] * an.d[0])) <= 1e-12
                and float(t @ an.d) > 0.0
                and abs(float((p - an.q) @ np.array([-an.d[1], an.d[0]])))
                <= 1e-9 * self.tol + 1e-13 * float(np.abs(p).max()))

    def _on(self, p: FloatArray, t: FloatArray, tx: float, ty: float, i: int) -> bool:
        """:meth:`on_line` of anchor ``i`` (``tx, ty``: ``t`` as floats): the cheap
        cross product first, the two dot products (numpy's) only where it passes."""
        dx, dy = self._dxy[i]
        if not abs(tx * dy - ty * dx) <= 1e-12:
            return False
        an = self.anchors[i]
        return (float(t @ an.d) > 0.0
                and abs(float((p - an.q) @ self._nrm[i]))
                <= 1e-9 * self.tol + 1e-13 * max(abs(float(p[0])), abs(float(p[1]))))

    def start_direction(self, a: int, p0: FloatArray) -> FloatArray | None:
        """The line's direction when a straight run starts the run at ``p0`` (sample ``a``)."""
        for an in self.anchors:
            if an.i0 == a and np.array_equal(an.q, p0):
                return an.d.copy()
        return None

    def is_over(self, k: int, j: int, kappa: float, length: float) -> bool:
        """True for an arc over samples ``k..j`` that is flat, covers more than half of an
        anchor (a straight run the chain should follow with a line), or lies on an
        anchor that starts or ends the run at that end (the chain starts or ends there on
        the anchor's line)."""
        if kappa == 0.0:
            return False
        if is_flat(kappa, length, self.tol):
            return True
        # an anchor ending before k or starting after j has no share of k..j (and does
        # not hold it): with ordered anchors only those from the first ending at or after
        # k up to the last starting at or before j are looked at
        first = bisect.bisect_left(self._i1, k) if self._ordered else 0
        for an in self.anchors[first:]:
            if self._ordered and an.i0 > j:
                break
            over = self.cum[min(j, an.i1)] - self.cum[max(k, an.i0)]
            if over > 0.5 * (self.cum[an.i1] - self.cum[an.i0]):
                return True
            if an.i0 <= k and j <= an.i1 and (
                    (j == an.i1 and _same(an.q, self.samples[j]))
                    or (k == an.i0 and _same(an.q, self.samples[k]))):
                return True
        return False

    def are_over(self, k: NDArray[np.int64], j: NDArray[np.int64], kappa: FloatArray,
                 length: FloatArray) -> NDArray[np.bool_]:
        """:meth:`is_over` of many pieces at once (arrays ``(C,)``)."""
        tol = self.tol
        arc = kappa != 0.0
        flat = (length >= FLAT_MIN_LEN * tol) & (sagitta(kappa, length) < FLAT_SAGITTA * tol)
        hit = anchors_hit(self.cum, self.samples, np.asarray(k, dtype=np.int64),
                          np.asarray(j, dtype=np.int64), self._i0s, self._i1s, self._qs)
        return arc & (flat | hit)

    def candidates(self, p: FloatArray, t: FloatArray, k: int, b: int) -> list[AnchorPiece]:
        """Pieces from the junction ``(p, t)`` (sample ``k``) onto the next anchor's line.

        From any junction: the arc that lands tangentially on the next anchor's line
        (its curvature follows from the junction and the line in closed form). From a
        junction on an anchor's line: the line up to the tangent point of the fillet onto
        the next anchor (radius from the input's distance to the lines' intersection),
        from where the landing arc is that fillet. Unverified; each ends exactly along
        the line it lands on.
        """
        here: Anchor | None = None
        nxt: Anchor | None = None
        ih = inx = -1
        tx, ty = float(t[0]), float(t[1])
        for i, an in enumerate(self.anchors):
            if an.i1 <= k:
                continue
            if an.i0 <= k + 1 and self._on(p, t, tx, ty, i):
                here, ih = an, i
                continue
            nxt, inx = an, i
            break
        if nxt is None:
            return []
        out: list[AnchorPiece] = []
        d = nxt.d
        dx, dy = self._dxy[inx]
        delta = math.atan2(tx * dy - ty * dx, float(t @ d))
        if 1e-9 < abs(delta) < math.pi - 1e-3:
            # landing arc: nd . (p + (sin D t + (1 - cos D) n) / kappa - q) = 0
            nd = self._nrm[inx]
            n = np.array([-t[1], t[0]])
            h0 = float(nd @ (p - nxt.q))
            w = float(nd @ (math.sin(delta) * t + (1.0 - math.cos(delta)) * n))
            if h0 != 0.0:
                kap = -w / h0
                if kap * delta > 0.0 and self.band.radius_ok(kap):
                    s_end = delta / kap
                    j = self._last_before(p, t, kap, k, min(nxt.i1, b - 1), s_end)
                    if j > k:
                        end = arc_point(p, t, kap, s_end)
                        out.append((j, kap, end, d.copy(), s_end))
        if here is not None:
            # the fillet between this line and the next one
            fil = self._fillet(ih, inx, k, min(nxt.i1, b))
            if fil is not None:
                vtx, m, half, den = fil
                dh = here.d
                along = float(dh @ (vtx - p))
                tan_half = math.tan(half)
                for f in (1.0, 0.97, 1.03):
                    rad = f * m / den if den > 0.0 else 0.0
                    s_line = along - rad * tan_half
                    if not s_line > 0.0 or rad <= 0.0:
                        continue
                    j = self._last_before(p, dh, 0.0, k, min(nxt.i1, b - 1), s_line)
                    if j > k:
                        out.append((j, 0.0, p + s_line * dh, dh.copy(), s_line))
        return out

    def _fillet(self, ih: int, inx: int, k: int,
                hi: int) -> tuple[FloatArray, float, float, float] | None:
        """The fillet from anchor ``ih``'s line onto anchor ``inx``'s, for a junction at
        sample ``k``: the lines' intersection, the input's distance to it (polyline
        segments ``k..hi-1``, compiled: :func:`min_segment_distance`), half the turn and
        ``1 / cos(half) - 1``; None where the lines are (nearly) parallel or opposed."""
        here, nxt = self.anchors[ih], self.anchors[inx]
        dh, d = here.d, nxt.d
        cr = float(dh[0] * d[1] - dh[1] * d[0])
        turn = math.atan2(cr, float(dh @ d))
        if not 1e-6 < abs(turn) < math.pi - 1e-3:
            return None
        # intersection V = q_here + a dh = q_next + c d
        rhs = nxt.q - here.q
        alpha = float(rhs[0] * d[1] - rhs[1] * d[0]) / cr
        vtx = here.q + alpha * dh
        m = min_segment_distance(self.samples, float(vtx[0]), float(vtx[1]), k, hi)
        half = 0.5 * abs(turn)
        return vtx, m, half, 1.0 / math.cos(half) - 1.0

    def landing_biarc(
        self, p: FloatArray, t: FloatArray, k: int, e: float, b: int,
        n_reach: int | None = None,
    ) -> list[Piece] | None:
        """Two verified arcs from ``(p, t)`` landing tangentially on the next anchor's line.

        For a junction (sample ``k``, distance ``e``) before the next anchor's first
        sample, where the single landing arc of :meth:`candidates` does not fit (the
        tangent it arrives with is off the fillet's). The arcs end on the line at the
        foot of one of a few samples of the anchor (:attr:`LANDING_OFFSETS`), along it;
        arcs of radius below the tolerance (knots, not landings) are refused.
        ``n_reach``: the number of samples the longest piece from ``(p, t)`` covers,
        when known (:meth:`~zwcore.arcs._pieces.ToleranceBand.longest_piece_bounds`).
        """
        band = self.band
        nxt = None
        tx, ty = float(t[0]), float(t[1])
        for i, an in enumerate(self.anchors):
            if an.i1 > k + 1 and not self._on(p, t, tx, ty, i):
                nxt = an
                break
        if nxt is None or k >= nxt.i0:
            return None
        if n_reach is None:
            n_reach = len(band.longest_piece_bounds(p, t, k, b)[0])
        reach = self.cum[min(k + n_reach, b)] - self.cum[k]
        first = max(nxt.i0, k + 2)
        # the landing point stands for a sample; at the run's end only for the end sample
        # itself (a line pinned through it)
        last = min(nxt.i1, b if _same(nxt.q, self.samples[b]) else b - 1)
        if first > last or (
                self.cum[first] - self.cum[k] > self.LANDING_SPAN * max(reach, 1e-300)):
            return None
        ms: list[int] = []
        at = self.cum.searchsorted(self.cum[first] + self._offsets * self.tol, side="right")
        for m in at.tolist():
            m = min(max(m - 1, first), last)
            if m not in ms:
                ms.append(m)
        # the landing points (feet of the samples on the line), tried in one kernel call
        p1s = np.array([nxt.q + float((self.samples[m] - nxt.q) @ nxt.d) * nxt.d for m in ms])
        i, f, m1 = landing_pair(
            self.samples, np.asarray(p, dtype=np.float64), np.asarray(t, dtype=np.float64), k,
            float(e), np.array(ms, dtype=np.int64), p1s, nxt.d,
            band.splits_array(self.LANDING_SPLITS), self.tol, band.dense_step, band.kmin,
            band.kcap)
        if i < 0:
            return None
        got = band.biarc_pieces(p, t, k, ms[i], nxt.d, p1s[i], False, f, m1)
        got[1].t_end = nxt.d.copy()  # exactly the anchor's direction
        return got

    def _last_before(
        self, p: FloatArray, t: FloatArray, kap: float, k: int, hi: int, s_end: float
    ) -> int:
        """Last sample in ``k..hi`` whose foot point on the piece lies before ``s_end``."""
        if hi <= k:
            return k
        return _kernels.last_before(self.samples, float(p[0]), float(p[1]), float(t[0]),
                                    float(t[1]), float(kap), k, hi, float(s_end))


def _same(q: FloatArray, x: FloatArray) -> bool:
    """``numpy.array_equal`` of two points ``(2,)``, without its overhead."""
    return bool(q[0] == x[0] and q[1] == x[1])
