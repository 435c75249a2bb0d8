"""Straight runs of the input, and how the C1 chain is made to follow them with lines.

The beam (:mod:`zwcore.arcs._search`) ranks pieces by how far the chain reaches; over a
straight run of the input it may lay an arc of huge radius where the tangent entering
the run missed it. Such arcs are found in a fitted run (:func:`arcs_over_straight`:
*flat* arcs, :func:`is_flat`, and arcs over a long :func:`straight_run`), and the run is
refitted with those straight runs as :class:`Anchor` lines
(:func:`refit_along_straight_runs`). During the refit :class:`StraightRuns` answers the
beam's questions about the anchors:

- candidate pieces onto the next anchor: the arc landing tangentially on its line
  (closed form) and, from a state on an anchor's line, the line to the tangent point of
  the fillet onto the next one (:meth:`StraightRuns.candidates`);
- where one landing arc does not fit, a biarc landing tangentially on the line
  (:meth:`StraightRuns.landing_biarc`);
- which arcs lie over a straight run (:meth:`StraightRuns.is_over`), so that chains
  with fewer of them rank first and finish first.

A refit's end may need extra short pieces (its junctions differ a little from the plain
fit's): pinned ends are also redone from the last few junctions (:func:`_landings`).
"""

from __future__ import annotations

import bisect
import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from zwcore.arcs._geometry import (
    arc_point,
    line_fit,
    local_uv,
    points_to_segments_distance,
    sagitta1,
    unwrap,
)
from zwcore.arcs._pieces import Piece, ToleranceBand, merge_lines
from zwcore.arcs._start import shorter_ends

FloatArray = NDArray[np.float64]

__all__ = [
    "FLAT_MIN_LEN",
    "STRAIGHT_MIN_LEN",
    "Anchor",
    "StraightRuns",
    "anchors_of",
    "arcs_over_straight",
    "is_flat",
    "refit_along_straight_runs",
    "straight_run",
]

# ---------------------------------------------------------------------------
# flat arcs and the straight runs under them (line anchors)

#: an arc at least :data:`FLAT_MIN_LEN` tolerances long whose sagitta is below this
#: share of the tolerance is *flat*: its chord, a line, is within a quarter tolerance of
#: it, so the input there is a straight run the chain should follow with a line
FLAT_SAGITTA = 0.25
FLAT_MIN_LEN = 20.0
#: a straight run keeps all its samples within this share of ``tol`` of one line
#: (the rest of the band is left for the pieces joining it) ...
STRAIGHT_BAND = 0.5
#: ... over at least this many tolerances (15 mm at 0.1 mm): a circle stays that
#: straight only above a radius of ``L^2 / (16 * 0.5 tol)`` = 2800 tolerances, and a
#: sine's inflection (amplitude 10, wavelength 50: 12 mm) is not a straight run
STRAIGHT_MIN_LEN = 150.0
#: a straight run at the start or end of a fitted run is followed by the line through
#: that end sample (the chain passes through it), which carries the sample's noise:
#: that line keeps the run's samples within this share of ``tol``
PINNED_BAND = 0.75


def is_flat(kappa: float, length: float, tol: float) -> bool:
    """True for an arc of ``length`` >= :data:`FLAT_MIN_LEN` tolerances whose sagitta is
    below :data:`FLAT_SAGITTA` tolerances (a line where the tangent missed the run)."""
    return (
        kappa != 0.0
        and length >= FLAT_MIN_LEN * tol
        and sagitta1(kappa, length) < FLAT_SAGITTA * tol
    )


@dataclass
class Anchor:
    """A straight run of the samples: ``i0..i1`` lie within :data:`STRAIGHT_BAND`
    tolerances of the line through ``q`` with unit direction ``d`` (along the travel)."""

    i0: int
    i1: int
    q: FloatArray
    d: FloatArray


