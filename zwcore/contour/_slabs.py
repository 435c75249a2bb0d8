"""Contour heights for waterline roughing: the slab-volume function and the
placement of heights (design section 4, steps 3 and 4; seed 000, 6.3 and Fig. 7).

A stage cuts the cells of its level model ``L`` from the previous stage model
``P`` (``L <= P`` cell by cell) with a flat end mill at contour heights
``z_0 > z_1 > ... > z_n``. At height ``b`` the tool can enter every cell whose
level model is at or below ``b`` (the level was chosen so that each cell is
wide enough for the tool), so a cell ends on the lowest contour height at or
above its level model (a terrace), and the slab ``[b, a]`` between two
consecutive heights removes

    W(a, b) = sum over cells with L <= b < P of  w * (min(P, a) - b)

(``w`` is the area of the input nodes a cell covers). As ``b`` falls, ``W``
grows continuously and drops only where cells leave the sum (``b`` passes below
their ``L``); it is continuous from above at those drops. Hence whenever
``W(a, lo) >= V > W(a, hi)`` there is an exact ``b`` in ``[lo, hi)`` with
``W(a, b) = V``, which is what the equal-volume placement solves for.

Heights are handled in integer units of :data:`QUANTUM` (``2**-24`` mm, far
below any machine resolution); a height is rounded up from any level-model
value it came from, so a terrace never moves into the part.

Where the flute cap binds and what "equal volume" means where ``W`` is flat
(nothing to remove) is stated in :func:`place_equal_volume`.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "QUANTUM",
    "SlabVolumes",
    "ceil_units",
    "even_heights",
    "floor_units",
    "removed_between",
    "volume_spread",
]

F64 = NDArray[np.float64]

#: Height quantum in mm. With heights below 2**20 mm (``MAX_ABS_HEIGHT``) every
#: Haar coefficient of quantised terraces needs at most 49 significant bits.
QUANTUM = 2.0 ** -24

# Candidate heights evaluated per refinement round of the crossing search.
_GRID = 128
# Breakpoints below which a bracket is searched exactly rather than on a grid.
_EXACT = 256


def ceil_units(z: float) -> int:
    """Smallest multiple of :data:`QUANTUM` at or above ``z``, in units.

    Rounding up keeps a height on or above any level-model value it was derived
    from, so a terrace never moves into the part.
    """
    return math.ceil(z / QUANTUM)  # z / 2**-24 is exact


def floor_units(z: float) -> int:
    """Largest multiple of :data:`QUANTUM` at or below ``z``, in units."""
    return math.floor(z / QUANTUM)


def even_heights(top_u: int, bottom_u: int, n: int) -> list[int]:
    """``n`` slabs from ``top_u`` to ``bottom_u`` (units), as even as whole units allow.

    Each spacing is ``floor`` or ``ceil`` of ``(top_u - bottom_u) / n``, so it
    never exceeds a cap ``c`` whenever ``n >= ceil((top_u - bottom_u) / c)``.
    """
    span = top_u - bottom_u
    return [top_u - (i * span) // n for i in range(n + 1)]


class SlabVolumes:
    """The slab-volume function ``W(a, b)`` of one stage (see the module docstring).

    Parameters
    ----------
    lower : (m,) float64
        Level-model height ``L`` of every cell the stage has to cut.
    upper : (m,) float64
        Previous stage model ``P`` over the same cells, ``P > L``. It holds few
        distinct values (earlier contour heights), which the evaluation uses.
    weight : (m,) float64
        Area of the input nodes each cell covers, mm².

    Notes
    -----
    Cells are grouped by ``P``; within a group they are ranked by ``L`` and
    their weights summed cumulatively under one integer key ``group * (D + 1) +
    rank``, so the weight of every group below any set of heights is a single
    ``searchsorted``: ``O(G * k * log m)`` for ``k`` heights and ``G`` groups.
    """

    def __init__(self, lower: F64, upper: F64, weight: F64) -> None:
        self.levels: F64 = np.unique(lower)
        rank = np.searchsorted(self.levels, lower)
        tops, group = np.unique(upper, return_inverse=True)
        self.tops: F64 = tops
        stride = self.levels.size + 1
        key = group.astype(np.int64).ravel() * stride + rank
        order = np.argsort(key, kind="stable")
        self._key = key[order]
        self._cw = np.concatenate(([0.0], np.cumsum(weight[order])))
        self._base = np.arange(tops.size, dtype=np.int64) * stride
        self._start = self._cw[np.searchsorted(self._key, self._base)]
        self._breaks: F64 = np.unique(np.concatenate((self.levels, tops)))
        self.total = float(np.sum(weight * (upper - lower)))

    def _below(self, b: F64) -> F64:
        """``(G, k)``: weight of each group's cells with ``L <= b``."""
        r = np.searchsorted(self.levels, b, side="right")
        idx = np.searchsorted(self._key, self._base[:, None] + r[None, :])
        out: F64 = self._cw[idx] - self._start[:, None]
        return out

    def _volume(self, a: float, b: F64) -> tuple[F64, F64]:
        below = self._below(b)
        depth = np.minimum(self.tops, a)[:, None] - b[None, :]
        out: F64 = (below * np.maximum(depth, 0.0)).sum(axis=0)
        return out, below

    def volume(self, a: float, b: ArrayLike) -> F64:
        """``W(a, b)`` for each ``b < a``: what the slab ``[b, a]`` removes, mm³."""
        return self._volume(a, np.atleast_1d(np.asarray(b, dtype=np.float64)))[0]

    def rise(self, b: float, target: float, hi_limit: float) -> float | None:
        """The lowest ``a`` in ``(b, hi_limit]`` with ``W(a, b) = target``, else ``None``.

        For a fixed bottom ``b`` the slab's cells are fixed (``L <= b < P``) and
        ``W(a, b)`` is continuous, piecewise linear and non-decreasing in ``a``
        with breakpoints at the group tops ``P``, so ``a`` is exact.
        """
        below = self._below(np.array([b]))[:, 0]
        act = (self.tops > b) & (below > 0.0)
        t, w = self.tops[act], below[act]
        if t.size == 0:
            return None
        rate = np.cumsum(w[::-1])[::-1]  # weight of the groups still rising above t[k-1]
        done = np.concatenate(([0.0], np.cumsum(w * (t - b))))[:-1]
        at_t = done + rate * (t - b)  # W(t[k], b)
        k = int(np.searchsorted(at_t, target, side="left"))
        if k == t.size:
            return None
        a = b + (target - done[k]) / rate[k]
        return a if a <= hi_limit else None

    def crossing(self, a: float, target: float, lo_limit: float) -> float | None:
        """A height ``b`` in ``[lo_limit, a)`` with ``W(a, b) = target``.

        Candidate heights are scanned from the top, bracketing the first one
        whose slab reaches ``target``; the bracket is refined on a grid until it
        holds few breakpoints (cell heights ``L`` and ``P``), then on those, and
        ``W`` is linear between the last two, which gives ``b`` exactly (to
        rounding). Returns ``None`` when no candidate reaches ``target``.
        """
        hi, lo = a, lo_limit
        if not lo < hi:
            return None
        for _ in range(16):
            i0 = np.searchsorted(self._breaks, lo, side="right")
            i1 = np.searchsorted(self._breaks, hi, side="left")
            exact = i1 - i0 <= _EXACT
            if exact:
                pts = np.concatenate((self._breaks[i0:i1][::-1], [lo]))
            else:
                pts = np.linspace(hi, lo, _GRID + 1)[1:]
            vals, below = self._volume(a, pts)
            hit = np.flatnonzero(vals >= target)
            if hit.size == 0:
                return None  # only in the first round: later ones end on a hit
            i = int(hit[0])
            lo_new, w_lo = float(pts[i]), float(vals[i])
            hi = float(pts[i - 1]) if i > 0 else hi
            lo = lo_new
            if exact or hi - lo <= 0.0:
                break
        # No breakpoint strictly inside (lo, hi): the cells with L <= lo and
        # P >= hi are cut all through, so W(b) = W(lo) - N * (b - lo).
        n = float(below[:, i][self.tops >= hi].sum())
        if n <= 0.0:
            return lo
        return min(max(lo + (w_lo - target) / n, lo), hi)


