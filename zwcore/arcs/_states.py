"""The junction states of the beam search (:mod:`zwcore.arcs._search`) and the candidate
pieces proposed from them."""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import NDArray

from zwcore.arcs._pieces import Piece

FloatArray = NDArray[np.float64]

__all__ = ["Cands", "State", "approx_lengths", "unwind"]


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
    def join(parts: list[Cands]) -> Cands:
        """The candidates of ``parts``, in order."""
        if len(parts) == 1:
            return parts[0]
        return Cands(**{f.name: np.concatenate([getattr(c, f.name) for c in parts])
                        for f in fields(Cands)})


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
