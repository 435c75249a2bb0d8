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
below any machine resolution). Every terrace value is then a multiple of the
quantum, so the lifted Haar transform of a terraced model (maxima, halved
differences and their sums) is exact in float64 and synthesis reproduces the
terraces bit for bit (design 4.5).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "QUANTUM",
    "EqualVolumeResult",
    "SlabVolumes",
    "ceil_units",
    "even_heights",
    "floor_units",
    "place_equal_volume",
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


@dataclass(frozen=True)
class EqualVolumeResult:
    """Heights placed by :func:`place_equal_volume`.

    Attributes
    ----------
    heights : list of int
        Contour heights in units of :data:`QUANTUM`, descending, first the top.
    capped : list of bool
        Per slab: its thickness was set by the flute length (a would-be slab
        thicker than the flute, split evenly), so it is exempt from equal volume.
    target : float
        Slab volume aimed at, mm³.
    """

    heights: list[int]
    capped: list[bool]
    target: float


def _greedy(sv: SlabVolumes, top_u: int, bottom_u: int, cap_u: int, target: float,
            limit: int) -> tuple[list[int], list[bool]]:
    """Slabs of volume ``target`` from the top down; capped runs split evenly."""
    heights: list[int] = [top_u]
    capped: list[bool] = []
    a_u = top_u
    bottom = bottom_u * QUANTUM
    while a_u > bottom_u and len(capped) <= limit:
        a = a_u * QUANTUM
        lo_u = max(bottom_u, a_u - cap_u)
        b = sv.crossing(a, target, lo_u * QUANTUM)
        if b is not None:
            b_u = min(max(ceil_units(b), lo_u), a_u - 1)
            heights.append(b_u)
            capped.append(False)
            a_u = b_u
            continue
        if lo_u == bottom_u:
            # The rest is less than one slab. It counts as capped when even a
            # flute-length slab above the bottom could not remove the target
            # (the deepest cells have too little area): then the flute length,
            # not the placement, limits its volume.
            reach_u = min(top_u, bottom_u + cap_u)
            reach = float(sv.volume(reach_u * QUANTUM, [bottom])[0])
            heights.append(bottom_u)
            capped.append(reach < target * (1.0 - 1e-9))
            break
        # The flute cap binds: find where the slab would end and split it evenly.
        b = sv.crossing(a, target, bottom)
        end_u = bottom_u if b is None else max(ceil_units(b), bottom_u)
        pieces = -(-(a_u - end_u) // cap_u)
        heights.extend(even_heights(a_u, end_u, pieces)[1:])
        capped.extend([True] * pieces)
        a_u = end_u
    return heights, capped


def _slab_volumes(sv: SlabVolumes, heights: Sequence[int]) -> F64:
    return np.array([float(sv.volume(heights[i] * QUANTUM, [heights[i + 1] * QUANTUM])[0])
                     for i in range(len(heights) - 1)])


def volume_spread(volumes: ArrayLike, capped: ArrayLike) -> float:
    """``max/min - 1`` over the slabs the flute cap does not bind (0 for fewer than two)."""
    v = np.asarray(volumes, dtype=np.float64)[~np.asarray(capped, dtype=bool)]
    if v.size < 2:
        return 0.0
    lo = float(v.min())
    if lo <= 0.0:
        return math.inf
    return float(v.max()) / lo - 1.0


def place_equal_volume(sv: SlabVolumes, top_u: int, bottom_u: int, cap_u: int,
                       n_target: int, *, rtol: float = 1e-2) -> EqualVolumeResult:
    """Contour heights from ``top_u`` down to ``bottom_u`` whose slabs remove equal volumes.

    Parameters
    ----------
    sv : SlabVolumes
        The stage's slab-volume function.
    top_u, bottom_u : int
        First and last contour height, units of :data:`QUANTUM`.
    cap_u : int
        Flute length in units: no spacing exceeds it.
    n_target : int
        Number of slabs aimed at (the nominal step-down's count); the achieved
        count may differ by the slabs the flute cap splits.
    rtol : float
        Spread (``max/min - 1``) that counts as even; a placement beyond it
        triggers the wider search described below.

    Returns
    -------
    EqualVolumeResult

    Notes
    -----
    For a slab volume ``V`` the greedy pass cuts slabs of exactly ``V`` from the
    top (:meth:`SlabVolumes.crossing`); the last slab holds what is left. The
    count falls as ``V`` grows, and at the ``V`` where it drops to ``n_target``
    the last slab is full too, so ``V`` is bisected (geometrically) for that
    transition. Candidates on both sides are compared by their real slab
    volumes, together with the variant that merges a sliver of a last slab into
    the one above when the flute allows, and the most even one wins.

    With few cells the count can jump past ``n_target`` without the last slab
    filling (the first crossing jumps when a cell leaves the sum). Then the slab
    volume is scanned over ``total / (4 n + 4) .. total`` and the count
    transitions found are bisected, nearest to ``n_target`` first, until a
    chain within ``rtol`` appears; otherwise the most even one is returned and
    its spread reported.
    """
    span = top_u - bottom_u
    if span <= 0:
        return EqualVolumeResult([top_u], [], 0.0)
    n_target = max(1, n_target)
    limit = 4 * n_target + 4 * (-(-span // cap_u)) + 16

    def run(v: float) -> tuple[list[int], list[bool]]:
        return _greedy(sv, top_u, bottom_u, cap_u, v, limit)

    total = max(sv.total, 1e-300) * (1.0 + 1e-9)
    best = _best_of(sv, _bracket(run, total, n_target), cap_u, n_target, rtol)
    if not best[0][0]:
        return best[1]
    # Discrete cell heights can leave no even chain at the nominal count (the
    # last slab's volume jumps rather than fills). Scan the slab volume over a
    # wide range and refine every count transition found, nearest counts first,
    # until one is even; the flute cap holds in every candidate.
    volumes = np.geomspace(total / (4.0 * n_target + 4.0), total, 48)
    grid = [(float(v), run(float(v))) for v in volumes]
    best = min(best, _best_of(sv, grid, cap_u, n_target, rtol), key=lambda b: b[0])
    pairs = [(grid[i], grid[i + 1]) for i in range(len(grid) - 1)
             if len(grid[i][1][1]) > len(grid[i + 1][1][1])]
    pairs.sort(key=lambda p: abs(len(p[1][1][1]) - n_target))
    for lo, hi in pairs[:8]:
        if not best[0][0]:
            break
        cands = _bisect(run, lo, hi, len(hi[1][1]))
        best = min(best, _best_of(sv, cands, cap_u, n_target, rtol), key=lambda b: b[0])
    return best[1]


Run = tuple[float, tuple[list[int], list[bool]]]


def _bisect(run: Callable[[float], tuple[list[int], list[bool]]], lo: Run, hi: Run,
            n: int) -> list[Run]:
    """Narrow ``lo`` (more than ``n`` slabs) and ``hi`` (at most ``n``) onto the transition."""
    (lo_v, lo_run), (hi_v, hi_run) = lo, hi
    while hi_v > lo_v * (1.0 + 1e-10):
        mid = math.sqrt(lo_v * hi_v)
        res = run(mid)
        if len(res[1]) > n:
            lo_v, lo_run = mid, res
        else:
            hi_v, hi_run = mid, res
    return [(hi_v, hi_run), (lo_v, lo_run)]


def _bracket(run: Callable[[float], tuple[list[int], list[bool]]], total: float, n: int,
             ) -> list[Run]:
    """Greedy runs on both sides of the slab volume at which the count drops to ``n``."""
    hi_v = total
    hi_run = run(hi_v)
    if len(hi_run[1]) > n:
        return [(hi_v, hi_run)]  # the flute cap alone needs more slabs
    lo_v = hi_v / (8.0 * n)
    lo_run = run(lo_v)
    for _ in range(20):
        if len(lo_run[1]) > n:
            break
        lo_v *= 0.25
        lo_run = run(lo_v)
    else:
        return [(lo_v, lo_run)]
    # At the transition the last slab is as full as it gets.
    return _bisect(run, (lo_v, lo_run), (hi_v, hi_run), n)


def _best_of(sv: SlabVolumes, candidates: list[Run],
             cap_u: int, n_target: int, rtol: float,
             ) -> tuple[tuple[bool, int, float], EqualVolumeResult]:
    """The most even candidate: within ``rtol`` first, then closest count, then spread."""
    best: tuple[tuple[bool, int, float], EqualVolumeResult] | None = None
    for v, (heights, capped) in candidates:
        options = [(heights, capped)]
        # A sliver left at the bottom: merge it into the slab above if the flute allows.
        if len(capped) >= 2 and not capped[-2] and heights[-3] - heights[-1] <= cap_u:
            options.append((heights[:-2] + heights[-1:], [*capped[:-2], False]))
        for h, c in options:
            spread = volume_spread(_slab_volumes(sv, h), c)
            key = (spread > rtol, abs(len(c) - n_target), spread)
            if best is None or key < best[0]:
                best = (key, EqualVolumeResult(list(h), list(c), v))
    assert best is not None
    return best


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
