"""Moves that repeat an earlier move exactly (a hash table over their end points, numba).

A scan-line plan's flute-length passes re-follow what the passes before them finished: on
the 1025² part 77 % of the Ø1 ball's moves are, to the last bit, moves it made before. A
move is keyed by its start, its end and its radius. A repeat of a move that already cut the
stock removes nothing: the stock is already at or under its envelope and only goes down
(:func:`repeat_of`). So it needs no sweep, and no result changes.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]
#: The bits of -0.0 (compared and hashed as 0.0).
_NEG_ZERO = np.int64(-(2**63))

__all__ = ["repeat_of"]


def repeat_of(p0: F64, p1: F64, radius: F64, insert: NDArray[np.bool_]) -> NDArray[np.int64]:
    """For each move, the first earlier move with ``insert`` and the same start, end and
    radius (compared as floats: ``-0.0 == 0.0``), else -1.

    Parameters
    ----------
    p0, p1 : (n, 3) float64
        Start and end of each move. Direction counts: the same volume swept backwards can
        differ in the last bit of a node's envelope, and skipping a repeat is to change no
        bit.
    radius : (n,) float64
    insert : (n,) bool
        Moves that later moves may repeat (e.g. moves that cut).

    Returns
    -------
    (n,) int64
        In program order: ``src[i] < i`` with ``insert[src[i]]`` and equal keys, or -1.
    """
    n = len(p0)
    src = np.empty(n, np.int64)
    cap = 16
    while cap < 2 * n + 2:
        cap *= 2
    _repeat_kernel(_bits(p0), _bits(p1), np.ascontiguousarray(radius, np.float64).view(np.int64),
                   np.ascontiguousarray(insert, np.bool_), np.full(cap, -1, np.int32), src)
    return src


def _bits(a: F64) -> I64:
    """The float64 bits of ``(n, 3)`` points as int64 (a view when contiguous)."""
    return np.ascontiguousarray(a, np.float64).reshape(-1, 3).view(np.int64)


@njit(cache=True, nogil=True, inline="always")
def _word(v: np.int64) -> np.int64:
    """A float's bits with -0.0 read as 0.0."""
    return np.int64(0) if v == _NEG_ZERO else v


@njit(cache=True, nogil=True, inline="always")
def _mix(h: np.uint64, v: np.int64) -> np.uint64:
    return (h ^ np.uint64(_word(v))) * np.uint64(1099511628211)


@njit(cache=True, nogil=True)
def _slot(p0: I64, p1: I64, r: I64, i: int, mask: np.uint64) -> np.uint64:
    h = np.uint64(1469598103934665603)
    for c in range(3):
        h = _mix(h, p0[i, c])
        h = _mix(h, p1[i, c])
    if len(r):
        h = _mix(h, r[i])
    h ^= h >> np.uint64(33)
    h *= np.uint64(0xFF51AFD7ED558CCD)
    h ^= h >> np.uint64(33)
    return h & mask


@njit(cache=True, nogil=True)
def _same(a0: I64, a1: I64, ar: I64, j: int, b0: I64, b1: I64, br: I64, i: int) -> bool:
    for c in range(3):
        if _word(a0[j, c]) != _word(b0[i, c]) or _word(a1[j, c]) != _word(b1[i, c]):
            return False
    return not len(ar) or _word(ar[j]) == _word(br[i])


@njit(cache=True, nogil=True)
def _repeat_kernel(p0: I64, p1: I64, r: I64, insert: NDArray[np.bool_],
                   table: NDArray[np.int32], src: I64) -> None:
    """Open addressing (linear probing, load <= 1/2; int32 slots, half the memory to miss
    in) over the moves with ``insert``; keys (the floats' bits) are compared exactly, the
    hash only picks the slot."""
    mask = np.uint64(len(table) - 1)
    for i in range(len(p0)):
        slot = _slot(p0, p1, r, i, mask)
        src[i] = -1
        while True:
            j = int(table[slot])
            if j < 0:
                if insert[i]:
                    table[slot] = np.int32(i)
                break
            if _same(p0, p1, r, j, p0, p1, r, i):
                src[i] = j
                break
            slot = (slot + np.uint64(1)) & mask
