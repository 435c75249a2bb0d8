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

__all__ = ["MoveMemo", "move_keys", "repeat_of"]


def move_keys(p0: F64, p1: F64, radius: F64 | float | None = None) -> NDArray[np.int64]:
    """``(n, 7)`` int64 keys (``(n, 6)`` without a radius): the bits of the start, the end
    and the radius (``-0.0`` made ``0.0``). Direction counts: the same volume swept
    backwards can differ in the last bit of a node's envelope, and skipping a repeat is to
    change no bit."""
    n = len(p0)
    out = np.empty((n, 6 if radius is None else 7))
    out[:, :3] = p0
    out[:, 3:6] = p1
    if radius is not None:
        out[:, 6] = radius
    out += 0.0  # -0.0 + 0.0 is 0.0
    return out.view(np.int64)


def repeat_of(keys: NDArray[np.int64], insert: NDArray[np.bool_]) -> NDArray[np.int64]:
    """For each row, the first earlier row with ``insert`` and the same key, else -1.

    Parameters
    ----------
    keys : (n, k) int64
    insert : (n,) bool
        Rows that later rows may repeat (e.g. moves that cut).

    Returns
    -------
    (n,) int64
        In program order: ``src[i] < i`` with ``insert[src[i]]`` and equal keys, or -1.
    """
    src = np.empty(len(keys), np.int64)
    _repeat_kernel(np.ascontiguousarray(keys, np.int64), np.ascontiguousarray(insert, np.bool_),
                   src)
    return src


@njit(cache=True, nogil=True)
def _repeat_kernel(keys: NDArray[np.int64], insert: NDArray[np.bool_],
                   src: NDArray[np.int64]) -> None:
    """Open addressing (linear probing, load <= 1/2) over the rows with ``insert``; keys are
    compared exactly, the hash only picks the slot."""
    n, m = keys.shape
    cap = 16
    while cap < 2 * n + 2:
        cap *= 2
    mask = np.uint64(cap - 1)
    table = np.full(cap, -1, np.int64)
    for i in range(n):
        h = np.uint64(1469598103934665603)
        for c in range(m):
            h = (h ^ np.uint64(keys[i, c])) * np.uint64(1099511628211)
        h ^= h >> np.uint64(33)
        h *= np.uint64(0xFF51AFD7ED558CCD)
        h ^= h >> np.uint64(33)
        slot = h & mask
        src[i] = -1
        while True:
            j = table[slot]
            if j < 0:
                if insert[i]:
                    table[slot] = i
                break
            same = True
            for c in range(m):
                if keys[j, c] != keys[i, c]:
                    same = False
                    break
            if same:
                src[i] = j
                break
            slot = (slot + np.uint64(1)) & mask


class MoveMemo:
    """Values of moves measured before (e.g. their gouge against a fixed part), kept across
    calls: a growing hash table over the moves' keys (:func:`move_keys` without the
    radius: one memo per tool and surface)."""

    def __init__(self) -> None:
        self.table = np.full(1024, -1, np.int64)
        self.keys = np.empty((512, 6), np.int64)
        self.values = np.empty(512)
        self.size = 0

    def lookup(self, keys: NDArray[np.int64]) -> NDArray[np.int64]:
        """Row of each key in :attr:`values`, or -1."""
        out = np.empty(len(keys), np.int64)
        _lookup_kernel(self.table, self.keys, np.ascontiguousarray(keys, np.int64), out)
        return out

    def store(self, keys: NDArray[np.int64], values: NDArray[np.float64]) -> None:
        """Remember ``values`` of moves ``keys`` (rows not already held)."""
        n = len(keys)
        if self.size + n > len(self.keys):
            cap = max(2 * len(self.keys), self.size + n)
            k, v = np.empty((cap, 6), np.int64), np.empty(cap)
            k[:self.size], v[:self.size] = self.keys[:self.size], self.values[:self.size]
            self.keys, self.values = k, v
        self.keys[self.size:self.size + n] = keys
        self.values[self.size:self.size + n] = values
        if 2 * (self.size + n) + 2 > len(self.table):  # rehash everything at load <= 1/2
            cap = len(self.table)
            while cap < 2 * (self.size + n) + 2:
                cap *= 2
            self.table = np.full(2 * cap, -1, np.int64)
            _insert_kernel(self.table, self.keys, 0, self.size + n)
        else:
            _insert_kernel(self.table, self.keys, self.size, self.size + n)
        self.size += n


@njit(cache=True, nogil=True)
def _slot(keys: NDArray[np.int64], i: int, mask: np.uint64) -> np.uint64:
    h = np.uint64(1469598103934665603)
    for c in range(keys.shape[1]):
        h = (h ^ np.uint64(keys[i, c])) * np.uint64(1099511628211)
    h ^= h >> np.uint64(33)
    h *= np.uint64(0xFF51AFD7ED558CCD)
    h ^= h >> np.uint64(33)
    return h & mask


@njit(cache=True, nogil=True)
def _find(table: NDArray[np.int64], stored: NDArray[np.int64], keys: NDArray[np.int64],
          i: int) -> tuple[int, np.uint64]:
    """(row holding key ``i`` or -1, the slot where the search ended)."""
    mask = np.uint64(len(table) - 1)
    slot = _slot(keys, i, mask)
    while True:
        j = table[slot]
        if j < 0:
            return -1, slot
        same = True
        for c in range(keys.shape[1]):
            if stored[j, c] != keys[i, c]:
                same = False
                break
        if same:
            return j, slot
        slot = (slot + np.uint64(1)) & mask


@njit(cache=True, nogil=True)
def _lookup_kernel(table: NDArray[np.int64], stored: NDArray[np.int64],
                   keys: NDArray[np.int64], out: NDArray[np.int64]) -> None:
    for i in range(len(keys)):
        out[i] = _find(table, stored, keys, i)[0]


@njit(cache=True, nogil=True)
def _insert_kernel(table: NDArray[np.int64], stored: NDArray[np.int64], a: int, b: int
                   ) -> None:
    """Enter rows ``a..b-1`` of ``stored`` (a row equal to one held already is skipped)."""
    for i in range(a, b):
        j, slot = _find(table, stored, stored, i)
        if j < 0:
            table[slot] = i