def straight_run(
    samples: FloatArray, k: int, j: int, a: int, b: int, tol: float, pin_start: bool,
    pin_end: bool,
) -> Anchor | None:
    """The maximal straight run (within ``a..b``) grown from samples ``k..j`` (or from
    their first, last or middle half), or None when none of these is straight (see
    :data:`STRAIGHT_BAND`).

    Grown both ways by galloping and bisection. ``pin_start``/``pin_end``: a run that
    reaches sample ``a``/``b`` gets the line through that sample (the chain must
    start/end exactly there, on the line), if that line still keeps the band.
    """
    band = STRAIGHT_BAND * tol

    def straight(i0: int, i1: int) -> bool:
        return i1 - i0 < 2 or line_fit(samples[i0 : i1 + 1])[2] <= band

    # the whole span, else its end parts or its middle half
    q4 = (j - k) // 4
    for kk, jj in ((k, j), (k + 2 * q4, j), (k, j - 2 * q4), (k + q4, j - q4)):
        if jj - kk >= 2 and straight(kk, jj):
            k, j = kk, jj
            break
    else:
        return None

    def grow(fixed: int, moving: int, limit: int, sgn: int) -> int:
        good, step = moving, max(1, abs(moving - fixed) // 4)
        while good != limit:
            cand = good + sgn * step
            cand = min(cand, limit) if sgn > 0 else max(cand, limit)
            ok = straight(fixed, cand) if sgn > 0 else straight(cand, fixed)
            if ok:
                good = cand
                step *= 2
                continue
            lo, hi = good, cand  # lo straight, hi not
            while abs(hi - lo) > 1:
                mid = (lo + hi) // 2
                if (straight(fixed, mid) if sgn > 0 else straight(mid, fixed)):
                    lo = mid
                else:
                    hi = mid
            return lo
        return good

    i1 = grow(k, j, b, 1)
    i0 = grow(i1, k, a, -1)
    q, d, _ = line_fit(samples[i0 : i1 + 1])
    for pin, flag in ((a, pin_start and i0 == a), (b, pin_end and i1 == b)):
        if not flag:
            continue

        def pinned(m: int, pin: int = pin) -> bool:
            lo, hi = (pin, m) if pin == a else (m, pin)
            return hi - lo < 2 or (
                line_fit(samples[lo : hi + 1], samples[pin])[2] <= PINNED_BAND * tol)

        # the longest part of the run from the pinned end that a line through it keeps
        far = i1 if pin == a else i0
        if not pinned(far):
            good, bad = pin, far
            while abs(bad - good) > 1:
                mid = (good + bad) // 2
                if pinned(mid):
                    good = mid
                else:
                    bad = mid
            far = good
        if abs(far - pin) >= 2:
            lo, hi = (pin, far) if pin == a else (far, pin)
            i0, i1 = lo, hi
            q = samples[pin].copy()
            d = line_fit(samples[lo : hi + 1], q)[1]
            break
    return Anchor(i0, i1, q, d)


# ---------------------------------------------------------------------------
# finding the arcs over straight runs in a fitted run, and refitting it


def arcs_over_straight(
    pieces: Sequence[Piece], samples: FloatArray, a: int, b: int, tol: float, *,
    pin_start: bool, pin_end: bool,
) -> dict[int, Anchor]:
    """The arcs of a run's chain that lie over a straight run of the input, with it.

    An arc is over a straight run when it is flat (:func:`is_flat`) or when its samples
    (or their first, last or middle half) lie within the straight band of a line that
    grows to a run of at least :data:`STRAIGHT_MIN_LEN` tolerances, more than half of
    which the arc covers (a fillet whose end lies in the run's band lands on it).
    """
    out: dict[int, Anchor] = {}
    cum_len = None
    for i, pc in enumerate(pieces):
        if pc.kappa == 0.0 or pc.length < FLAT_MIN_LEN * tol:
            continue
        an = straight_run(samples, pc.k, pc.j, a, b, tol, pin_start, pin_end)
        if an is None:
            continue
        if cum_len is None:
            cum_len = np.concatenate(
                [[0.0], np.cumsum(np.hypot(*(np.diff(samples, axis=0).T)))])
        run_len = cum_len[an.i1] - cum_len[an.i0]
        covered = cum_len[min(pc.j, an.i1)] - cum_len[max(pc.k, an.i0)]
        if is_flat(pc.kappa, pc.length, tol) or (
                run_len >= STRAIGHT_MIN_LEN * tol and covered > 0.5 * run_len):
            out[i] = an
    return out


def anchors_of(
    pieces: Sequence[Piece], bad: dict[int, Anchor], samples: FloatArray, a: int, b: int,
    tol: float, *, pin_start: bool, pin_end: bool, own_lines: bool = False,
) -> list[Anchor]:
    """Anchors of a refit: the straight runs under the arcs ``bad`` and the long lines
    (``own_lines``: a long line away from the run's ends on its own line, so the refit
    can keep the pieces joining it; else on the run's least-squares line)."""
    out: list[Anchor] = []
    for i, pc in enumerate(pieces):
        if out and pc.j <= out[-1].i1:
            continue
        an: Anchor | None = None
        if i in bad:
            an = bad[i]
        elif pc.kappa == 0.0 and pc.length >= FLAT_MIN_LEN * tol:
            an = straight_run(samples, pc.k, pc.j, a, b, tol, pin_start, pin_end)
            if own_lines and an is not None and not (
                    np.array_equal(an.q, samples[a]) or np.array_equal(an.q, samples[b])):
                an = Anchor(an.i0, an.i1, pc.p.copy(), pc.t.copy())
        if an is None:
            continue
        if out and an.i1 <= out[-1].i1:
            continue
        if out and out[-1].i1 - an.i0 > 0.5 * min(out[-1].i1 - out[-1].i0, an.i1 - an.i0):
            # mostly the same run, grown from different pieces: the longer one
            if an.i1 - an.i0 > out[-1].i1 - out[-1].i0:
                out[-1] = an
            continue
        # (runs may overlap a little where a short fillet joins them: both bands hold it)
        out.append(an)
    return out


FitResult = tuple[list[Piece], list[int]]


def refit_along_straight_runs(
    fit: Callable[[list[Anchor]], FitResult], samples: FloatArray, a: int, b: int,
    tol: float, *, pin_start: bool, pin_end: bool, band: ToleranceBand | None = None,
) -> FitResult:
    """Fit samples ``a..b`` and, where the chain lays arcs over straight runs, refit.

    Parameters
    ----------
    fit : callable
        Fits the run with the given anchors (none: the plain beam); returns the pieces
        and the forced-corner indices.
    samples : ndarray, shape (M, 2)
        The sample polyline.
    a, b, tol : int, int, float
        The run's first and last sample; the tolerance.
    pin_start, pin_end : bool
        The chain passes through sample ``a`` / ``b`` with a free tangent there: a
        straight run reaching it gets the line through it (:func:`straight_run`).
    band : ToleranceBand, optional
        The band to verify replacement ends in (:func:`~zwcore.arcs._start.shorter_ends`).

    Returns
    -------
    tuple
        The best refit (fewest arcs over straight runs, then fewest segments) with fewer
        arcs over straight runs and at most one more segment per arc it removed (a line
        where the input is straight is worth a segment), else the plain fit. The long
        lines are anchored on the run's least-squares lines, else on their own lines;
        for a pinned end the refit's and the plain fit's ends are also redone with fewer
        pieces (:func:`~zwcore.arcs._start.shorter_ends`, :func:`_landings`).
    """
    got = _merge_lines(fit([]))
    pins = {"pin_start": pin_start, "pin_end": pin_end}
    bad = arcs_over_straight(got[0], samples, a, b, tol, **pins)
    best, best_key = got, (len(bad), 0)
    tried: list[list[tuple[float, ...]]] = []
    for own in (False, True) if bad else ():
        anchors = anchors_of(got[0], bad, samples, a, b, tol, **pins, own_lines=own)
        key = [(an.i0, an.i1, *an.q, *an.d) for an in anchors]
        if not anchors or key in tried:
            continue
        tried.append(key)
        alts = [_merge_lines(fit(anchors))]
        if band is not None and pin_end:
            ends = [got[0][-1].t_end, alts[0][0][-1].t_end]
            land = _landings(anchors[-1], band, b)
            for base, forced in (alts[0], got):
                if not forced:
                    alts.extend((ch, []) for ch in shorter_ends(base, band, b, ends, land))
        for alt in alts:
            n_bad = len(arcs_over_straight(alt[0], samples, a, b, tol, **pins))
            extra = len(alt[0]) - len(got[0])
            if n_bad < len(bad) and extra <= len(bad) - n_bad and (n_bad, extra) < best_key:
                best, best_key = alt, (n_bad, extra)
        if best_key[0] == 0:
            break
    return best


def _landings(
    an: Anchor, band: ToleranceBand, b: int
) -> Callable[[Piece, float], list[list[Piece]]]:
    """Ends of a run on the straight run ``an`` pinned through its end sample ``b``: from
    the start of a piece (and the distance of its first sample), the arc (or biarc)
    landing tangentially on the line and the line to ``b`` (see :func:`shorter_ends`)."""
    runs = StraightRuns(band, [an])
    pinned = an.i1 == b and bool(np.array_equal(an.q, band.samples[b]))

    def land(pc: Piece, e: float) -> list[list[Piece]]:
        if not pinned or pc.k >= an.i1 - 1:
            return []
        out: list[list[Piece]] = []
        for j, kap, _end, tend, s_end in runs.candidates(pc.p, pc.t, pc.k, b):
            res = band.verify(pc.p, pc.t, kap, pc.k, j, e, sig_end=s_end)
            if kap != 0.0 and res is not None:
                arc = band.make_piece(pc.p, pc.t, kap, pc.k, j, res)
                arc.t_end = tend.copy()
                out.append([arc])
        if not out:
            two = runs.landing_biarc(pc.p, pc.t, pc.k, e, b)
            out = [two] if two is not None else []
        for pieces in out:
            last = pieces[-1]
            res = band.verify(last.end, last.t_end, 0.0, last.j, b, last.e_end) if (
                last.j < b) else None
            if res is None:
                pieces.clear()
                continue
            line = band.make_piece(last.end, last.t_end, 0.0, last.j, b, res)
            line.end = band.samples[b].copy()
            line.t_end = last.t_end.copy()
            pieces.append(line)
        return [pieces for pieces in out if pieces]

    return land


def _merge_lines(got: FitResult) -> FitResult:
    """The fit with consecutive lines merged (:func:`~zwcore.arcs._pieces.merge_lines`),
    unless it has forced corners (their indices would shift)."""
    return got if got[1] else (merge_lines(got[0]), got[1])


# ---------------------------------------------------------------------------
# the anchors as the beam sees them

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

    def on_line(self, p: FloatArray, t: FloatArray, an: Anchor) -> bool:
        """True when the junction ``(p, t)`` lies on the anchor's line, along it."""
        return (abs(float(t[0] * an.d[1] - t[1] * an.d[0])) <= 1e-12
                and float(t @ an.d) > 0.0
                and abs(float((p - an.q) @ np.array([-an.d[1], an.d[0]])))
                <= 1e-9 * self.tol + 1e-13 * float(np.abs(p).max()))

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
                    (j == an.i1 and np.array_equal(an.q, self.samples[j]))
                    or (k == an.i0 and np.array_equal(an.q, self.samples[k]))):
                return True
        return False

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
        for an in self.anchors:
            if an.i1 <= k:
                continue
            if an.i0 <= k + 1 and self.on_line(p, t, an):
                here = an
                continue
            nxt = an
            break
        if nxt is None:
            return []
        out: list[AnchorPiece] = []
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
                        end = arc_point(p, t, kap, s_end)
                        out.append((j, kap, end, d.copy(), s_end))
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
                        out.append((j, 0.0, p + s_line * dh, dh.copy(), s_line))
        return out

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
        for an in self.anchors:
            if an.i1 > k + 1 and not self.on_line(p, t, an):
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
        last = min(nxt.i1, b if np.array_equal(nxt.q, self.samples[b]) else b - 1)
        if first > last or (
                self.cum[first] - self.cum[k] > self.LANDING_SPAN * max(reach, 1e-300)):
            return None
        tried = set()
        for off in self.LANDING_OFFSETS:
            m = int(np.searchsorted(self.cum, self.cum[first] + off * self.tol,
                                    side="right")) - 1
            m = min(max(m, first), last)
            if m in tried:
                continue
            tried.add(m)
            p1 = nxt.q + float((self.samples[m] - nxt.q) @ nxt.d) * nxt.d
            got = band.biarc(p, t, k, e, m, nxt.d, p1, self.LANDING_SPLITS)
            if got is None or max(abs(got[0].kappa), abs(got[1].kappa)) > 1.0 / self.tol:
                continue
            got[1].t_end = nxt.d.copy()  # exactly the anchor's direction
            return got
        return None

    def _last_before(
        self, p: FloatArray, t: FloatArray, kap: float, k: int, hi: int, s_end: float
    ) -> int:
        """Last sample in ``k..hi`` whose foot point on the piece lies before ``s_end``."""
        if hi <= k:
            return k
        u, v = local_uv(p, t, self.samples[k + 1 : hi + 1])
        if kap != 0.0:
            sig = unwrap(np.arctan2(kap * u, 1.0 - kap * v)) / kap
        else:
            sig = u
        over = np.flatnonzero(sig > s_end)
        return k + (int(over[0]) if over.size else len(sig))
