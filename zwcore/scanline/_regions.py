"""Finishing balls by simulated reach, and the rest region each smaller ball works in.

The finishing sequence is a *chain* of library balls ``b_0 > b_1 > ... > b_n``:

- ``b_0`` (the main finishing ball) machines the whole part;
- each later ball ``b_i`` machines only its rest region. Its seed: the nodes where the
  previous ball ``b_{i-1}`` leaves more than ``tolerance`` above the part *and* ``b_i``
  does better there by more than ``tolerance`` (``rest_{i-1} - rest_i > tolerance``; the
  comparison discounts position cusps, see :mod:`._reach`: they are common to both
  balls, larger for the smaller one, so they never send a small ball along a wall). Its
  region: the positions within ``b_i``'s radius of the seed whose ball, at its nodal CL
  on the part, cuts into the material ``b_{i-1}`` leaves
  (:class:`zwcore.scanline._reach_cut.CuttingRegion`), as the plan's rest rule
  (:mod:`zwcore.scanline._rest`) takes it on the simulated stock: not the whole seed
  grown by the radius, which counts positions beside a crease or across a wall that cut
  nothing.
- the chain ends where no smaller library ball does better anywhere.

Rest comes from :func:`zwcore.scanline._reach.ball_reach` (nodal closing). A ball of
radius ``R`` is evaluated on every ``k``-th node, ``k`` the largest power of two with
``R / (k * spacing) >= LATTICE_CELLS`` (its footprint stays a few hundred nodes, and a
ball that large does not see detail finer than ``R / 8`` anyway); nodes closer than
``k`` cells to a point sharper than ``k`` cells (detail the lattice can miss) are added
to its rest region, so nothing a coarse lattice skips is left unassigned. A pair of
balls is compared on the smaller ball's (finer) lattice, the larger ball's rest carried
there as the lesser of two bilinear interpolants (rest; closing less the fine part).

Which chain: the one with the shortest estimated finishing *time*
(:mod:`zwcore.scanline._chain_time`: per ball its passes (the flute rule on the material
it meets), its region's cut length at the pick-feed that holds the tolerance on the
part's slopes over the feed, and per stretch of the region along the scan lines an
entry and exit at the plunge feed and rapid; the program's own time formula), plus
:data:`TOOL_CHANGE_MIN` per tool change, by dynamic programming over (previous ball,
next ball) pairs, a pair skipped when a lower bound of its cost (its cost after a
smaller previous ball) cannot win. The main ball meets at least what the next larger
library ball leaves (the roughing before it is that ball or a larger one).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from functools import partial

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from zwcore.grid.tools import Tool
from zwcore.scanline._chain_time import (
    SCALLOP_FLUTE_SHARE,
    BallTime,
    Feeds,
    ball_time,
    flat_pick_feed,
    stock_met,
)
from zwcore.scanline._reach import ball_reach, concave_radii, within_distance
from zwcore.scanline._reach_cut import CuttingRegion, material_grid
from zwcore.scanline._reach_grid import _pool_any, _upsample_where
from zwcore.scanline._threads import both, each, split
from zwcore.sim import RegionBox

__all__ = ["TOOL_CHANGE_MIN", "TOOL_CHANGE_MM", "Chain", "MainBall", "finishing_chain",
           "flat_pick_feed", "region_boxes"]

F64 = NDArray[np.float64]
B8 = NDArray[np.bool_]

#: A ball is evaluated on a lattice where it spans at least this many cells.
LATTICE_CELLS = 6.0

#: Detail sharper than this share of a ball's lattice spacing (concave radius at the
#: input nodes) may fall between its lattice nodes: it goes to the next ball.
SHARP_SHARE = 0.25

#: A tool change (stop, change, measure, approach) costs as much finishing time as
#: cutting this length, mm (about 7 s at a 2,000 mm/min finishing feed).
TOOL_CHANGE_MM = 250.0

#: A tool change in the chain's time ranking, minutes (stop, change, measure the length,
#: approach: about 15 s on a machining centre; the program's estimate counts moves only).
TOOL_CHANGE_MIN = 0.25

#: The roughing ball before a main ball is taken as the largest library ball of at most
#: this many times its radius (the pyramid's levels double the spacing).
ROUGHING_RATIO = 2.0

#: Most region boxes listed per stage (largest first).
MAX_BOXES = 64


@dataclass(frozen=True)
class MainBall:
    """The chain's main ball (it machines the whole part) and its estimated figures.

    Attributes
    ----------
    tool : Tool
    cut_length : float
        Part area / flat pick-feed at ``tolerance``, mm.
    rest_max : float
        Most material left over the part after this ball, mm.
    reason : str
    """

    tool: Tool
    cut_length: float
    rest_max: float
    reason: str


@dataclass(frozen=True, eq=False)
class Chain:
    """The finishing chain and the figures of its choice.

    Attributes
    ----------
    balls : tuple of Tool
        The chain's balls, main ball first.
    main : MainBall
    smallest_everywhere : float
        Cut length if the smallest library ball finished the whole part, mm.
    rho : (ny, nx) float64
        The part's concave radii (:func:`zwcore.scanline._reach.concave_radii`), for the
        rest rules and the reach figures (computed once per plan).
    """

    balls: tuple[Tool, ...]
    main: MainBall
    smallest_everywhere: float
    rho: F64


def lattice(radius: float, dx: float, dy: float) -> int:
    """Largest power of two ``k`` with ``radius / (k * max(dx, dy)) >= LATTICE_CELLS``."""
    k = 1
    while radius / (2 * k * max(dx, dy)) >= LATTICE_CELLS:
        k *= 2
    return k


@dataclass(eq=False)
class _Material:
    """What one ball leaves, on a (finer) lattice: its rest ``(my, mx)``, the flat indices
    of the nodes where that exceeds the tolerance, the material's heights there (-inf
    elsewhere) and their block maxima (:func:`~zwcore.scanline._reach_cut.material_grid`)."""

    rest: F64
    nodes: NDArray[np.int64]
    heights: F64
    blocks: F64


class _Reach:
    """Rest maps per (ball, lattice), computed once."""

    def __init__(self, z: F64, dx: float, dy: float, tolerance: float,
                 feeds: Feeds | None = None) -> None:
        self.z, self.dx, self.dy, self.tol = z, dx, dy, tolerance
        self.feeds = Feeds() if feeds is None else feeds
        #: the estimate of every pair costed, ``(previous radius, next tool id)``; the
        #: main balls' under ``(inf, tool id)``
        self.times: dict[tuple[float, str], BallTime] = {}
        self.rho = concave_radii(z, dx, dy)
        self._rest: dict[tuple[float, int], F64] = {}
        self._cutting: dict[tuple[float, int], CuttingRegion] = {}
        self._cl: dict[tuple[float, int], F64 | None] = {}
        self._safe: dict[tuple[int, int, float], tuple[B8, NDArray[np.int64]] | None] = {}
        self._rho: dict[int, F64] = {1: self.rho}
        self._safety: dict[int, B8] = {}
        self._pooled: dict[tuple[int, int], B8] = {}
        self._last_prev = math.nan
        self._material: dict[int, _Material] = {}

    def rest(self, radius: float, k: int) -> F64:
        key = (radius, k)
        if key not in self._rest:
            zk = self.z[::k, ::k]
            if k not in self._rho:
                self._rho[k] = concave_radii(zk, k * self.dx, k * self.dy)
            got = ball_reach(zk, k * self.dx, k * self.dy, radius, self.tol, self._rho[k])
            self._cl[key] = got.cl  # (before the rest: a thread that finds the rest
            self._rest[key] = got.rest  # finds the CL too)
        return self._rest[key]

    def main_times(self, balls: list[Tool]) -> list[BallTime]:
        """:meth:`main_time` of every ball, on two threads (:mod:`._threads`): first every
        ball's rest on its lattice (the nodal closings, most of the work), then the
        estimates (their kernels), each a task the threads share, costliest first (the
        finest lattices). The same figures as one by one: each task's result depends on
        the part and the ball alone, and the caches hold the same values whichever thread
        fills them."""
        keys = [(b.radius, lattice(b.radius, self.dx, self.dy)) for b in balls]
        for k in sorted({k for _, k in keys}):  # the lattices' concave radii, once each
            if k not in self._rho:
                self._rho[k] = concave_radii(self.z[::k, ::k], k * self.dx, k * self.dy)
        todo = sorted(set(keys), key=lambda key: (key[1], -key[0]))
        each([partial(self.rest, r, k) for r, k in todo])
        order = sorted(range(len(balls)), key=lambda j: (keys[j][1], -keys[j][0]))
        got = each([partial(self.main_time, balls, j) for j in order])
        out: list[BallTime] = [got[0]] * len(balls)
        for j, t in zip(order, got, strict=True):
            out[j] = t
        return out

    def safety(self, k: int) -> B8:
        """Fine nodes near detail sharper than ``k > 1`` cells."""
        if k not in self._safety:
            sharp = self.rho < SHARP_SHARE * k * max(self.dx, self.dy)
            self._safety[k] = within_distance(sharp, k * math.hypot(self.dx, self.dy),
                                              self.dx, self.dy)
        return self._safety[k]

    def fine_mask(self, coarse: B8, k: int) -> B8:
        """Fine nodes with a flagged lattice node among their cell's corners."""
        if k == 1:
            return coarse
        ny, nx = self.z.shape
        grown = coarse.copy()
        grown[1:] |= coarse[:-1]
        grown[:, 1:] |= grown[:, :-1].copy()
        rows = np.minimum(-(-np.arange(ny) // k), coarse.shape[0] - 1)
        cols = np.minimum(-(-np.arange(nx) // k), coarse.shape[1] - 1)
        return grown[np.ix_(rows, cols)]

    def material(self, prev: float, kn: int) -> _Material:
        """What ``prev`` leaves, on lattice ``kn`` (from its own coarser lattice by
        :func:`_upsample_where`: the lesser of its rest and its closing less the part,
        both interpolated bilinearly); cached for the latest ``prev`` only (full-size
        arrays)."""
        if self._last_prev != prev:  # (set before two threads ask for the same prev)
            self._last_prev, self._material = prev, {}
        got = self._material.get(kn)
        if got is None:
            kp = lattice(prev, self.dx, self.dy)
            theirs = self.rest(prev, kp)
            zk = self.z[::kn, ::kn]
            if kp != kn:
                theirs = _upsample_where(theirs, self.z[::kp, ::kp], kp // kn, zk, self.tol)
            nodes = np.flatnonzero(theirs > self.tol)
            heights, blocks = material_grid(zk.shape, nodes,
                                            zk.ravel()[nodes] + theirs.ravel()[nodes])
            got = _Material(theirs, nodes, heights, blocks)
            self._material[kn] = got
        return got

    def costs(self, prev: float, balls: list[Tool], order: list[int],
              low: Callable[[int], float], options: list[tuple[float, int | None]]
              ) -> Iterator[tuple[int, float | None]]:
        """``(i, cost(prev, balls[i]))`` for the candidates ``order`` in turn, as long as
        ``low(i)`` stays below the least option so far (``options``, which the caller
        extends between the items): :func:`_plan`'s search, two candidates at a time on
        two threads. The second of a pair is computed alongside the first and kept only
        if the first's option leaves it a chance (as the one-by-one search would have
        gone on to it); its figures depend on the pair alone, so the items are the same
        as one by one. A pair of two balls of one radius (a custom library) is not run
        side by side (they would share one :class:`CuttingRegion`), nor is any pair on one
        thread (:func:`._threads.split`: the second would be computed in turn, maybe for
        nothing)."""
        if self._last_prev != prev:
            self._last_prev, self._material = prev, {}

        def least() -> float:
            return min((o[0] for o in options), default=math.inf)

        n = 0
        while n < len(order):
            a = order[n]
            if low(a) >= least():
                return
            b = order[n + 1] if n + 1 < len(order) else None
            if (b is None or low(b) >= least() or balls[a].radius == balls[b].radius
                    or not split()):
                yield a, self.cost(prev, balls[a])
                n += 1
                continue
            first, second = both(partial(self.cost, prev, balls[a]),
                                 partial(self.cost, prev, balls[b]))
            yield a, first
            if low(b) >= least():
                return
            yield b, second
            n += 2

    def _compare(self, prev: float, nxt: float) -> tuple[NDArray[np.int64], _Material, int]:
        """On the smaller ball's (finer) lattice ``kn``: the flat indices of the nodes where
        ``nxt`` does better than ``prev`` by more than the tolerance, and what ``prev``
        leaves there."""
        kn = lattice(nxt, self.dx, self.dy)
        mat = self.material(prev, kn)
        mine = self.rest(nxt, kn).ravel()
        nodes = mat.nodes
        better = nodes[mat.rest.ravel()[nodes] - mine[nodes] > self.tol]
        return better, mat, kn

    def _safe_region(self, kp: int, kn: int, nxt: float
                     ) -> tuple[B8, NDArray[np.int64]] | None:
        """Lattice ``kn`` positions within ``nxt`` of detail lattice ``kp`` may skip (mask
        and flat indices; None: none)."""
        if kp == 1:
            return None
        key = (kp, kn, nxt)
        if key not in self._safe:
            if (kp, kn) not in self._pooled:  # the fine safety nodes, on the lattice
                fine = self.safety(kp)
                self._pooled[kp, kn] = _pool_any(fine, kn) if kn > 1 else fine
            pooled = self._pooled[kp, kn]
            got = None
            if pooled.any():
                mask = within_distance(pooled, nxt, kn * self.dx, kn * self.dy)
                got = (mask, np.flatnonzero(mask))
            self._safe[key] = got
        return self._safe[key]

    def cutter(self, radius: float, k: int) -> CuttingRegion:
        """The ball's :class:`CuttingRegion` on lattice ``k`` (its CL kept across calls)."""
        key = (radius, k)
        if key not in self._cutting:
            self.rest(radius, k)
            self._cutting[key] = CuttingRegion(self.z[::k, ::k], k * self.dx, k * self.dy,
                                               radius, self._cl[key])
        return self._cutting[key]

    def cost(self, prev: float, nxt: Tool) -> float | None:
        """Estimated minutes of ball ``nxt`` over its rest region after ``prev``, on
        ``nxt``'s lattice (None: no region): :func:`~zwcore.scanline._chain_time.ball_time`
        with the most stock it meets above its tip there (:meth:`met`), entered through
        the material ``prev`` left, in its own whole-part scan direction.

        The region is what the plan's rest rule (:mod:`zwcore.scanline._rest`) cuts: of
        the positions within ``nxt``'s radius of the nodes where it does better, those
        whose ball, at its nodal CL on the part, cuts into the material ``prev`` leaves
        more than the tolerance above the part (:class:`CuttingRegion`); plus, near detail
        ``prev``'s lattice may have skipped, every position within the radius."""
        better, mat, kn = self._compare(prev, nxt.radius)
        safe = self._safe_region(lattice(prev, self.dx, self.dy), kn, nxt.radius)
        region = None if safe is None else safe[0]
        if better.size:
            got, _ = self.cutter(nxt.radius, kn).layers(
                better, mat.heights, mat.blocks, mat.rest, nxt.flute_length,
                None if safe is None else safe[0])
            if got:
                cut = self.cutter(nxt.radius, kn).last_region()
                region = cut if region is None else cut | region
        if region is None or not region.any():
            return None
        zk = self.z[::kn, ::kn]
        depth = self.met(zk, kn, mat.rest, self.rest(nxt.radius, kn), nxt.radius, region)
        # an entry comes down to the stock the ball before left around the start
        entry = nxt.radius + float(mat.rest[region].mean())
        main = self.times.get((math.inf, nxt.id))  # its scan direction over the whole part
        got_time = ball_time(zk, zk + self.rest(nxt.radius, kn), kn * self.dx, kn * self.dy,
                             (self.dx, self.dy), nxt, region, depth, self.tol, self.feeds,
                             entry, None if main is None else main.along_x)
        self.times[prev, nxt.id] = got_time
        return got_time.minutes

    def met(self, zk: F64, k: int, theirs: F64, mine: F64, radius: float,
            region: B8 | None) -> float:
        """Most stock a ball of ``radius`` meets above its tip in ``region`` (None:
        everywhere) of lattice ``k`` (the part ``zk`` there; ``theirs``, ``mine``: what the
        ball before and this one leave): :func:`~zwcore.scanline._chain_time.stock_met`.
        Beside a cliff that is the cliff's height: a ball whose flutes are shorter goes
        down along it in layers."""
        return stock_met(zk, theirs, mine, region, math.floor(radius / (k * self.dy)),
                         math.floor(radius / (k * self.dx)))

    def main_time(self, balls: list[Tool], j: int) -> BallTime:
        """Estimated time of ``balls[j]`` over the whole part: it meets what the roughing
        before it leaves, taken as what the largest library ball of at most twice its
        diameter leaves (the roughing stage before it is one pyramid level coarser,
        twice its spacing), and up to half its own flute length the roughing may leave
        over its stage model; the largest ball only its cliffs. Roughing is not counted,
        for any main ball (the largest, which the plan lets rough at the finishing
        level itself, included)."""
        tool = balls[j]
        k = lattice(tool.radius, self.dx, self.dy)
        zk = self.z[::k, ::k]
        theirs = np.zeros(zk.shape)
        if j > 0:
            prev = next((b.radius for b in balls[:j] if b.radius <= ROUGHING_RATIO * tool.radius),
                        balls[j - 1].radius)
            kp = lattice(prev, self.dx, self.dy)
            theirs = self.rest(prev, kp)
            if kp != k:
                theirs = _upsample_where(theirs, self.z[::kp, ::kp], kp // k, zk, self.tol)
        depth = self.met(zk, k, theirs, self.rest(tool.radius, k), tool.radius, None)
        if j > 0:  # the roughing leaves up to half this ball's flutes over its own model
            depth += SCALLOP_FLUTE_SHARE * tool.flute_length
        got = ball_time(zk, zk + self.rest(tool.radius, k), k * self.dx, k * self.dy,
                        (self.dx, self.dy), tool, None, depth, self.tol, self.feeds)
        self.times[math.inf, tool.id] = got
        return got


def region_boxes(region: B8, dx: float, dy: float) -> tuple[int, tuple[RegionBox, ...]]:
    """Region count and the largest :data:`MAX_BOXES` regions' boxes (node positions from
    the grid's origin, mm), largest first."""
    labels, count = ndimage.label(region, structure=np.ones((3, 3), dtype=bool))
    if count == 0:
        return 0, ()
    sizes = np.bincount(labels.ravel())[1:]
    order = np.argsort(-sizes, kind="stable")[:MAX_BOXES]
    slices = ndimage.find_objects(labels)
    out = []
    for n in order:
        sy, sx = slices[n]
        out.append(RegionBox(sx.start * dx, sy.start * dy, (sx.stop - 1) * dx,
                             (sy.stop - 1) * dy, float(sizes[n]) * dx * dy))
    return int(count), tuple(out)


def _plan(balls: list[Tool], reach: _Reach, bound: bool = True
          ) -> tuple[list[int], list[BallTime]]:
    """The chain (indices into ``balls``, largest first) of least estimated finishing
    time, and the estimate per ball of it.

    Dynamic programming from the smallest ball up: ``best[j]`` is the least time of the
    balls after ``j``. A pair's region cost is computed only when it may beat the best
    option found so far for ``j``: candidates go in order of a lower bound, ``cost after
    a smaller previous ball + tool change + best[i]`` (``bound``; a larger previous ball
    leaves at least the material a smaller one leaves, so its rest region is no smaller
    and no shallower: the closing grows with the ball), else of ``tool change +
    best[i]`` alone, and the search stops at the first whose bound is not below it.
    """
    n = len(balls)
    # every ball over the whole part first: its scan direction serves its rest regions
    mains = reach.main_times(balls)
    best: list[float] = [math.inf] * n
    after: list[int | None] = [None] * n
    floor = [0.0] * n  # per next ball: its cost after the largest previous ball so far
    for j in range(n - 1, -1, -1):
        options: list[tuple[float, int | None]] = []

        def low(m: int) -> float:
            return (floor[m] if bound else 0.0) + TOOL_CHANGE_MIN + best[m]

        order = sorted(range(j + 1, n), key=lambda m: (low(m), m))
        for i, minutes in reach.costs(balls[j].radius, balls, order, low, options):
            if minutes is not None:
                floor[i] = max(floor[i], minutes)
                options.append((minutes + TOOL_CHANGE_MIN + best[i], i))
        if not options:
            options.append((0.0, None))
        best[j], after[j] = min(options, key=lambda o: (o[0], -1 if o[1] is None else o[1]))
    totals = [mains[j].minutes + best[j] for j in range(n)]
    main = min(range(n), key=lambda j: (totals[j], j))
    chain = [main]
    times = [mains[main]]
    while after[chain[-1]] is not None:
        nxt = after[chain[-1]]
        assert nxt is not None
        times.append(reach.times[balls[chain[-1]].radius, balls[nxt].id])
        chain.append(nxt)
    return chain, times


def finishing_chain(z: F64, dx: float, dy: float, balls: list[Tool], tolerance: float,
                    feeds: Feeds | None = None) -> Chain:
    """The finishing balls the estimate ranks first, and its figures for the main ball.

    Parameters
    ----------
    z : (ny, nx) float64
        The part.
    dx, dy : float
    balls : list of Tool
        Ball end mills, largest first.
    tolerance : float
    feeds : Feeds, optional
        Feeds and rapid rate of the time estimate (default: the program's defaults).

    Returns
    -------
    Chain
    """
    ny, nx = z.shape
    cell = dx * dy
    area = float(ny * nx) * cell
    reach = _Reach(z, dx, dy, tolerance, feeds)
    chain, times = _plan(balls, reach)
    tool = balls[chain[0]]
    k = lattice(tool.radius, dx, dy)
    rest = reach.rest(tool.radius, k)
    left = reach.fine_mask(rest > tolerance, k)
    main = MainBall(tool, area / flat_pick_feed(tool.radius, tolerance), float(rest.max()),
                    f"simulated reach: {tool.id} finishes the whole part and leaves more than "
                    f"{tolerance:g} mm on {100 * float(left.mean()):.3g} % of it (to the "
                    f"smaller balls); shortest estimated finishing time of the library's chains "
                    f"({sum(t.minutes for t in times):.4g} min: "
                    + ", ".join(f"{balls[j].id} {t.passes} pass{'es' if t.passes > 1 else ''} "
                                f"{t.minutes:.4g} min" for j, t in zip(chain, times, strict=True))
                    + ")")
    smallest = area / flat_pick_feed(balls[-1].radius, tolerance)
    return Chain(tuple(balls[j] for j in chain), main, smallest, reach.rho)
