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

__all__ = ["RepeatTable", "repeat_of"]


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
    return RepeatTable().add(p0, p1, radius, insert)


class RepeatTable:
    """:func:`repeat_of` over moves that come in pieces: each piece's moves are looked up
    among every earlier piece's too (indices count from the first piece's first move), so
    the pieces give what their concatenation gives."""

    def __init__(self) -> None:
        self._keys = np.empty((0, 7), np.int64)  # p0, p1, radius bits per move
        self._insert = np.empty(0, np.bool_)
        self._table = np.full(16, -1, np.int32)
        self._n = 0

    def add(self, p0: F64, p1: F64, radius: F64, insert: NDArray[np.bool_]
            ) -> NDArray[np.int64]:
        """:func:`repeat_of` of the next piece's moves; ``(m,) int64`` sources."""
        m = len(p0)
        first, n = self._n, self._n + m
        if n > len(self._keys):  # room for twice as many (amortised copies)
            keys = np.empty((max(2 * n, 16), 7), np.int64)
            keys[:first] = self._keys[:first]
            ins = np.empty(len(keys), np.bool_)
            ins[:first] = self._insert[:first]
            self._keys, self._insert = keys, ins
        self._keys[first:n, 0:3] = _bits(p0)
        self._keys[first:n, 3:6] = _bits(p1)
        self._keys[first:n, 6] = np.ascontiguousarray(radius, np.float64).view(np.int64)
        self._insert[first:n] = insert
        src = np.empty(n, np.int64)
        if len(self._table) < 2 * n + 2:  # load <= 1/2: a larger table, refilled
            cap = len(self._table)
            while cap < 2 * n + 2:
                cap *= 2
            self._table = np.full(cap, -1, np.int32)
            first = 0
        _repeat_kernel(self._keys[:n], self._insert[:n], self._table, src, first)
        self._n = n
        return src[self._n - m:]


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
def _slot(keys: I64, i: int, mask: np.uint64) -> np.uint64:
    h = np.uint64(1469598103934665603)
    for c in range(7):
        h = _mix(h, keys[i, c])
    h ^= h >> np.uint64(33)
    h *= np.uint64(0xFF51AFD7ED558CCD)
    h ^= h >> np.uint64(33)
    return h & mask


@njit(cache=True, nogil=True)
def _same(keys: I64, j: int, i: int) -> bool:
    for c in range(7):
        if _word(keys[j, c]) != _word(keys[i, c]):
            return False
    return True


@njit(cache=True, nogil=True)
def _repeat_kernel(keys: I64, insert: NDArray[np.bool_], table: NDArray[np.int32], src: I64,
                   first: int) -> None:
    """Open addressing (linear probing, load <= 1/2; int32 slots, half the memory to miss
    in) over the moves with ``insert``; keys (the floats' bits: start, end, radius) are
    compared exactly, the hash only picks the slot. Moves before ``first`` are in
    ``table`` already."""
    mask = np.uint64(len(table) - 1)
    for i in range(first, len(keys)):
        slot = _slot(keys, i, mask)
        src[i] = -1
        while True:
            j = int(table[slot])
            if j < 0:
                if insert[i]:
                    table[slot] = np.int32(i)
                break
            if _same(keys, j, i):
                src[i] = j
                break
            slot = (slot + np.uint64(1)) & mask
