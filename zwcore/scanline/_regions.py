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
smaller previous ball) cannot win. A main ball's estimate includes the roughing the plan
lays before it (:meth:`_Reach.roughing`: the tool choice's rule on the plan's levels) and
its own passes over what that roughing leaves, or over the whole stock for the largest
ball, which nothing roughs before (:meth:`_Reach.main_time`).
"""

from __future__ import annotations

import heapq
import math
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace
from functools import partial

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.mrr.wavelets import analyse
from zwcore.scanline._chain import TOOL_CHANGE_MM, Chain, MainBall
from zwcore.scanline._chain_time import (
    SCALLOP_FLUTE_SHARE,
    BallTime,
    Feeds,
    PassFigures,
    ball_time,
    flat_pick_feed,
    pass_figures,
    passes_for,
    stock_met,
)
from zwcore.scanline._levels import first_level_and_guard, targets_and_levels
from zwcore.scanline._reach import ball_reach, concave_radii, within_distance
from zwcore.scanline._reach_cut import CuttingRegion, material_grid
from zwcore.scanline._reach_grid import _pool_any, _upsample_where
from zwcore.scanline._threads import both, each, split
from zwcore.scanline._tool_choice import REST_FLUTE_SHARE, REST_MAX_CELLS, Level, rest_map
from zwcore.sim import RegionBox, coarse_grid

__all__ = ["TOOL_CHANGE_MIN", "TOOL_CHANGE_MM", "Chain", "MainBall", "finishing_chain",
           "flat_pick_feed", "region_boxes"]

F64 = NDArray[np.float64]
B8 = NDArray[np.bool_]

#: A ball is evaluated on a lattice where it spans at least this many cells.
LATTICE_CELLS = 6.0

#: Detail sharper than this share of a ball's lattice spacing (concave radius at the
#: input nodes) may fall between its lattice nodes: it goes to the next ball.
SHARP_SHARE = 0.25

#: A tool change in the chain's time ranking, minutes (stop, change, measure the length,
#: approach: about 15 s on a machining centre; the program's estimate counts moves only).
TOOL_CHANGE_MIN = 0.25

#: What previous balls leave (:meth:`_Reach.material`, full-size arrays on a fine
#: lattice) is kept for this many (previous ball, lattice) pairs: the chain search's
#: envelope asks for a pair's cost after smaller previous balls between its own.
MATERIALS_KEPT = 4

#: The roughing ball before a main ball is taken as the largest library ball of at most
#: this many times its radius (the pyramid's levels double the spacing).
ROUGHING_RATIO = 2.0

#: Most region boxes listed per stage (largest first).
MAX_BOXES = 64


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
                 feeds: Feeds | None = None,
                 levels: Callable[[], list[Level]] | None = None) -> None:
        self.z, self.dx, self.dy, self.tol = z, dx, dy, tolerance
        self.feeds = Feeds() if feeds is None else feeds
        #: the estimate of every pair costed, ``(previous radius, next tool id)``; the
        #: main balls' under ``(inf, tool id)``
        self.times: dict[tuple[float, str], BallTime] = {}
        #: :meth:`costs`' second costs computed alongside and not handed out (yet)
        self.spare: dict[tuple[float, str], float | None] = {}
        self.rho = concave_radii(z, dx, dy)
        self._rest: dict[tuple[float, int], F64] = {}
        self._cutting: dict[tuple[float, int], CuttingRegion] = {}
        self._cl: dict[tuple[float, int], F64 | None] = {}
        self._safe: dict[tuple[int, int, float], tuple[B8, NDArray[np.int64]] | None] = {}
        self._rho: dict[int, F64] = {1: self.rho}
        self._safety: dict[int, B8] = {}
        self._pooled: dict[tuple[int, int], B8] = {}
        #: :meth:`material` per (prev, lattice), the latest :data:`MATERIALS_KEPT`
        self._material: dict[tuple[float, int], _Material] = {}
        self._material_lock = threading.Lock()
        self._levels: list[Level] | None = None
        self._plan_levels = levels
        #: per ball over the whole part: its pass figures, and its scan direction where
        #: known without its depth (:meth:`main_bounds`)
        self._figures: dict[str, PassFigures] = {}
        self._along: dict[str, bool] = {}

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

    def main_bounds(self, balls: list[Tool]) -> list[float]:
        """A lower bound of every ball's :meth:`main_time` (its roughing and the passes
        after the first left out: its last pass alone), on two threads
        (:mod:`._threads`): first every ball's rest on its lattice (the nodal closings,
        most of the work), then its pass figures over the whole part (their kernels),
        each a task the threads share, costliest first (the finest lattices). A ball's
        rest regions run in the scan direction of its one pass at the tolerance over the
        whole part (:meth:`cost`: a rest ball's passes are finishing passes; it needs no
        depth, so no roughing). The same figures as one by one: each task's result depends on the
        part and the ball alone, and the caches hold the same values whichever thread
        fills them."""
        keys = [(b.radius, lattice(b.radius, self.dx, self.dy)) for b in balls]
        for k in sorted({k for _, k in keys}):  # the lattices' concave radii, once each
            if k not in self._rho:
                self._rho[k] = concave_radii(self.z[::k, ::k], k * self.dx, k * self.dy)
        todo = sorted(set(keys), key=lambda key: (key[1], -key[0]))
        each([partial(self.rest, r, k) for r, k in todo])
        order = sorted(range(len(balls)), key=lambda j: (keys[j][1], -keys[j][0]))
        got = each([partial(self._main_bound, balls, j) for j in order])
        out = [0.0] * len(balls)
        for j, t in zip(order, got, strict=True):
            out[j] = t
        return out

    def _main_figures(self, tool: Tool) -> PassFigures:
        if tool.id not in self._figures:
            k = lattice(tool.radius, self.dx, self.dy)
            zk = self.z[::k, ::k]
            self._figures[tool.id] = pass_figures(
                zk, zk + self.rest(tool.radius, k), k * self.dx, k * self.dy,
                (self.dx, self.dy), tool, None, self.tol, True)
        return self._figures[tool.id]

    def main_bound(self, balls: list[Tool], j: int) -> float:
        """A lower bound of :meth:`main_time`'s passes (its roughing left out), tighter than
        :meth:`main_bounds`' and dearer (a depth): the ball meets at least the stock over
        the finest roughing level's target (the targets nest: every coarser one, where
        the roughing before it stops, stands at least as high at the input's nodes, and
        its rest and scallops add to it), within the span every level's nodes cover;
        and without roughing before it the whole stock, whichever is less."""
        tool = balls[j]
        k = lattice(tool.radius, self.dx, self.dy)
        zk = self.z[::k, ::k]
        tip = zk + self.rest(tool.radius, k)
        depth = float(self.z.max()) + tool.flute_length - float(tip.min())
        levs = self.roughing_levels(balls)
        if levs:
            fine = levs[-1]
            kr = round(fine.sx / self.dx)
            ny, nx = tip.shape
            up = fine.model[: fine.extent[0], : fine.extent[1]]
            up = _bilinear(up, kr // k, (ny, nx)) if kr > k else up[::k // kr, ::k // kr]
            theirs = np.maximum(up[:ny, :nx] - zk, 0.0)
            # beyond the coarsest level's last node a level's model is held, not nested
            span = [(e - 1) * round(lev.sy / self.dy) // k + 1 for lev in levs
                    for e in (lev.extent[0],)]
            spanx = [(e - 1) * round(lev.sx / self.dx) // k + 1 for lev in levs
                     for e in (lev.extent[1],)]
            theirs[min(span):] = 0.0
            theirs[:, min(spanx):] = 0.0
            depth = min(depth, stock_met(zk, theirs, tip - zk, None,
                                         math.floor(tool.radius / (k * self.dy)),
                                         math.floor(tool.radius / (k * self.dx))))
        return self._main_figures(tool).time(passes_for(depth, tool.flute_length), depth,
                                             self.feeds).minutes

    def _main_bound(self, balls: list[Tool], j: int) -> float:
        one = self._main_figures(balls[j]).time(1, 0.0, self.feeds)
        self._along[balls[j].id] = one.along_x
        return one.minutes

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
        both interpolated bilinearly); the latest :data:`MATERIALS_KEPT` kept."""
        got = self._material.get((prev, kn))
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
            with self._material_lock:
                while len(self._material) >= MATERIALS_KEPT:
                    del self._material[next(iter(self._material))]
                self._material[prev, kn] = got
        return got

    def costs(self, prev: float, balls: list[Tool], order: list[int],
              low: Callable[[int], float], options: list[tuple[float, int | None]]
              ) -> Iterator[tuple[int, float | None]]:
        """``(i, cost(prev, balls[i]))`` for the candidates ``order`` in turn, as long as
        ``low(i)`` stays below the least option so far (``options``, which the caller
        extends between the items): :func:`_plan`'s search, two candidates at a time on
        two threads. The second of a pair is computed alongside the first and kept only
        if the first's option leaves it a chance (as the one-by-one search would have
        gone on to it), else kept in :attr:`spare` and handed out when asked for later
        (the pair envelope of :func:`_plan` asks for skipped pairs); its figures depend on
        the pair alone, so the items are the same as one by one. A pair of two balls of one
        radius (a custom library) is not run side by side (they would share one
        :class:`CuttingRegion`), nor is any pair on one
        thread (:func:`._threads.split`: the second would be computed in turn, maybe for
        nothing)."""
        def least() -> float:
            return min((o[0] for o in options), default=math.inf)

        n = 0
        while n < len(order):
            a = order[n]
            if low(a) >= least():
                return
            if (prev, balls[a].id) in self.spare:  # computed alongside another earlier
                yield a, self.spare.pop((prev, balls[a].id))
                n += 1
                continue
            b = order[n + 1] if n + 1 < len(order) else None
            if (b is None or low(b) >= least() or balls[a].radius == balls[b].radius
                    or (prev, balls[b].id) in self.spare or not split()):
                yield a, self.cost(prev, balls[a])
                n += 1
                continue
            first, second = both(partial(self.cost, prev, balls[a]),
                                 partial(self.cost, prev, balls[b]))
            yield a, first
            if low(b) >= least():
                self.spare[prev, balls[b].id] = second  # (a larger prev's envelope may ask)
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
        along = self._along.get(nxt.id)  # its scan direction over the whole part
        got_time = ball_time(zk, zk + self.rest(nxt.radius, kn), kn * self.dx, kn * self.dy,
                             (self.dx, self.dy), nxt, region, depth, self.tol, self.feeds,
                             entry, along)
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

    def roughing_levels(self, balls: list[Tool]) -> list[Level]:
        """The plan's roughing levels (coarsest first), built as the plan's first round
        builds them (:func:`zwcore.scanline._levels.targets_and_levels`: the lifted
        single-knot MRR, nested targets under the default stock); once per ranking (60
        ms CPU at 1025²), or the plan's own (``levels``: the plan builds them on its second
        thread meanwhile, and the default stock's are the same). Their
        models are what the roughing before a main ball machines to: a coarse level's
        model stands tens of millimetres over the part beside cliffs and pockets (the
        1025² bench part's 12.5 mm level up to 54 mm at its nodes). A stock top the
        request gives is not seen (nor its feeds: :class:`Feeds`)."""
        if self._levels is None and self._plan_levels is not None:
            self._levels = self._plan_levels()[:-1]  # (the last is the finishing level)
        if self._levels is None:
            zmap = ZMap(self.z, dx=self.dx, dy=self.dy)
            mrr = analyse(self.z, "single_knot")
            first, ceiling, g = first_level_and_guard(zmap, mrr, balls, None)
            _, levs = targets_and_levels(zmap, mrr, first, ceiling, g, balls, 0.0, {})
            self._levels = levs[:-1]  # (the last is the finishing level)
        return self._levels

    def _level_rest(self, lev: Level, radius: float) -> F64:
        """A ball's rest on a level's model (inside the input), as
        :func:`zwcore.scanline._tool_choice.ball_rest` takes it (the map, kept on the
        level: the tool choice reads the same)."""
        return rest_map(lev, radius)

    def roughing(self, balls: list[Tool], j: int) -> list[tuple[Tool, Level]]:
        """The roughing stages the plan lays before main ball ``balls[j]``, coarsest
        first: :func:`zwcore.scanline._tool_choice.choose`'s rule on
        :meth:`roughing_levels`, from the finest towards the coarsest (a level takes the
        largest library ball larger than the stage after it whose rest on the level's
        model is at most a quarter of the smaller flute length, for a ball of at most
        ``REST_MAX_CELLS`` level cells; a larger one if it fits the level's smallest
        concave radius)."""
        current = balls[j]
        out: list[tuple[Tool, Level]] = []
        for lev in reversed(self.roughing_levels(balls)):
            spacing = min(lev.sx, lev.sy)
            for tool in balls:
                if tool.radius <= current.radius:
                    break
                if spacing >= tool.diameter:
                    continue
                allowance = REST_FLUTE_SHARE * min(current.flute_length, tool.flute_length)
                if tool.radius <= REST_MAX_CELLS * spacing:
                    fits = float(self._level_rest(lev, tool.radius).max()) <= allowance
                else:
                    fits = tool.radius <= lev.concave_radius
                if fits:
                    out.append((tool, lev))
                    current = tool
                    break
        out.reverse()
        return out

    def _pass_mm(self, tool: Tool, lev: Level) -> float:
        """Cut length of one roughing pass of ``tool`` on level ``lev``: a line on every
        level grid line over the whole part, each a radius and an input grid step past
        both stock edges, linked beside the stock (the tool paths' whole lines); in the
        direction of fewer lines. Its climb is left out."""
        ny, nx = self.z.shape
        wx, wy = (nx - 1) * self.dx, (ny - 1) * self.dy
        over = 2.0 * (tool.radius + max(self.dx, self.dy))
        along_x = (math.floor(wy / lev.sy + 1e-9) + 1) * (wx + over) + wy
        along_y = (math.floor(wx / lev.sx + 1e-9) + 1) * (wy + over) + wx
        return min(along_x, along_y)

    def main_time(self, balls: list[Tool], j: int) -> BallTime:
        """Estimated time of ``balls[j]`` over the whole part, and of the roughing the plan
        lays before it (:meth:`roughing`; :attr:`BallTime.roughing`).

        The first roughing stage meets the stock from the plan's default stock top (the
        part's top plus that ball's flute length) and each later one what the stage
        before leaves: its level's model, its rest there and its scallops, which the
        plan lets take half the next flute length less that rest (over the whole part
        the flute rule's window, :func:`~zwcore.scanline._chain_time.stock_met`, on the
        stage's lattice); a stage goes down in as many passes as its flutes need, each a
        line on every level grid line. The main ball meets, likewise, what the last
        roughing stage leaves, or the whole stock when there is none (the largest ball:
        a roughing level takes only a larger ball than the stage after it), in as many
        passes as its flutes need, the lifted ones on every grid line of the finishing
        level (:func:`~zwcore.scanline._chain_time.ball_time`). Before (session 10) the
        main ball met the nodal rest of the next larger library ball plus half its flute
        length, the largest ball only its cliffs, and no roughing was priced: on the 45°
        fillet Ø20 as main ball was priced at 1 pass, 1.7 min, and its stage emits 2
        passes, 13.6 min."""
        tool = balls[j]
        k = lattice(tool.radius, self.dx, self.dy)
        zk = self.z[::k, ::k]
        mine = self.rest(tool.radius, k)
        stages = self.roughing(balls, j)
        first = stages[0][0] if stages else tool
        stock = float(self.z.max()) + first.flute_length
        rough = 0.0
        before: tuple[F64, int, float] | None = None  # surface, its lattice, scallop
        for n, (ball, lev) in enumerate(stages):
            nxt = stages[n + 1][0] if n + 1 < len(stages) else tool
            kr = round(lev.sx / self.dx)
            left = lev.model[: lev.extent[0], : lev.extent[1]] + self._level_rest(lev, ball.radius)
            if before is None:
                depth = stock - float(left.min())
            else:
                depth = self._depth_over(before, left, kr, ball.radius)
            count = passes_for(depth, ball.flute_length)
            rough += count * self._pass_mm(ball, lev) / self.feeds.feed
            # its scallops: up to its budget, half the next flute less its rest (the plan's)
            rest = float(self._level_rest(lev, ball.radius).max())
            budget = max(SCALLOP_FLUTE_SHARE * min(ball.flute_length, nxt.flute_length) - rest,
                         0.0)
            before = (left, kr, budget)
        if before is None:
            depth = stock - float((zk + mine).min())
        else:
            depth = self._depth_over(before, zk + mine, k, tool.radius)
        got = self._main_figures(tool).time(passes_for(depth, tool.flute_length), depth,
                                            self.feeds)
        got = replace(got, roughing=rough)
        self.times[math.inf, tool.id] = got
        return got

    def _depth_over(self, before: tuple[F64, int, float], tip: F64, k: int,
                    radius: float) -> float:
        """Most stock a ball of ``radius`` with its tip at ``tip`` (lattice ``k``) meets
        over the surface ``before`` leaves (on its lattice, interpolated bilinearly) and
        its scallops: :func:`~zwcore.scanline._chain_time.stock_met`."""
        surface, kb, scallop = before
        ny, nx = tip.shape
        up = _bilinear(surface, kb // k, (ny, nx)) if kb > k else surface[::k // kb, ::k // kb]
        zk = self.z[::k, ::k]
        theirs = np.maximum(up[:ny, :nx] - zk, 0.0) + scallop
        return stock_met(zk, theirs, tip - zk, None, math.floor(radius / (k * self.dy)),
                         math.floor(radius / (k * self.dx)))


def _bilinear(coarse: F64, f: int, shape: tuple[int, int]) -> F64:
    """``coarse`` (a lattice ``f`` times coarser) at the finer lattice's nodes ``shape``,
    bilinearly (held at the last coarse node beyond it)."""
    def axis(n: int, m: int) -> tuple[NDArray[np.int64], F64]:
        t = np.minimum(np.arange(n) / f, m - 1)
        i0 = np.minimum(np.floor(t).astype(np.int64), max(m - 2, 0))
        return i0, t - i0

    (iy, wy), (ix, wx) = axis(shape[0], coarse.shape[0]), axis(shape[1], coarse.shape[1])
    iy1, ix1 = np.minimum(iy + 1, coarse.shape[0] - 1), np.minimum(ix + 1, coarse.shape[1] - 1)
    rows = coarse[iy] * (1.0 - wy)[:, None] + coarse[iy1] * wy[:, None]
    out: F64 = rows[:, ix] * (1.0 - wx) + rows[:, ix1] * wx
    return out


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
    balls after ``j``. A pair's cost is the largest region cost (:meth:`_Reach.cost`) of
    its next ball after the previous ball or any smaller one: a larger previous ball
    leaves at least the material a smaller one leaves, so its rest region should be no
    smaller and no shallower, but the region costs are computed on different lattices
    and are not monotone in the previous ball (the 3 mm trench: Ø3 after Ø10 and after
    Ø16); the envelope is monotone by construction. A pair whose next ball has no region
    after the previous ball stays without one (it is no option: the plan tries every
    smaller ball after the chain anyway). So ``cost(j, i) >= cost(j', i)`` for every
    ``j < j' < i`` where both have a region (the envelope is completed only for a pair
    whose own cost does not already lose), and a pair is computed only when it may beat
    the best option found so far for ``j``: candidates go in order of a lower bound,
    ``cost after a smaller previous ball + tool change + best[i]`` (``bound``), else of
    ``tool change + best[i]`` alone, and the search stops at the first whose bound is not
    below it. Pruned or not, it is the least over the same costs.
    """
    n = len(balls)
    # every ball over the whole part first: its scan direction serves its rest regions
    lows = reach.main_bounds(balls)
    best: list[float] = [math.inf] * n
    after: list[int | None] = [None] * n
    floor = [0.0] * n  # per next ball: its cost after the largest previous ball so far
    raw: dict[tuple[int, int], float | None] = {}
    # per pair: the largest region cost after it or a smaller previous ball, and whose
    tops: dict[tuple[int, int], tuple[float, int] | None] = {}

    def largest(j: int, i: int) -> tuple[float, int] | None:
        if (j, i) not in tops:
            if (j, i) not in raw:  # the search skipped it
                raw[j, i] = next(reach.costs(balls[j].radius, balls, [i],
                                             lambda m: -math.inf, []))[1]
            r = raw[j, i]
            lo = largest(j + 1, i) if j + 1 < i else None
            tops[j, i] = lo if r is None else (r, j) if lo is None or r >= lo[0] else lo
        return tops[j, i]

    def envelope(j: int, i: int) -> tuple[float, int] | None:
        """The pair's cost and the previous ball whose region cost it is (None: ``i``
        has no region after ``j``)."""
        return None if raw[j, i] is None else largest(j, i)

    for j in range(n - 1, -1, -1):
        options: list[tuple[float, int | None]] = []

        def low(m: int) -> float:
            return (floor[m] if bound else 0.0) + TOOL_CHANGE_MIN + best[m]

        order = sorted(range(j + 1, n), key=lambda m: (low(m), m))
        for i, minutes in reach.costs(balls[j].radius, balls, order, low, options):
            raw[j, i] = minutes
            if minutes is not None and options and (
                    minutes + TOOL_CHANGE_MIN + best[i] > min(o[0] for o in options)):
                # loses on its own cost, so on the envelope's (no smaller previous ball's
                # cost needed); its own still bounds the pair's after larger ones
                floor[i] = max(floor[i], minutes)
                continue
            pair = envelope(j, i)
            if pair is not None:
                floor[i] = max(floor[i], pair[0])
                options.append((pair[0] + TOOL_CHANGE_MIN + best[i], i))
        if not options:
            options.append((0.0, None))
        best[j], after[j] = min(options, key=lambda o: (o[0], -1 if o[1] is None else o[1]))
    # the main ball of least (roughing + its passes + best after it, index), best first
    # by lower bounds: a ball's depth is bounded (:meth:`_Reach.main_bound`) and its
    # roughing and depth computed (:meth:`_Reach.main_time`) only while its bound may
    # still win; the bounds never exceed the totals, so this is the least of them all
    main, top, first = -1, math.inf, None
    heap = [(lows[j] + best[j], j, False) for j in range(n)]
    heapq.heapify(heap)
    while heap:
        least, j, tight = heapq.heappop(heap)
        if main >= 0 and (least, j) > (top, main):
            break
        if not tight:
            heapq.heappush(heap, (reach.main_bound(balls, j) + best[j], j, True))
            continue
        got = reach.main_time(balls, j)
        total = got.roughing + got.minutes + best[j]
        if main < 0 or (total, j) < (top, main):
            main, top, first = j, total, got
    assert first is not None
    chain = [main]
    times = [first]
    while after[chain[-1]] is not None:
        nxt = after[chain[-1]]
        assert nxt is not None
        pair = envelope(chain[-1], nxt)
        assert pair is not None
        times.append(reach.times[balls[pair[1]].radius, balls[nxt].id])
        chain.append(nxt)
    return chain, times


def finishing_chain(z: F64, dx: float, dy: float, balls: list[Tool], tolerance: float,
                    feeds: Feeds | None = None,
                    levels: Callable[[], list[Level]] | None = None) -> Chain:
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
    levels : callable, optional
        The plan's first-round levels under the default stock (finishing level last),
        asked for only when a main ball's roughing is priced (the plan builds them on its
        second thread meanwhile); default: built here the same way.

    Returns
    -------
    Chain
    """
    ny, nx = z.shape
    cell = dx * dy
    area = float(ny * nx) * cell
    reach = _Reach(z, dx, dy, tolerance, feeds, levels)
    chain, times = _plan(balls, reach)
    tool = balls[chain[0]]
    k = lattice(tool.radius, dx, dy)
    rest = reach.rest(tool.radius, k)
    left = reach.fine_mask(rest > tolerance, k)
    main = MainBall(tool, area / flat_pick_feed(tool.radius, tolerance), float(rest.max()),
                    f"simulated reach: {tool.id} finishes the whole part and leaves more than "
                    f"{tolerance:g} mm on {100 * float(left.mean()):.3g} % of it (to the "
                    f"smaller balls); shortest estimated machining time of the library's chains "
                    f"({times[0].roughing + sum(t.minutes for t in times):.4g} min: roughing "
                    f"before {tool.id} {times[0].roughing:.4g} min, "
                    + ", ".join(f"{balls[j].id} {t.passes} pass{'es' if t.passes > 1 else ''} "
                                f"{t.minutes:.4g} min" for j, t in zip(chain, times, strict=True))
                    + ")")
    smallest = area / flat_pick_feed(balls[-1].radius, tolerance)
    return Chain(tuple(balls[j] for j in chain), main, smallest, reach.rho,
                 coarse_grid(balls, dx, dy, tolerance))