def volume_spread(volumes: ArrayLike, capped: ArrayLike) -> float:
    """``max/min - 1`` over the slabs the flute cap does not bind (0 for fewer than two)."""
    v = np.asarray(volumes, dtype=np.float64)[~np.asarray(capped, dtype=bool)]
    if v.size < 2:
        return 0.0
    lo = float(v.min())
    if lo <= 0.0:
        return math.inf
    return float(v.max()) / lo - 1.0


def removed_between(upper: F64, lower: F64, weight: F64, heights: ArrayLike) -> F64:
    """Volume between two models inside each slab of a descending height list.

    Parameters
    ----------
    upper, lower : (m,) float64
        Previous and new model over the same cells, ``lower <= upper``.
    weight : (m,) float64
        Cell areas, mm².
    heights : (n + 1,) float64
        Contour heights, descending.

    Returns
    -------
    (n,) float64
        ``sum w * |[lower, upper] ∩ [z_{i+1}, z_i]|`` per slab: what the slab
        really removes. Material above the first or below the last height falls
        in no slab.

    Notes
    -----
    ``U(z) = sum w * ((upper - z)+ - (lower - z)+)`` is the volume between the
    models above ``z``; a slab's volume is ``U(z_{i+1}) - U(z_i)``. Each ``(X -
    z)+`` sum comes from sorted ``X`` and suffix sums, so all slabs cost one
    sort.
    """
    z = np.asarray(heights, dtype=np.float64)

    def above(x: F64) -> F64:
        order = np.argsort(x)
        xs, ws = x[order], weight[order]
        sw = np.concatenate((np.cumsum((ws * xs)[::-1])[::-1], [0.0]))
        s1 = np.concatenate((np.cumsum(ws[::-1])[::-1], [0.0]))
        i = np.searchsorted(xs, z, side="right")
        out: F64 = sw[i] - z * s1[i]
        return out

    u = above(upper) - above(lower)
    out: F64 = u[1:] - u[:-1]
    return out
