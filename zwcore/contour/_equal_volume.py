"""Equal-volume contour heights (private; see :func:`place_equal_volume`).

Given a stage's slab-volume function (:class:`zwcore.contour._slabs.SlabVolumes`),
greedy chains of slabs of one volume are run from either end and the volume is
bisected until a chain lands on the far end with a finished slab; the placement
closest to the aimed-at count within the spread tolerance wins.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from zwcore.contour._slabs import QUANTUM, SlabVolumes, ceil_units, floor_units, volume_spread

__all__ = ["EqualVolumeResult", "place_equal_volume"]

F64 = NDArray[np.float64]

# Slab counts tried per chain direction first (next to the aimed-at count).
_COUNTS = 5
# Chains one direction may run in all when the first counts find no even placement and the
# search goes on to counts farther from the aimed-at one (see place_equal_volume).
_RUN_BUDGET = 320


@dataclass(frozen=True)
class EqualVolumeResult:
    """Heights placed by :func:`place_equal_volume`.

    Attributes
    ----------
    heights : list of int
        Contour heights in units of :data:`QUANTUM`, descending, first the top.
    capped : list of bool
        Per slab: the flute cap bound it. Such a slab is exactly the flute length
        (``cap_u`` units) thick and removes less than ``target``, so no slab on
        its bottom height within the flute could remove ``target``; it is exempt
        from equal volume. Every other slab is an equal-volume slab.
    target : float
        Slab volume aimed at, mm³.
    """

    heights: list[int]
    capped: list[bool]
    target: float


@dataclass(frozen=True)
class _Chain:
    """One greedy chain of slabs for a slab volume ``v``.

    ``heights`` end on the bottom; the last slab is unfinished when ``rest > 0``:
    it removes less than ``v`` and is thinner than the flute, ``rest`` being the
    larger of the two fractions. ``phase = finished slabs + rest`` does not
    decrease as ``v`` falls, and a chain with ``phase == n`` is exactly ``n``
    finished slabs (see :func:`place_equal_volume`).
    """

    v: float
    heights: list[int]
    capped: list[bool]
    rest: float
    rest_by_thickness: bool

    @property
    def phase(self) -> float:
        return len(self.capped) - (1.0 if self.rest > 0.0 else 0.0) + self.rest


def _chain(sv: SlabVolumes, top_u: int, bottom_u: int, cap_u: int, v: float,
           limit: int) -> _Chain:
    """Slabs of volume ``v`` from the top down; where none fits the flute, a
    flute-length slab; what is left above the bottom is the unfinished last slab."""
    heights: list[int] = [top_u]
    capped: list[bool] = []
    a_u = top_u
    bottom = bottom_u * QUANTUM
    while a_u > bottom_u:
        if len(capped) >= limit:  # far more slabs than wanted: count the rest as slabs
            heights.append(bottom_u)
            capped.append(False)
            return _Chain(v, heights, capped, 1.0 + (a_u - bottom_u) / cap_u, False)
        a = a_u * QUANTUM
        lo_u = max(bottom_u, a_u - cap_u)
        b = sv.crossing(a, v, lo_u * QUANTUM)
        if b is not None:
            b_u = min(max(ceil_units(b), lo_u), a_u - 1)
            heights.append(b_u)
            capped.append(False)
            a_u = b_u
        elif a_u - cap_u >= bottom_u:
            # No slab within the flute removes v: the cap binds, a flute-length slab.
            a_u -= cap_u
            heights.append(a_u)
            capped.append(True)
        else:
            by_volume = float(sv.volume(a, [bottom])[0]) / v
            by_thickness = (a_u - bottom_u) / cap_u
            heights.append(bottom_u)
            capped.append(False)
            return _Chain(v, heights, capped, max(by_volume, by_thickness, 1e-300),
                          by_thickness >= by_volume)
    return _Chain(v, heights, capped, 0.0, False)


def _chain_up(sv: SlabVolumes, top_u: int, bottom_u: int, cap_u: int, v: float,
              limit: int) -> _Chain:
    """:func:`_chain` from the bottom up, in mirrored units (``-height``), so that
    its unfinished slab is last as well: slabs of volume ``v`` from the bottom
    (:meth:`SlabVolumes.rise`), flute-length slabs where none fits the flute."""
    heights: list[int] = [-bottom_u]
    capped: list[bool] = []
    b_u = bottom_u
    while b_u < top_u:
        if len(capped) >= limit:
            heights.append(-top_u)
            capped.append(False)
            return _Chain(v, heights, capped, 1.0 + (top_u - b_u) / cap_u, False)
        hi_u = min(top_u, b_u + cap_u)
        a = sv.rise(b_u * QUANTUM, v, hi_u * QUANTUM)
        if a is not None:
            b_u = max(min(floor_units(a), hi_u), b_u + 1)
            heights.append(-b_u)
            capped.append(False)
        elif b_u + cap_u <= top_u:
            b_u += cap_u
            heights.append(-b_u)
            capped.append(True)
        else:
            by_volume = float(sv.volume(top_u * QUANTUM, [b_u * QUANTUM])[0]) / v
            by_thickness = (top_u - b_u) / cap_u
            heights.append(-top_u)
            capped.append(False)
            return _Chain(v, heights, capped, max(by_volume, by_thickness, 1e-300),
                          by_thickness >= by_volume)
    return _Chain(v, heights, capped, 0.0, False)


def _slab_volumes(sv: SlabVolumes, heights: Sequence[int]) -> F64:
    return np.array([float(sv.volume(heights[i] * QUANTUM, [heights[i + 1] * QUANTUM])[0])
                     for i in range(len(heights) - 1)])


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
        Number of slabs aimed at (the nominal step-down's count), capped slabs
        included; at least ``ceil((top_u - bottom_u) / cap_u)`` are used.
    rtol : float
        Spread (``max/min - 1`` over the equal-volume slabs) that counts as even;
        beyond it other slab counts are tried.

    Returns
    -------
    EqualVolumeResult

    Notes
    -----
    The rule. Every slab is one of two kinds:

    * an equal-volume slab: it removes ``V`` (the stage's slab volume) and is
      at most the flute length thick;
    * a capped slab: it is exactly the flute length thick and removes less than
      ``V``. Since ``W(a, b)`` grows with the slab's top ``a``, no slab on the
      same bottom height within the flute could remove ``V``: the cap binds
      (the area to cut there is too small).

    There is no third kind, in particular no leftover slab at either end. Where
    ``W`` is flat, nothing is there to remove: below ``bottom_u`` (the lowest
    height the stage lowers a cell to) and above ``top_u``, so the heights never
    leave ``[bottom_u, top_u]``; inside, a band where little or nothing is cut
    is crossed by capped slabs or inside an equal-volume slab. "Equal volume"
    means equal among all slabs that are not capped: the count and ``V`` are
    chosen so that the chain of slabs lands exactly on the far end with a
    finished slab (an equal-volume one, or a capped one of the full flute
    length).

    The search. For a slab volume ``v`` a greedy chain runs from one end: from
    the bottom up (:func:`_chain_up`, tried first: for a fixed bottom ``W`` is
    continuous and monotone in the top, so each slab is exact), or from the top
    down (:func:`_chain`). It cuts slabs of volume ``v``, flute-length slabs
    where none fits the flute, and ends with an unfinished slab whose ``rest``
    is the larger of its volume and thickness fractions. ``phase = finished +
    rest`` falls as ``v`` grows, continuously except where a cell joins or
    leaves a slab; ``v`` is bisected for ``phase = n``. There the unfinished
    slab has just become full (an equal-volume slab) or just reached the flute
    length (a capped slab, re-laid at exactly the flute length from the end,
    which moves the neighbouring equal-volume slab by the small misfit). Where
    a jump skips ``n``, the counts next to ``n_target`` are tried, then the
    other direction; if none is even, counts farther from ``n_target`` in both
    directions, within :data:`_RUN_BUDGET` chains per direction. (A jump may
    skip every count near ``n_target``: a one-cell pit below a wide floor,
    where a slab that crosses the floor's height leaves the floor cells on a
    terrace above it and takes nearly a whole pit slab instead, so ``phase``
    jumps by almost 1 at each count while varying by a few hundredths between
    jumps; the even placements lie a dozen counts away.) Flags are then
    derived from the real volumes (above), and the placement within ``rtol``
    with the count closest to ``n_target`` wins;
    failing that, the most even one, with its real spread.
    """
    span = top_u - bottom_u
    if span <= 0:
        return EqualVolumeResult([top_u], [], 0.0)
    n_min = -(-span // cap_u)
    n_target = max(1, n_target, n_min)
    limit = 4 * n_target + 16
    total = max(sv.total, 1e-300) * (1.0 + 1e-9)
    best: _Ranked | None = None
    counts = _counts(n_target, n_min, limit)
    caches: dict[Callable[..., _Chain], dict[float, _Chain]] = {_chain_up: {}, _chain: {}}
    ends = (top_u, bottom_u, cap_u)
    # The counts next to n_target first, then (only if none of them is even) farther ones,
    # within a budget of chain runs: every count in between may be skipped by a jump.
    for tried, budget in ((counts[:_COUNTS], None), (counts[_COUNTS:], _RUN_BUDGET)):
        for chain in (_chain_up, _chain):
            best = _search_direction(sv, chain, ends, (n_target, limit, tried, budget), total,
                                     rtol, best, caches[chain])
            if best is not None and not best[0][0]:
                return best[1]
    assert best is not None
    return best[1]


#: A placement with its ranking key (see :func:`_judge`).
_Ranked = tuple[tuple[bool, int, float], EqualVolumeResult]


def _search_direction(sv: SlabVolumes, chain: Callable[..., _Chain], ends: tuple[int, int, int],
                      counts: tuple[int, int, list[int], int | None], total: float, rtol: float,
                      best: _Ranked | None, cache: dict[float, _Chain]) -> _Ranked | None:
    """The best placement so far after trying the chains of one direction.

    ``ends`` is ``(top_u, bottom_u, cap_u)``, ``counts`` is ``(n_target, limit, slab
    counts to try in order, budget)``: they are tried until one placement is within
    ``rtol``, or (with a budget) until ``cache``, the chains this direction ran, holds
    that many.
    """
    top_u, bottom_u, cap_u = ends
    n_target, limit, tried, budget = counts
    mirror = chain is _chain_up
    lo_u = -top_u if mirror else bottom_u

    def run(v: float) -> _Chain:
        if v not in cache:
            cache[v] = chain(sv, top_u, bottom_u, cap_u, v, limit)
        return cache[v]

    for n in tried:
        if budget is not None and len(cache) >= budget:
            break
        for cand in _candidates(_solve(run, cache, total, n), lo_u, cap_u):
            if mirror:
                cand = EqualVolumeResult([-x for x in reversed(cand.heights)],
                                         cand.capped[::-1], cand.target)
            res, key = _judge(sv, cand, cap_u, n_target, rtol)
            if best is None or key < best[0]:
                best = (key, res)
        if best is not None and not best[0][0]:
            break
    return best


def _judge(sv: SlabVolumes, cand: EqualVolumeResult, cap_u: int, n_target: int, rtol: float,
           ) -> tuple[EqualVolumeResult, tuple[bool, int, float]]:
    """Honest flags and the ranking key of a placement.

    A slab counts as capped only if it is exactly the flute length thick and
    removes less than the target (so no slab from its bottom height, at most a
    flute long, removes the target: ``W`` grows with the slab's top). The key
    ranks within ``rtol`` first, then the count closest to ``n_target``, then
    the spread.
    """
    h = cand.heights
    vols = _slab_volumes(sv, h)
    capped = [h[i] - h[i + 1] == cap_u and bool(vols[i] < cand.target)
              for i in range(len(h) - 1)]
    spread = volume_spread(vols, capped)
    return (EqualVolumeResult(list(h), capped, cand.target),
            (spread > rtol, abs(len(capped) - n_target), spread))


def _counts(n_target: int, n_min: int, limit: int) -> list[int]:
    """Slab counts to try: ``n_target`` first, then alternately more and fewer."""
    out = [n_target]
    for d in range(1, limit):
        if n_target + d <= limit:
            out.append(n_target + d)
        if n_target - d >= n_min:
            out.append(n_target - d)
    return out


def _solve(run: Callable[[float], _Chain], cache: dict[float, _Chain], total: float,
           n: int) -> list[_Chain]:
    """Chains on both sides of ``phase = n`` (one when a chain hits it exactly).

    The bracket starts from the chains already run (for other counts).
    """
    hi = run(total)  # no slab removes more than everything: all capped, phase <= n_min
    if hi.phase >= n:
        return [hi]
    lo: _Chain | None = None
    for c in cache.values():
        if c.phase >= n and (lo is None or c.v > lo.v):
            lo = c
        elif c.phase < n and c.v < hi.v:
            hi = c
    if lo is None:
        lo_v = total / (2.0 * n)
        lo = run(lo_v)
        for _ in range(60):
            if lo.phase >= n:
                break
            lo_v *= 0.25
            lo = run(lo_v)
        else:
            return [lo]
    while hi.v > lo.v * (1.0 + 1e-10):
        if lo.phase == n:
            return [lo]
        mid = run(math.sqrt(lo.v * hi.v))
        if mid.phase >= n:
            lo = mid
        else:
            hi = mid
    return [lo, hi]


def _candidates(chains: list[_Chain], bottom_u: int, cap_u: int) -> list[EqualVolumeResult]:
    """Finished placements from the chains next to ``phase = n``.

    A nearly full last slab is kept as an equal-volume slab when its volume is
    what filled up; when its thickness did, it becomes a capped slab of exactly
    the flute length. A sliver at the bottom is dropped. Either way the capped
    slabs at the bottom are re-laid at exactly the flute length from the bottom
    up, which moves the lowest equal-volume slab's bottom by the (small) misfit.
    """
    out = []
    for c in chains:
        if c.rest == 0.0:
            out.append(EqualVolumeResult(list(c.heights), list(c.capped), c.v))
            continue
        h, cap = c.heights[:-1], c.capped[:-1]  # the finished slabs
        j = len(cap)
        while j > 0 and cap[j - 1]:
            j -= 1
        run = len(cap) - j  # capped slabs right above the unfinished one
        if c.rest_by_thickness:
            ks = [run + 1, run]
        else:
            out.append(EqualVolumeResult(list(c.heights), list(c.capped), c.v))
            ks = [run]
        for k in ks:
            tail = [bottom_u + i * cap_u for i in range(k, -1, -1)]
            if j == 0:
                ok = tail[0] == h[0]
                heights = tail
            else:
                ok = h[j - 1] > tail[0] and h[j - 1] - tail[0] <= cap_u
                heights = [*h[:j], *tail]
            if ok:
                out.append(EqualVolumeResult(heights, [*cap[:j], *([True] * k)], c.v))
    return out
