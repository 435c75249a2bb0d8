"""Moves that repeat an earlier move exactly (a hash table over their end points, numba).

A scan-line plan's flute-length passes re-follow what the passes before them finished: on
the 1025² part 77 % of the Ø1 ball's moves are, to the last bit, moves it made before. A
move is keyed by its start, its end and its radius. What depends only on that sweep and a
fixed surface (its gouge against the part) is the same for every repeat
(:class:`MoveMemo`), and a repeat of a move that already cut the stock removes nothing: the
stock is already at or under its envelope and only goes down (:func:`repeat_of`). So
neither needs sweeping again, and no result changes.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]
#: The bits of -0.0 (compared and hashed as 0.0).
_NEG_ZERO = np.int64(-(2**63))

__all__ = ["MoveMemo", "repeat_of"]


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


#: Moves looked up before a memo's cost is weighed (:attr:`MoveMemo.active`).
MEMO_TRIAL = 200_000


class MoveMemo:
    """Values of moves measured before (e.g. their gouge against a fixed part), kept across
    calls: a growing hash table over the moves' start and end points (one memo per tool
    and surface). Its users report the seconds its lookups and their sweeps took
    (:meth:`account`) and stop asking (:attr:`active`) once, after :data:`MEMO_TRIAL`
    lookups, the sweeps it saved (its hits at the measured seconds per swept move) cost
    less than it did: short moves on a small part sweep faster than a lookup in a large
    table. The values are the measured ones either way: only the time changes."""

    def __init__(self) -> None:
        self.looked = self.found = 0
        self.cost = self.saved = 0.0
        self.table = np.full(1024, -1, np.int64)
        self.p0: F64 = np.empty((512, 3))
        self.p1: F64 = np.empty((512, 3))
        self.values: F64 = np.empty(512)
        self.size = 0

    def lookup(self, p0: F64, p1: F64) -> NDArray[np.int64]:
        """Row of each move in :attr:`values`, or -1."""
        out = np.empty(len(p0), np.int64)
        _lookup_kernel(self.table, _bits(self.p0), _bits(self.p1), _bits(p0), _bits(p1), out)
        self.looked += len(out)
        self.found += int((out >= 0).sum())
        return out

    def account(self, memo_seconds: float, sweep_seconds: float, found: int, swept: int
                ) -> None:
        """Seconds spent on lookups and stores, and on sweeping ``swept`` moves while
        ``found`` were answered."""
        self.cost += memo_seconds
        self.saved += found * sweep_seconds / max(swept, 1)

    @property
    def active(self) -> bool:
        """Whether the lookups have paid so far (or too few were made to tell)."""
        return self.looked < MEMO_TRIAL or self.saved > self.cost

    def store(self, p0: F64, p1: F64, values: F64) -> None:
        """Remember ``values`` of moves ``p0 -> p1`` (a move already held keeps its row)."""
        n, m = len(p0), self.size
        if m + n > len(self.values):
            cap = max(2 * len(self.values), m + n)
            grown = [np.empty((cap, 3)), np.empty((cap, 3)), np.empty(cap)]
            for new, old in zip(grown, (self.p0, self.p1, self.values), strict=True):
                new[:m] = old[:m]
            self.p0, self.p1, self.values = grown
        self.p0[m:m + n], self.p1[m:m + n], self.values[m:m + n] = p0, p1, values
        if 2 * (m + n) + 2 > len(self.table):  # rehash everything at load <= 1/2
            cap = len(self.table)
            while cap < 2 * (m + n) + 2:
                cap *= 2
            self.table = np.full(2 * cap, -1, np.int64)
            _insert_kernel(self.table, _bits(self.p0), _bits(self.p1), 0, m + n)
        else:
            _insert_kernel(self.table, _bits(self.p0), _bits(self.p1), m, m + n)
        self.size = m + n


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


@njit(cache=True, nogil=True)
def _find(table: I64, s0: I64, s1: I64, q0: I64, q1: I64, i: int, none: I64
          ) -> tuple[int, np.uint64]:
    """(stored row equal to query ``i`` or -1, the slot where the search ended); ``none``
    an empty array (no radius)."""
    mask = np.uint64(len(table) - 1)
    slot = _slot(q0, q1, none, i, mask)
    while True:
        j = table[slot]
        if j < 0 or _same(s0, s1, none, j, q0, q1, none, i):
            return j, slot
        slot = (slot + np.uint64(1)) & mask


@njit(cache=True, nogil=True)
def _lookup_kernel(table: I64, s0: I64, s1: I64, q0: I64, q1: I64, out: I64) -> None:
    none = np.empty(0, np.int64)
    for i in range(len(q0)):
        out[i] = _find(table, s0, s1, q0, q1, i, none)[0]


@njit(cache=True, nogil=True)
def _insert_kernel(table: I64, s0: I64, s1: I64, a: int, b: int) -> None:
    """Enter stored rows ``a..b-1`` (a row equal to one held already is skipped)."""
    none = np.empty(0, np.int64)
    for i in range(a, b):
        j, slot = _find(table, s0, s1, s0, s1, i, none)
        if j < 0:
            table[slot] = i
