"""Straight runs of the input, and how the C1 chain is made to follow them with lines.

The beam (:mod:`zwcore.arcs._search`) ranks pieces by how far the chain reaches; over a
straight run of the input it may lay an arc of huge radius where the tangent entering
the run missed it. Such arcs are found in a fitted run (:mod:`zwcore.arcs._straight`:
*flat* arcs and arcs over a long straight run), and the run is refitted with those
straight runs as anchor lines (:func:`refit_along_straight_runs`). During the refit
:class:`~zwcore.arcs._anchors.StraightRuns` answers the beam's questions about the
anchors:

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

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from zwcore.arcs._anchors import StraightRuns
from zwcore.arcs._pieces import Piece, ToleranceBand, merge_lines
from zwcore.arcs._start import shorter_ends
from zwcore.arcs._straight import (
    Anchor,
    anchors_of,
    arcs_over_straight,
    is_flat,
    pinned_shorter,
)

FloatArray = NDArray[np.float64]

__all__ = ["FitResult", "refit_along_straight_runs", "refit_flat_ends"]

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
    cum = None if band is None else band.cum
    bad = arcs_over_straight(got[0], samples, a, b, tol, **pins, cum=cum)
    best, best_key = got, (len(bad), 0)
    tried: list[list[tuple[float, ...]]] = []
    # the refit with the fewest arcs over straight runs that still has some (its new
    # ones: straight runs the plain fit did not lay an arc over), for a second round
    near: tuple[tuple[int, int], list[Piece], dict[int, Anchor]] | None = None

    def refits(anchors: list[Anchor]) -> None:
        nonlocal best, best_key, near
        key = [(an.i0, an.i1, *an.q, *an.d) for an in anchors]
        if not anchors or key in tried:
            return
        tried.append(key)
        alts = [_merge_lines(fit(anchors))]
        if band is not None and pin_end:
            ends = [got[0][-1].t_end, alts[0][0][-1].t_end]
            land = _landings(anchors[-1], band, b)
            for base, forced in (alts[0], got):
                if not forced:
                    alts.extend((ch, []) for ch in shorter_ends(base, band, b, ends, land))
        for alt in alts:
            alt_bad = arcs_over_straight(alt[0], samples, a, b, tol, **pins, cum=cum)
            n_bad = len(alt_bad)
            extra = len(alt[0]) - len(got[0])
            if n_bad < len(bad) and extra <= len(bad) - n_bad and (n_bad, extra) < best_key:
                best, best_key = alt, (n_bad, extra)
            if n_bad and not alt[1] and (near is None or (n_bad, extra) < near[0]):
                near = ((n_bad, extra), alt[0], alt_bad)

    for own in (False, True) if bad else ():
        refits(anchors_of(got[0], bad, samples, a, b, tol, **pins, own_lines=own))
        if best_key[0] == 0:
            return best
    if bad and near is not None:
        # a second round: the refit laid an arc over a straight run the plain fit did not
        # (a short end run, say, after the chain moved): anchor those too
        refits(anchors_of(near[1], near[2], samples, a, b, tol, **pins))
    return best


def _n_flat(pieces: list[Piece], tol: float) -> int:
    """How many of ``pieces`` are flat arcs (:func:`~zwcore.arcs._straight.is_flat`)."""
    return sum(is_flat(pc.kappa, pc.length, tol) for pc in pieces)


def refit_flat_ends(
    fit: Callable[[list[Anchor]], FitResult], best: FitResult, samples: FloatArray, a: int,
    b: int, tol: float, *, pin_start: bool, pin_end: bool, band: ToleranceBand | None = None,
) -> FitResult:
    """``best`` (a fit of samples ``a..b``, as :func:`refit_along_straight_runs` returns
    it) or, where it keeps a flat arc over a straight run at a pinned end, the refit
    along a shorter run from that end (:func:`~zwcore.arcs._straight.pinned_shorter`)
    with fewer flat arcs and at most one more segment per flat arc it removed (a line
    where the input is straight is worth a segment); the first such refit, from the
    longest run on. The last resort of an open curve's run (:mod:`zwcore.arcs._runs`):
    the refits that cost no segment come first.
    """
    pins = {"pin_start": pin_start, "pin_end": pin_end}
    cum = None if band is None else band.cum
    n_flat = _n_flat(best[0], tol)
    if not n_flat or best[1] or not (pin_start or pin_end):
        return best
    bad = arcs_over_straight(best[0], samples, a, b, tol, **pins, cum=cum)
    anchors = anchors_of(best[0], bad, samples, a, b, tol, **pins)
    for i, pc in enumerate(best[0]):
        if i not in bad or not is_flat(pc.kappa, pc.length, tol):
            continue
        at = next((m for m, an in enumerate(anchors) if an is bad[i]), None)
        if at is None:
            continue
        for short in pinned_shorter(bad[i], samples, a, b, tol):
            alt = _merge_lines(fit([*anchors[:at], short, *anchors[at + 1 :]]))
            n_alt = _n_flat(alt[0], tol)
            if not alt[1] and n_alt < n_flat and (
                    len(alt[0]) - len(best[0]) <= n_flat - n_alt):
                return alt
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
