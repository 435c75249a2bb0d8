"""The pinned ends of a finished run redone with fewer pieces (issue 15, session 9).

The beam (:mod:`zwcore.arcs._search`) grows a run's chain from its start and finishes
it with the first state from which one piece reaches the last sample. Where a run ends
at a corner (or an open curve's end) the chain may arrive there with any tangent, so
from one of its last junctions a biarc onto the end sample, arriving along one of a few
tangents, may cover what the beam's last two or more pieces did
(:func:`zwcore.arcs._start.shorter_ends`, until now only asked for refits along
straight runs). The run's start, when pinned at a corner, is the same question asked of
the chain run backwards (:func:`turned`, on the reversed samples). Every replacement is
verified two-sided by the same kernels as the beam's pieces and keeps the chain C1 (a
biarc starts on a junction's point and tangent); the run's corners stay where they were.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from zwcore.arcs._geometry import rotate1
from zwcore.arcs._pieces import Piece, ToleranceBand
from zwcore.arcs._start import shorter_ends
from zwcore.arcs._straight import STRAIGHT_MIN_LEN

FloatArray = NDArray[np.float64]

__all__ = ["END_TURNS", "end_tails", "redo_ends", "turned"]

#: Turns (radians) of the chain's last tangent tried as the arrival tangent of a biarc
#: onto a pinned end (the polyline's last direction is tried too). On the glyph table
#: the turns (0, +-0.03, +-0.1, +-0.2) saved 0-9 segments a row (docs/arcs.md), the
#: last tangent alone about half of that.
END_TURNS: tuple[float, ...] = (0.0, -0.03, 0.03, -0.1, 0.1, -0.2, 0.2)

#: Rank of a chain of a run, the smaller the better (flat arcs, arcs over straight runs,
#: segments: ``_runs._RunFitter._rank``).
Rank = Callable[[list[Piece]], tuple[int, int, int]]


def turned(pieces: list[Piece], samples: FloatArray) -> list[Piece]:
    """The chain ``pieces`` of the reversed ``samples`` ``(M, 2)`` run the other way:
    the same pieces in the input's direction, indexing ``samples`` (and, given the
    reversed samples, a chain of ``samples`` run backwards)."""
    m = len(samples) - 1
    out = []
    for pc in reversed(pieces):
        j = m - pc.k
        out.append(Piece(pc.end.copy(), -pc.t_end, -pc.kappa, pc.length, m - pc.j, j,
                         pc.p.copy(), -pc.t, float(np.hypot(*(samples[j] - pc.p)))))
    return out


def end_tails(
    pieces: list[Piece], band: ToleranceBand, b: int,
    turns: tuple[float, ...] = END_TURNS,
) -> list[list[Piece]]:
    """``pieces`` (a run ending at sample ``b``, pinned there with a free tangent) with
    its end redone in fewer pieces: from one of its last junctions the single piece to
    ``b`` or a biarc arriving along the chain's last tangent turned by each of ``turns``
    or along the polyline's last segment (:func:`zwcore.arcs._start.shorter_ends`)."""
    t_last = pieces[-1].t_end
    ends = [rotate1(t_last, d) for d in turns]
    seg = band.samples[b] - band.samples[b - 1]
    n = float(np.hypot(*seg))
    if n > 0.0:
        ends.append(seg / n)
    return [alt for alt in shorter_ends(pieces, band, b, ends) if len(alt) < len(pieces)]


def _n_lines(pieces: list[Piece], tol: float) -> int:
    """Lines of ``pieces`` at least :data:`~zwcore.arcs._straight.STRAIGHT_MIN_LEN`
    tolerances long, as long as a straight run of the input (shorter ones are where the
    beam found a line between two arcs, e.g. 2 mm before a glyph's corner at 0.05)."""
    return sum(pc.kappa == 0.0 and pc.length >= STRAIGHT_MIN_LEN * tol for pc in pieces)


def _better(k2: tuple[int, int, int], key: tuple[int, int, int], alt: list[Piece],
            best: list[Piece], tol: float) -> bool:
    """``alt`` (rank ``k2``) has fewer segments than ``best`` (rank ``key``), no more of
    anything else, and keeps its lines: a line at a pinned end is what the refits
    along straight runs chose (the NACA 2412's trailing edge: a line, not an arc of
    radius 40,000 mm that the flat-arc rule would let through at sampling 0.2 mm)."""
    return (k2[-1] < key[-1]
            and all(x <= y for x, y in zip(k2[:-1], key[:-1], strict=True))
            and _n_lines(alt, tol) >= _n_lines(best, tol))


def redo_ends(
    pieces: list[Piece], band: ToleranceBand, back: Callable[[], ToleranceBand], a: int,
    b: int, pin_start: bool, pin_end: bool, rank: Rank,
) -> list[Piece]:
    """The run ``pieces`` (samples ``a..b`` of ``band``) with its pinned ends redone.

    Parameters
    ----------
    pieces : list of Piece
        The run's C1 chain (no forced corners).
    band : ToleranceBand
        The band of the samples (its tolerance is the one every piece keeps).
    back : callable
        Returns the band of the reversed samples (built on first use).
    a, b : int
        The run's first and last sample.
    pin_start, pin_end : bool
        The chain passes through sample ``a`` / ``b`` with a free tangent there.
    rank : callable
        The rank of a chain of the run, the smaller the better; its last item is the
        number of segments.

    Returns
    -------
    list of Piece
        ``pieces``, or a chain of fewer pieces ranking no worse in its other items (as
        few flat arcs and arcs over straight runs, as many long lines), the same ends and C1;
        each end is redone again after a replacement until neither gives fewer.
    """
    best, key = pieces, rank(pieces)
    m = len(band.samples) - 1
    improved = True
    while improved and len(best) >= 2:
        improved = False
        if pin_end:
            for alt in sorted(end_tails(best, band, b), key=len):
                k2 = rank(alt)
                if _better(k2, key, alt, best, band.tol):
                    best, key, improved = alt, k2, True
                    break
        if pin_start and len(best) >= 2:
            bk = back()
            for alt in sorted(end_tails(turned(best, bk.samples), bk, m - a), key=len):
                fwd = turned(alt, band.samples)
                k2 = rank(fwd)
                if _better(k2, key, fwd, best, band.tol):
                    best, key, improved = fwd, k2, True
                    break
    return best
