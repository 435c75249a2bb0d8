"""The junction states of the beam search (:mod:`zwcore.arcs._search`) and the candidate
pieces proposed from them."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from zwcore.arcs._pieces import Piece

FloatArray = NDArray[np.float64]

__all__ = ["Cand", "State", "approx_len", "unwind"]


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
class Cand:
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


def approx_len(c: Cand, chord: float) -> float:
    """Length of candidate ``c`` whose chord is ``chord`` long (its given length, or the
    chord's arc)."""
    if c.sig_end is not None:
        return c.sig_end
    x = 0.5 * c.kappa * chord
    return chord * (math.asin(min(abs(x), 1.0)) / abs(x) if x != 0.0 else 1.0)
