"""The junction states of the beam search (:mod:`zwcore.arcs._search`) and the candidate
pieces proposed from them."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import NDArray

from zwcore.arcs._pieces import Piece

FloatArray = NDArray[np.float64]

__all__ = ["Behind", "Cands", "State", "Stuck", "approx_lengths", "level_arrays", "unwind"]


class Stuck(Exception):
    """No verified piece could be placed from the current junction."""


class Behind(Stuck):
    """A run's cutoff dropped it: its chains cannot be worth finishing (so not a reason
    to retry at a tighter working tolerance, as :class:`Stuck` is)."""


@dataclass
class State:
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
    parent: State | None
    piece: Piece | None
    t_first: FloatArray | None
    depth: int
    fresh: bool = False
    n_over: int | None = None
    #: :meth:`ToleranceBand.longest_piece_bounds` from here, once asked (see
    #: :meth:`Fitter._bounds`)
    bounds: tuple[FloatArray, FloatArray] | None = None


@dataclass
class Cands:
    """Candidate pieces from the states of a level, as arrays ``(C,)``: piece ``c``
    starts from state ``si[c]`` and ends at ``end[c]`` ``(C, 2)`` with tangent ``t_end[c]``
    standing for sample ``j[c]``; ``sig_end`` is its length when given (NaN: it ends at
    the foot point of ``j``), ``special`` marks pieces onto straight runs
    (:class:`~zwcore.arcs._anchors.StraightRuns`), ``bonus`` is added to its rank score."""

    si: NDArray[np.int64]
    j: NDArray[np.int64]
    kappa: FloatArray
    end: FloatArray
    t_end: FloatArray
    bonus: FloatArray
    sig_end: FloatArray
    special: NDArray[np.bool_]

    def __len__(self) -> int:
        return len(self.j)

    @staticmethod
    def anchored(si: int, extra: Sequence[tuple[int, float, FloatArray, FloatArray, float]],
                 ) -> Cands:
        """The pieces ``extra`` onto straight runs from state ``si`` (each: end sample,
        curvature, end point, end tangent, length;
        :meth:`~zwcore.arcs._anchors.StraightRuns.candidates`)."""
        m = len(extra)
        return Cands(np.full(m, si, dtype=np.int64), np.array([c[0] for c in extra]),
                     np.array([c[1] for c in extra]), np.array([c[2] for c in extra]),
                     np.array([c[3] for c in extra]), np.zeros(m),
                     np.array([c[4] for c in extra]), np.ones(m, dtype=bool))

    @staticmethod
    def anchored_level(
        extra: Sequence[tuple[int, tuple[int, float, FloatArray, FloatArray, float]]],
    ) -> Cands:
        """The pieces onto straight runs from several states of a level, each with its
        state's index (``(si, piece)``, pieces as in :meth:`anchored`): the arrays of
        :meth:`anchored` per state joined, built once per level."""
        m = len(extra)
        return Cands(np.array([x[0] for x in extra], dtype=np.int64),
                     np.array([x[1][0] for x in extra]), np.array([x[1][1] for x in extra]),
                     np.array([x[1][2] for x in extra]), np.array([x[1][3] for x in extra]),
                     np.zeros(m), np.array([x[1][4] for x in extra]), np.ones(m, dtype=bool))

    @staticmethod
    def join(parts: list[Cands]) -> Cands:
        """The candidates of ``parts``, in order."""
        if len(parts) == 1:
            return parts[0]
        return Cands(**{name: np.concatenate([getattr(c, name) for c in parts])
                        for name in _FIELDS})


#: the field names of :class:`Cands` (looked up once, not per level)
_FIELDS = tuple(f.name for f in fields(Cands))


def level_arrays(
    level: list[State], b: int,
    bounds: Callable[[State, int], tuple[FloatArray, FloatArray]],
) -> tuple[FloatArray, FloatArray, NDArray[np.int64], NDArray[np.int64], FloatArray,
           FloatArray, NDArray[np.int64]]:
    """The states of ``level`` as arrays for :func:`zwcore.arcs._select.candidates_level`:
    points ``(S, 2)``, tangents ``(S, 2)``, samples ``(S,)``, the last sample their longest
    piece reaches before ``b`` ``(S,)`` (none: their own), and the running curvature
    bounds of that piece (``bounds(state, b)``) concatenated with their offsets
    ``(S + 1,)``."""
    ns = len(level)
    sk = np.array([st.k for st in level], dtype=np.int64)
    sjm = sk.copy()
    b_off = np.zeros(ns + 1, dtype=np.int64)
    los: list[FloatArray] = []
    ups: list[FloatArray] = []
    for i, st in enumerate(level):
        b_off[i + 1] = b_off[i]
        if b - 1 > st.k:
            lo1, up1 = bounds(st, b)
            sjm[i] = min(st.k + len(lo1), b - 1)
            los.append(lo1)
            ups.append(up1)
            b_off[i + 1] += len(lo1)
    empty = np.empty(0)
    return (np.array([st.p for st in level]), np.array([st.t for st in level], dtype=np.float64),
            sk, sjm, np.concatenate(los) if los else empty,
            np.concatenate(ups) if ups else empty, b_off)


def approx_lengths(c: Cands, chord: FloatArray) -> FloatArray:
    """Lengths ``(C,)`` of the candidates whose chords are ``chord`` long (the given
    length, or the chord's arc)."""
    x = 0.5 * c.kappa * chord
    ax = np.abs(x)
    arc = chord * np.where(x != 0.0, np.arcsin(np.minimum(ax, 1.0)) / np.where(
        x != 0.0, ax, 1.0), 1.0)
    return np.where(np.isnan(c.sig_end), arc, c.sig_end)


def unwind(st: State) -> list[Piece]:
    """The pieces of the chain that ends at ``st``, first to last."""
    out: list[Piece] = []
    node: State | None = st
    while node is not None:
        if node.piece is not None:
            out.append(node.piece)
        node = node.parent
    out.reverse()
    return out
