"""The runs of a curve (between corners) fitted one by one and joined into one chain
(steps 2-6 of :mod:`zwcore.arcs.fit`), and the second fits of loops: from turned start
tangents at the first point (``seam="first_point"``) or from other seams (``"free"``)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from zwcore.arcs._anchors import StraightRuns
from zwcore.arcs._ends import redo_ends
from zwcore.arcs._ends import turned as _turned
from zwcore.arcs._geometry import rotate
from zwcore.arcs._lines import refit_along_straight_runs, refit_flat_ends
from zwcore.arcs._pieces import Piece, ToleranceBand
from zwcore.arcs._polygon import polygon_run
from zwcore.arcs._prepare import Prepared
from zwcore.arcs._search import Behind, Fitter, Stuck
from zwcore.arcs._start import free_start
from zwcore.arcs._states import State
from zwcore.arcs._straight import Anchor, arcs_over_straight, is_flat
from zwcore.arcs.verify import deviations

FloatArray = NDArray[np.float64]

__all__ = [
    "LOOP_SEAMS", "LOOP_START_TURNS", "LOOP_SWEEP_MAX_SAMPLES", "assemble", "short_closure",
    "sweep_loop_seams", "sweep_loop_start",
]

#: Turns (radians) of the start tangent tried for a corner-free closed curve.
LOOP_START_TURNS = (-0.01, 0.01, -0.02, 0.02, -0.03, 0.03)
#: A sweep fit is dropped once every state of its beam is this many pieces behind the
#: first fit at the same sample (its start costs one piece it wins back, if at all, at
#: the closure: a chain two behind has never come out shorter on the benchmarks).
LOOP_SWEEP_BEHIND = 2
#: Other seams tried for a corner-free loop with ``seam="free"``, as shares of its
#: length (the first fit's junction nearest there; :func:`_seam_fit`): fewer segments
#: than the turned start tangents for less CPU (docs/arcs.md, "Closed curves").
LOOP_SEAMS: tuple[float, ...] = (0.25, 0.5, 0.75)
#: Other seams are tried only when the first fit's closing biarc is shorter than this
#: share of two typical pieces (:func:`short_closure`): on the glyph table (session 7)
#: the seams saved 45 segments on the 39 loops with such a closure, 8 on the other 27
#: (for 40 % of the seams' CPU)
LOOP_SHORT_CLOSURE = 0.5
#: Loops with more samples than this are fitted from one start tangent only (time).
LOOP_SWEEP_MAX_SAMPLES = 5_000
#: A refit along straight runs goes on from the plain fit's last level whose states were
#: all more than this many single-piece reaches before the first anchor (the levels up
#: to there are the plain fit's: a landing biarc is tried from 2.2 reaches).
RESUME_FAR = 3.0

#: Share of the tolerance the first beam's feasibility scans use (the pieces are verified
#: at the full tolerance; the retries scan at 0.8, 0.6, 0.4). At 0.97 instead of 0.95 no
#: glyph row got more segments and five of six got fewer (chordal 0.01: 584 -> 575, noisy
#: 0.01: 1,004 -> 977); at 0.98-0.995 noisy 0.05 and even 0.05 got more. With a radius
#: cap (lines where arcs would be flatter) 0.97 costs segments (the ellipse of the bench
#: capped at 120 mm: 43 -> 48; at 60 mm: 75 -> 81), so capped fits keep 0.95.
WORK = 0.97
WORK_CAPPED = 0.95
#: :data:`WORK` of ``seam="free"`` (its runs fitted both ways, its loops from other seams
#: and reversed; glyph rows even, chordal, noisy at 0.05 then 0.01, at 0.97 / 0.98 /
#: 0.99: 404 / 403 / 401, 370 / 370 / 372, 421 / 420 / 420, 630 / 635 / 631, 566 / 562 /
#: 565, 905 / 894 / 872). The default keeps 0.97: its chains stay as they were.
WORK_FREE = 0.98
#: Runs (between corners) of fewer pieces than this are not fitted backwards: on the
#: glyph table no run of two pieces came out shorter (77 tried).
REVERSE_MIN_PIECES = 3
#: A backward plain beam (no anchors) of more pieces than the forward chain plus this
#: (``seam="free"``; the default seam: plus 0) is dropped before its refit along straight
#: runs: that refit rarely takes a segment off, and a backward chain is only kept when
#: shorter. At +1 no chain of the glyph table changed (at +0 even 0.01 got one more
#: segment with "free"); the backward fits' refits were a third of their CPU.
REVERSE_PLAIN_SLACK = 1


def work_share(max_radius: float | None, free: bool = False) -> float:
    """:data:`WORK` without a radius cap (:data:`WORK_FREE` with ``seam="free"``),
    :data:`WORK_CAPPED` with one."""
    if max_radius is not None:
        return WORK_CAPPED
    return WORK_FREE if free else WORK

RunFit = tuple[list[Piece], list[int]]


class _RunFitter:
    """Fits one run of ``prep`` (samples ``a..b``) with the beam, its retries, its
    fallback and the refit along straight runs."""

    def __init__(self, prep: Prepared, max_radius: float | None, bridge: bool,
                 free: bool = False) -> None:
        self.prep = prep
        self.max_radius = max_radius
        self.bridge = bridge
        #: ``seam="free"``: the first scans at :data:`WORK_FREE`
        self.free = free
        #: runs fitted in closed form (:mod:`zwcore.arcs._polygon`); off: the beam only
        self.closed_form = bridge and max_radius is None
        #: every run so far was fitted in closed form
        self.all_closed_form = True
        self._band: ToleranceBand | None = None
        self._back: ToleranceBand | None = None
        #: the levels of the plain fit of each run ``(a, b, work)``: a refit goes on from
        #: one of them (:func:`_resume_level`)
        self._levels: dict[tuple[int, int, float], list[list[State]]] = {}
        #: free run starts per working tolerance, shared by the fitters of each run
        self._starts: dict[float, dict[tuple[int, int], tuple[FloatArray, int]]] = {}
        #: a plain beam (no anchors) of more pieces than this raises :class:`Behind`
        #: instead of being refitted (a second fit that only counts when it is shorter)
        self.plain_max: int | None = None

    def fitter(self, work: float, anchors: list[Anchor]) -> Fitter:
        f = Fitter(self.prep.samples, self.prep.tol, work, self.max_radius,
                   None if self._band is None else self._band.cum)
        f.use_bridge = self.bridge
        f.starts = self._starts.setdefault(work, {})
        if anchors:
            f.straight = StraightRuns(f.band, anchors)
        return f

    def beam(self, a: int, b: int, t_start: FloatArray | None, anchors: list[Anchor],
             first: float) -> RunFit:
        loop = self.prep.loop
        for work in (first, 0.8, 0.6, 0.4):
            f = self.fitter(work, anchors)
            resume = None
            if not anchors:
                f.levels = self._levels[(a, b, work)] = []
            elif (a, b, work) in self._levels:
                resume = _resume_level(f, self._levels[(a, b, work)], a, b, loop, t_start)
            try:
                got = f.run(a, b, loop, allow_forced=False, t_start=t_start, resume=resume)
            except Behind:
                raise
            except Stuck:
                continue
            if not anchors and self.plain_max is not None and len(got[0]) > self.plain_max:
                raise Behind
            return got
        # the beam with a filleted-polyline fallback wherever it is stuck: never fails
        return self.fitter(0.9, anchors).run(a, b, loop, allow_forced=True, t_start=t_start)

    def run(self, a: int, b: int, t_start: FloatArray | None) -> RunFit:
        loop = self.prep.loop
        work = work_share(self.max_radius, self.free)
        if self._band is None:
            self._band = self.fitter(work, []).band
        if self.closed_form and t_start is None:
            # a coarse polygon: the filleted polygon (checked densely by fit_arcs; the
            # refit without closed forms uses the beam)
            poly = polygon_run(self._band, a, b, loop)
            if poly is not None:
                return poly, []
        self.all_closed_form = False
        pins = {"pin_start": t_start is None and not loop, "pin_end": not loop}
        got = self._refit(a, b, t_start, work, pins)
        if self.max_radius is None and not self.prep.closed and self._n_flat(got[0]):
            # the scans at WORK may leave a flat arc that the refit along straight runs
            # cannot replace at its price and the scans at WORK_CAPPED do not lay (NACA
            # 2412 at 0.05: radius 43,000 mm at the trailing edge, sagitta 0.21 tol):
            # then the chain with fewer flat arcs, then fewer arcs over straight runs,
            # then fewer segments. Open curves only: on the closed glyph outlines it
            # refits 87 runs of the table (most at noisy 0.01, noise-sized flat arcs: 104
            # -> 88, main 125), +27 % CPU on that row
            alt = self._refit(a, b, t_start, WORK_CAPPED, pins)
            if self._rank(alt[0], a, b, pins) < self._rank(got[0], a, b, pins):
                got = alt
            if self._n_flat(got[0]):
                # (hook, arcfast7) still flat: a shorter line from a pinned end, +1 segment
                got = refit_flat_ends(lambda anchors: self.beam(a, b, t_start, anchors, work),
                                      got, self.prep.samples, a, b, self.prep.tol,
                                      band=self._band, **pins)
        # the last run of a wrapping curve ends at the smooth first point, not at a
        # corner: the first run starts with its end tangent (not a free one)
        pin_end = pins["pin_end"] and not (self.prep.wrap and b == self.prep.bounds[-1])
        if (pin_end or pins["pin_start"]) and not got[1] and len(got[0]) >= 2:
            got = (redo_ends(got[0], self._band, self._back_band, a, b, pins["pin_start"],
                             pin_end, lambda pcs: self._rank(pcs, a, b, pins)), [])
        return got

    def _back_band(self) -> ToleranceBand:
        """The band of the reversed samples (for :func:`redo_ends`), built once."""
        if self._back is None:
            assert self._band is not None
            self._back = ToleranceBand(
                np.ascontiguousarray(self.prep.samples[::-1]), self.prep.tol,
                self._band.work_tol / self.prep.tol, self.max_radius)
        return self._back

    def _refit(self, a: int, b: int, t_start: FloatArray | None, work: float,
               pins: dict[str, bool]) -> RunFit:
        """The run fitted with the beam's first scans at ``work``: arcs over straight
        runs (the tangent missed the run) are refitted with those runs as anchors the
        chain follows with lines (:mod:`zwcore.arcs._lines`)."""
        return refit_along_straight_runs(
            lambda anchors: self.beam(a, b, t_start, anchors, work), self.prep.samples, a,
            b, self.prep.tol, band=self._band, **pins)

    def _n_flat(self, pieces: list[Piece]) -> int:
        """How many of ``pieces`` are flat arcs (:func:`is_flat`)."""
        return sum(is_flat(pc.kappa, pc.length, self.prep.tol) for pc in pieces)

    def _rank(self, pieces: list[Piece], a: int, b: int,
              pins: dict[str, bool]) -> tuple[int, int, int]:
        """Flat arcs, arcs over straight runs and segments of the chain ``pieces`` of
        samples ``a..b``: the smaller the better."""
        assert self._band is not None
        over = arcs_over_straight(pieces, self.prep.samples, a, b, self.prep.tol,
                                  cum=self._band.cum, **pins)
        return self._n_flat(pieces), len(over), len(pieces)


def _resume_level(
    f: Fitter, levels: list[list[State]], a: int, b: int, loop: bool,
    t_start: FloatArray | None,
) -> list[State] | None:
    """The level of the plain fit ``levels`` of samples ``a..b`` that the refit ``f``
    (with anchors) goes on from, copied, or None (from the start).

    Far before the first anchor a refit proposes what the plain fit did: anchor pieces
    are tried only within :attr:`StraightRuns.LANDING_SPAN` single-piece reaches of an
    anchor (a landing arc from further away would span several reaches: it fails its
    check), and only arcs over straight runs rank otherwise. So the refit takes the
    plain fit's levels as long as every state of a level is :data:`RESUME_FAR` reaches
    before the first anchor and none of the pieces of the next level is over a straight
    run, and goes on from the last such next level.
    """
    sr = f.straight
    if sr is None or len(levels) < 2 or (
            t_start is None and not loop and sr.start_direction(a, f.samples[a]) is not None):
        return None
    cum = f.cum
    first = min(an.i0 for an in sr.anchors)
    at = 0
    for lv in range(len(levels) - 1):
        far = True
        for st in levels[lv]:
            assert st.t is not None
            lo, _up = st.bounds if st.bounds is not None else f.band.longest_piece_bounds(
                st.p, st.t, st.k, b)
            reach = cum[min(st.k + len(lo), b)] - cum[st.k]
            if not cum[first] - cum[st.k] > RESUME_FAR * reach:
                far = False
                break
        if not far or any(
                st.piece is None
                or sr.is_over(st.piece.k, st.piece.j, st.piece.kappa, st.piece.length)
                for st in levels[lv + 1]):
            break
        at = lv + 1
    if at == 0:
        return None
    return [_copy_chain(st) for st in levels[at]]


def _copy_chain(st: State) -> State:
    """``st`` and its ancestors as new states (their counts of arcs over straight runs
    belong to another set of anchors: not copied)."""
    chain: list[State] = []
    node: State | None = st
    while node is not None:
        chain.append(node)
        node = node.parent
    par: State | None = None
    for nd in reversed(chain):
        par = State(nd.p, nd.t, nd.k, nd.e, par, nd.piece, nd.t_first, nd.depth, nd.fresh,
                    None, nd.bounds)
    assert par is not None
    return par


def assemble(
    prep: Prepared, max_radius: float | None, bridge: bool, free: bool = False,
) -> tuple[list[Piece], list[int], list[int], bool]:
    """Every run fitted and joined: the pieces, the corner junctions, the forced corners
    (``-1``: the closing junction) and whether every run was a closed form.
    ``bridge``: allow biarc bridges and closed forms (off: the beam only).
    ``free`` (``seam="free"``): the first scans at :data:`WORK_FREE`, and on a curve
    whose runs all end at corners each run of :data:`REVERSE_MIN_PIECES` or more is also
    fitted the other way round, the fewer pieces kept (:func:`_reverse_runs`); with the
    default seam the same for the runs of a closed curve between two corners (session
    10: 6-38 segments fewer a glyph row for 20-45 % more CPU)."""
    fit = _RunFitter(prep, max_radius, bridge, free)
    bounds = prep.bounds
    n_runs = len(bounds) - 1
    results: list[RunFit | None] = [None] * n_runs
    if prep.wrap:
        last_run = fit.run(bounds[-2], bounds[-1], None)
        results[-1] = last_run
        results[0] = fit.run(bounds[0], bounds[1], last_run[0][-1].t_end)
    for r in range(n_runs):
        if results[r] is None:
            results[r] = fit.run(bounds[r], bounds[r + 1], None)
    all_closed_form = fit.all_closed_form
    if free and not (prep.wrap or prep.loop):
        all_closed_form &= _reverse_runs(prep, max_radius, bridge, results)
    elif prep.closed and not (free or prep.loop):
        all_closed_form &= _reverse_runs(prep, max_radius, bridge, results, False)
    pieces: list[Piece] = []
    corner_j: list[int] = []
    forced_j: list[int] = []
    for r, got in enumerate(results):
        assert got is not None
        run_pieces, run_forced = got
        base = len(pieces)
        forced_j.extend(-1 if f == -1 else base + f for f in run_forced)
        pieces.extend(run_pieces)
        if r < n_runs - 1 or (prep.closed and prep.cs and not prep.wrap):
            corner_j.append(len(pieces) - 1)
    return pieces, corner_j, forced_j, all_closed_form


def _reverse_runs(prep: Prepared, max_radius: float | None, bridge: bool,
                  results: list[RunFit | None], free: bool = True) -> bool:
    """Each run of ``results`` (a closed curve's, fitted forwards) of at least
    :data:`REVERSE_MIN_PIECES` pieces with corners at both ends fitted again on the
    reversed samples; where that takes fewer pieces (and no forced corner) it replaces
    the run, turned back to the input's direction. The beam grows a chain from its
    start, so where its junctions fall, and what the last piece must cover, depends on
    the direction (glyph table: 2-16 segments a row with ``seam="free"``).

    ``free``: ``seam="free"`` (every run ends at corners; the first scans at
    :data:`WORK_FREE`). Else the default seam: the runs of a wrapping closed curve that
    meet at its smooth first point stay as fitted, the scans are at :data:`WORK`, and a
    backward chain replaces the run only with no more flat arcs and arcs over straight
    runs than it has (the straight-run rules the forward fit applied; on noisy 0.01
    this keeps 13 segments, 88 flat arcs instead of 97). A backward plain beam much
    longer than the forward chain is dropped (:data:`REVERSE_PLAIN_SLACK`).
    Returns whether every run fitted backwards was a closed form."""
    m = prep.m_last
    back = Prepared(prep.origin, np.ascontiguousarray(prep.samples[::-1]), prep.tol,
                    prep.closed, [m - b for b in reversed(prep.bounds)],
                    sorted(m - c for c in prep.cs), False, False)
    fit = _RunFitter(back, max_radius, bridge, free)
    last = len(results) - 1
    for r, got in enumerate(results):
        assert got is not None
        if len(got[0]) < REVERSE_MIN_PIECES or (prep.wrap and r in (0, last)):
            continue
        a, b = prep.bounds[r], prep.bounds[r + 1]
        fit.plain_max = len(got[0]) + (REVERSE_PLAIN_SLACK if free else 0)
        try:
            pieces, forced = fit.run(m - b, m - a, None)
        except Behind:
            continue
        if forced or len(pieces) >= len(got[0]):
            continue
        turned = _turned(pieces, prep.samples)
        if free or all(n <= o for n, o in zip(_straight_rank(turned, prep, a, b),
                                              _straight_rank(got[0], prep, a, b), strict=True)):
            results[r] = (turned, [])
    return fit.all_closed_form


def _straight_rank(pieces: list[Piece], prep: Prepared, a: int, b: int) -> tuple[int, int]:
    """Flat arcs and arcs over straight runs of the chain ``pieces`` of samples ``a..b``
    of ``prep``, both ends pinned (:func:`is_flat`, :func:`arcs_over_straight`)."""
    n_flat = sum(is_flat(pc.kappa, pc.length, prep.tol) for pc in pieces)
    over = arcs_over_straight(pieces, prep.samples, a, b, prep.tol, pin_start=True,
                              pin_end=True)
    return n_flat, len(over)


def sweep_loop_start(
    prep: Prepared, max_radius: float | None, pieces: list[Piece], lim: float
) -> tuple[list[Piece], float, float] | None:
    """A shorter valid chain of a loop from a turned start tangent, or None.

    The first point is a junction with a free tangent that the closing biarc must meet
    again; the count depends on that tangent in a way no local rule predicts (the
    closure lands at a good or a bad place), so a few separate fits from turned start
    tangents (:data:`LOOP_START_TURNS`) are tried; returns the shortest with its two
    deviations (each at most ``lim``) when it is shorter than ``pieces``. A turned fit
    starts with a short piece and wins it back, if at all, at the closure; one whose
    every state is :data:`LOOP_SWEEP_BEHIND` pieces behind the first fit ``pieces`` at
    the same sample is dropped there (about half of the sweep's work).
    """
    samples, tol, m_last = prep.samples, prep.tol, prep.m_last
    fz = Fitter(samples, tol, work_share(max_radius), max_radius)
    t0, _ = free_start(fz.band, samples[0].copy(), 0, m_last)
    best: tuple[list[Piece], float, float] | None = None
    # the first fit's progress: pieces finished by each sample
    ends = np.array([pc.j for pc in pieces], dtype=np.int64)
    n_first = len(pieces)

    def behind(level: list[State]) -> bool:
        """Every chain of ``level`` is LOOP_SWEEP_BEHIND pieces behind a chain shorter
        than the best so far (its length estimated from the first fit's progress)."""
        n_best = n_first if best is None else len(best[0])
        done = np.searchsorted(ends, [st.k for st in level], side="right")
        ahead = min(st.depth - int(d) for st, d in zip(level, done, strict=True))
        return n_first + ahead >= n_best + LOOP_SWEEP_BEHIND

    for d in LOOP_START_TURNS:
        tt = rotate(t0, d)
        fit = Fitter(samples, tol, work_share(max_radius), max_radius, fz.band.cum)
        fit.cutoff = behind
        # (the first fit found no full circle; the samples and the band are the same)
        fit.one_piece_runs = False
        try:
            alt, _ = fit.run(0, m_last, True, allow_forced=False, t_start=tt)
        except Stuck:
            continue
        if len(alt) >= len(pieces if best is None else best[0]):
            continue
        ap, ac = deviations(samples, alt, tol)
        if ap <= lim and ac <= lim:
            best = (alt, ap, ac)
    return best


def _seam_fit(
    samples: FloatArray, tol: float, max_radius: float | None, pieces: list[Piece],
    share: float, behind: Callable[[list[State], int], bool], lim: float,
) -> tuple[list[Piece], float, float, int] | None:
    """The loop ``samples`` (``(M, 2)``, the first repeated at the end) fitted from
    another seam: the sample ending the first fit's (``pieces``) junction nearest
    ``share`` of the loop's length, with free start tangents. Returns the chain (its
    samples: ``samples`` rolled to start at the seam), its two deviations (each at most
    ``lim``) and the seam's sample, or None. ``behind(level, s)``: the cutoff of a fit
    whose sample 0 is sample ``s`` of ``samples``."""
    m_last = len(samples) - 1
    cum = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(samples, axis=0).T))])
    js = np.array([pc.j for pc in pieces[:-1]], dtype=np.int64)
    js = js[(js > 0) & (js < m_last)]
    if js.size == 0:
        return None
    s = int(js[np.argmin(np.abs(cum[js] - share * cum[-1]))])
    rs = np.ascontiguousarray(np.vstack([samples[s:-1], samples[: s + 1]]))
    fit = Fitter(rs, tol, work_share(max_radius, True), max_radius)
    fit.cutoff = lambda level: behind(level, s)
    # (the first fit found no full circle)
    fit.one_piece_runs = False
    try:
        alt, _ = fit.run(0, m_last, True, allow_forced=False)
    except Stuck:
        return None
    ap, ac = deviations(rs, alt, tol)
    return (alt, ap, ac, s) if ap <= lim and ac <= lim else None


