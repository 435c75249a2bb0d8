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
# Slab counts tried per chain direction before settling for the most even placement.
_COUNTS = 5


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
    other direction. Flags are then derived from the real volumes (above), and
    the placement within ``rtol`` with the count closest to ``n_target`` wins;
    failing that, the most even one, with its real spread.
    """
    span = top_u - bottom_u
    if span <= 0:
        return EqualVolumeResult([top_u], [], 0.0)
    n_min = -(-span // cap_u)
    n_target = max(1, n_target, n_min)
    limit = 4 * n_target + 16
    total = max(sv.total, 1e-300) * (1.0 + 1e-9)
    best: tuple[tuple[bool, int, float], EqualVolumeResult] | None = None
    for chain in (_chain_up, _chain):
        mirror = chain is _chain_up
        lo_u = -top_u if mirror else bottom_u
        cache: dict[float, _Chain] = {}

        def run(v: float, chain: Callable[..., _Chain] = chain, cache: dict[float, _Chain] = cache,
                ) -> _Chain:
            if v not in cache:
                cache[v] = chain(sv, top_u, bottom_u, cap_u, v, limit)
            return cache[v]

        for n in _counts(n_target, n_min, limit)[:_COUNTS]:
            for cand in _candidates(_solve(run, cache, total, n), lo_u, cap_u):
                if mirror:
                    cand = EqualVolumeResult([-x for x in reversed(cand.heights)],
                                             cand.capped[::-1], cand.target)
                res, key = _judge(sv, cand, cap_u, n_target, rtol)
                if best is None or key < best[0]:
                    best = (key, res)
            if best is not None and not best[0][0]:
                break
        if best is not None and not best[0][0]:
            break
    assert best is not None
    return best[1]


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
