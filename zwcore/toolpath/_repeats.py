"""Moves that repeat an earlier move exactly (a hash table over their end points, numba).

A scan-line plan's flute-length passes re-follow what the passes before them finished: on
the 1025² part 77 % of the Ø1 ball's moves are, to the last bit, moves it made before. A move is keyed by its
start, its end and its radius. What depends only on that volume and a fixed surface (its
gouge against the part) is the same for every repeat, and a repeat of a move that already
cut the stock removes nothing (the stock is already at or under its envelope and only goes
down), so sweeping it again can be skipped without changing any result.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

F64 = NDArray[np.float64]

__all__ = ["move_keys", "repeat_of"]


def move_keys(p0: F64, p1: F64, radius: F64) -> NDArray[np.int64]:
    """``(n, 7)`` int64 keys: the bits of the start, the end and the radius (``-0.0`` made
    ``0.0``). Direction counts: the same volume swept backwards can differ in the last bit
    of a node's envelope, and skipping a repeat is to change no bit."""
    p0 = np.asarray(p0, np.float64) + 0.0
    p1 = np.asarray(p1, np.float64) + 0.0
    r = np.broadcast_to(np.asarray(radius, np.float64), (len(p0),)) + 0.0
    return np.ascontiguousarray(np.column_stack([p0, p1, r])).view(np.int64)


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