def short_closure(pieces: list[Piece]) -> bool:
    """Whether the loop ``pieces`` closes with a short biarc: its last two pieces together
    shorter than :data:`LOOP_SHORT_CLOSURE` times two of its other pieces (median)."""
    if len(pieces) < 4:
        return True
    lengths = np.array([pc.length for pc in pieces])
    return bool(lengths[-2:].sum() < LOOP_SHORT_CLOSURE * 2.0 * np.median(lengths[:-2]))


def sweep_loop_seams(
    prep: Prepared, max_radius: float | None, pieces: list[Piece], lim: float
) -> tuple[list[Piece], float, float, int] | None:
    """A shorter valid chain of a corner-free loop from another seam, or None
    (``seam="free"``).

    The first fit ``pieces`` starts at the first sample, a junction with a free tangent
    that the closing biarc must meet again; where the loop starts changes the count in a
    way no local rule predicts (the closure lands at a good or a bad place), so the loop
    is also fitted from a few other seams (:data:`LOOP_SEAMS`, :func:`_seam_fit`) when
    the first fit's closure is short (:func:`short_closure`). Returns the shortest when
    shorter than ``pieces``: its pieces (indexing ``prep.samples`` rolled to start at the
    seam), its two deviations (each at most ``lim``) and its seam sample. A seam fit
    whose every state is :data:`LOOP_SWEEP_BEHIND` pieces behind the first fit over the
    same stretch is dropped there (most of them).
    """
    if not short_closure(pieces):
        return None
    samples, m_last = prep.samples, prep.m_last
    best: tuple[list[Piece], float, float, int] | None = None
    # the first fit's progress: pieces finished by each sample
    ends = np.array([pc.j for pc in pieces], dtype=np.int64)
    n_first = len(pieces)

    def behind(level: list[State], seam: int) -> bool:
        """Every chain of ``level`` (of a fit from sample ``seam``) is LOOP_SWEEP_BEHIND
        pieces behind a chain shorter than the best so far (its length estimated from
        the first fit's progress: its pieces finished between the seam and there)."""
        n_best = n_first if best is None else len(best[0])
        at = np.array([st.k for st in level], dtype=np.int64) + seam
        before = int(np.searchsorted(ends, seam, side="right"))
        done = np.searchsorted(ends, at, side="right") - before
        over = at > m_last  # past the first fit's seam: the rest of its lap, then more
        done[over] = n_first - before + np.searchsorted(ends, at[over] - m_last, side="right")
        ahead = min(st.depth - int(d) for st, d in zip(level, done, strict=True))
        return n_first + ahead >= n_best + LOOP_SWEEP_BEHIND

    for share in LOOP_SEAMS:
        got = _seam_fit(samples, prep.tol, max_radius, pieces, share, behind, lim)
        if got is not None and len(got[0]) < len(pieces if best is None else best[0]):
            best = got
    return best
