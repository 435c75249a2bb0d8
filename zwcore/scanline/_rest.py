"""Rest regions from the simulated stock: where a smaller finishing ball machines.

A rest ball's region is decided when its stage begins, from the stock the passes before
it really left (:mod:`zwcore.scanline._stock`), not from an estimate:

- *seed*: the input nodes where that stock lies more than ``tolerance`` above the part
  and where this ball can do better than the ball before it: its closing of the part
  (:func:`zwcore.sim.closing`, ``bilinear``, the surface meaning the passes drop the
  ball on, so a ball the wall chords hold up is held up here too) lies more than
  ``tolerance`` below the previous ball's closing. Material a pass leaves for other
  reasons (its scallops, the grid's border where its lines end) is left out of the
  seed: a smaller ball would leave it too, only less; it is reported with the final
  stock. Both closings see the part continued beyond the grid's edge with its slope
  there (odd reflection), as if the positions overran the part.
- *region*: the positions (the part's nodes, which are the finishing stages' model nodes)
  within the ball's radius of the seed whose ball, at its drop-cutter CL on the part, cuts
  into the stock at some node where it stands more than ``tolerance`` above the part: the
  nodal drop of the ball on that stock (elsewhere far below) lies above its CL. The
  positions left out cut none of that material, so at every seed node the region leaves
  what all positions within the radius would; they are those whose ball rests on the part
  above the material (beside a crease, on the far side of a wall).

The closings are computed on the seed's bounding box grown by ``2R`` and two cells (a
node's closing depends on the part within ``2R`` of it), so a few corners cost a few
windows, not the grid.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.scanline._reach import concave_radii, within_distance
from zwcore.scanline._regions import TOOL_CHANGE_MM, flat_pick_feed
from zwcore.sim import drop_cutter, envelope, nodal_drop_cutter, simulation_work

__all__ = ["RestRegion", "RestShared"]

F64 = NDArray[np.float64]
B8 = NDArray[np.bool_]

#: Most node-offset pairs (:func:`zwcore.sim.simulation_work`) the closing of the ball
#: before may take (a few seconds: the 45° fillet part needs 2.8e9); beyond, this
#: ball's closing is compared with the simulated stock itself, which sends it to more
#: nodes (scallops and borders too).
REST_CLOSING_WORK = 1 << 32

#: Most (position, node) pairs the region's cutting test may visit (about a second of
#: the nodal drop at worst); beyond, the region is the seed grown by the radius (a
#: superset). A thinned pass before leaves stock over most of a large grid and would
#: ask for every position.
CUT_WORK = 1 << 28

#: The ball before is compared only within ``2R`` of nodes whose concave radius is below
#: this many times its radius.
TIGHT_SHARE = 2.0


@dataclass(eq=False)
class RestShared:
    """What a plan's rest rules share.

    Attributes
    ----------
    ran : list of Tool
        The finishing balls that machined so far, main first (a rule whose region is
        not empty appends its ball).
    rho : (ny, nx) float64 or None
        The part's concave radii (:func:`zwcore.scanline._reach.concave_radii`): the
        plan passes the estimate's; computed on first use when None.
    closings : dict
        Closings minus the part and drop-cutter CLs, windows ``(h, w)``, by (tool,
        window) while the stock stays the same (the ball before is compared with every
        smaller candidate on it).
    """

    ran: list[Tool]
    closings: dict[tuple[object, ...], tuple[F64, F64]] = field(default_factory=dict)
    rho: F64 | None = field(default=None, repr=False)


@dataclass(eq=False)
class RestRegion:
    """The rule for one rest ball's region; called with the stock when its stage begins.

    Attributes
    ----------
    part : ZMap
        The part (the finishing stages' model grid).
    tool : Tool
        The rest ball.
    tolerance : float
    shared : RestShared
    last : bool
        The smallest candidate (never dropped while it does better anywhere).
    seed_nodes : int
        After the call: the seed's node count.
    left_before : float
        After the call: most stock over the part when the stage began, mm.
    previous : Tool or None
        After the call: the ball compared with.
    against_stock : bool
        After the call: the ball before's closing was too large a computation and this
        ball's closing was compared with the stock instead.
    grown_nodes : int
        After the call: the seed grown by the ball's radius, nodes (the region is the
        part of it whose positions cut the seed's stock).
    cut_tested : bool
        After the call: False when that test was over :data:`CUT_WORK` and the region is
        the seed grown by the radius.
    """

    part: ZMap
    tool: Tool
    tolerance: float
    shared: RestShared
    last: bool = False
    seed_nodes: int = 0
    left_before: float = 0.0
    previous: Tool | None = None
    against_stock: bool = False
    grown_nodes: int = 0
    cut_tested: bool = True
    region: B8 | None = field(default=None, repr=False)
    _window_seed: B8 | None = field(default=None, repr=False)

    def __call__(self, stock: F64) -> B8:
        """The region on the part's nodes, ``(ny, nx)`` bool, from the stock ``(ny, nx)``."""
        z = self.part.z
        rest = stock - z
        self.left_before = float(rest.max(initial=0.0))
        self.previous = self.shared.ran[-1]
        self._window_seed = None
        self.cut_tested = True
        seed = rest > self.tolerance
        if seed.any():
            seed = self._better(seed, rest)
        self.seed_nodes = int(seed.sum())
        worth = self.seed_nodes * self.part.dx * self.part.dy / flat_pick_feed(
            self.tool.radius, self.tolerance)
        if not self.last and worth < TOOL_CHANGE_MM:
            seed = np.zeros(seed.shape, dtype=bool)
        grown = within_distance(seed, self.tool.radius, self.part.dx, self.part.dy)
        self.grown_nodes = int(grown.sum())
        self.region = self._cutting(seed, stock, grown) if self.grown_nodes else grown
        if self.region.any():
            self.shared.ran.append(self.tool)
            self.shared.closings.clear()  # the stock changes: closings of a new ball before
        return self.region

    def _better(self, seed: B8, rest: F64) -> B8:
        """Seed nodes where this ball's closing lies more than the tolerance below the
        previous ball's: first where the previous ball's closing leaves more than the
        tolerance at all (one closing per previous ball and stock, shared by the
        candidates), then this ball's closing on that smaller seed's window."""
        prev = self.previous
        assert prev is not None
        # A ball leaves material beyond its scallops only within 2R of where the part
        # bends about as sharply as the ball or more (the nodal bound of
        # :mod:`zwcore.scanline._reach`; twice the radius for the bilinear chords that
        # hold a nearly fitting ball up): elsewhere no closing is needed.
        seed = seed & self._near_tight(prev)
        if not seed.any():
            return seed
        if self._work(seed, prev) <= REST_CLOSING_WORK:
            theirs, _, _ = self._on_window(seed, prev)
            seed = seed & (theirs > self.tolerance)
            if not seed.any():
                return seed
        else:  # too large a closing: compared with what the stock shows (more nodes)
            self.against_stock = True
            theirs = rest
        mine, inside, _ = self._on_window(seed, self.tool)
        self._window_seed = seed  # the region's test reuses this window's CL
        return seed & inside & (mine < theirs - self.tolerance)

    def _cutting(self, seed: B8, stock: F64, grown: B8) -> B8:
        """Nodes of ``grown`` (``(ny, nx)`` bool) whose ball, at its drop-cutter CL on the
        part, lies below the stock ``(ny, nx)`` at some node where that stands more than
        the tolerance above the part: ``CL(c) < max over such nodes p within R of
        (stock(p) - h(|p - c|))``, the nodal drop of the ball on that stock."""
        # the window of this ball's closing (cached), which holds the final seed
        assert self._window_seed is not None  # a seed came through _better
        _, inside, cl = self._on_window(self._window_seed, self.tool)
        rows = np.flatnonzero(inside.any(axis=1))
        cols = np.flatnonzero(inside.any(axis=0))
        win = (slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1))
        z = self.part.z[win]
        far = float(z.min()) - 1.0  # below every CL on the part: nothing to cut here
        top = stock[win]
        material = np.where(top - z > self.tolerance, top, far)
        # a ball whose tip lies below that stock at its own node cuts it (h(0) = 0): only
        # the other positions need the drop on the stock
        here = grown[win] & (cl < material)
        asked = grown[win] & ~here
        disc = math.pi * self.tool.radius ** 2 / (self.part.dx * self.part.dy)
        if int(asked.sum()) * disc > CUT_WORK:
            self.cut_tested = False
            return grown
        # a position within R of a seed node sees all of the part within R of itself in
        # the window (2R and two cells): at the seed nodes the test below is exact
        lowers, _ = nodal_drop_cutter(material, self.tool.radius, self.part.dx, self.part.dy,
                                      asked)
        out = np.zeros(seed.shape, dtype=bool)
        out[win] = here | (asked & (cl < lowers))
        return out

    def _work(self, seed: B8, tool: Tool) -> int:
        """Node-offset pairs of the ball's closing on the seed's window."""
        ga = math.ceil(2.0 * tool.radius / self.part.dy) + 2
        gb = math.ceil(2.0 * tool.radius / self.part.dx) + 2
        rows = np.flatnonzero(seed.any(axis=1))
        cols = np.flatnonzero(seed.any(axis=0))
        shape = (int(rows[-1] - rows[0]) + 1 + 4 * ga, int(cols[-1] - cols[0]) + 1 + 4 * gb)
        return simulation_work(shape, tool, self.part.dx, self.part.dy)

    def _near_tight(self, tool: Tool) -> B8:
        sh = self.shared
        if sh.rho is None:
            sh.rho = concave_radii(self.part.z, self.part.dx, self.part.dy)
        cell = math.hypot(self.part.dx, self.part.dy)
        return within_distance(sh.rho < TIGHT_SHARE * tool.radius,
                               2.0 * tool.radius + cell, self.part.dx, self.part.dy)

    def _on_window(self, seed: B8, tool: Tool) -> tuple[F64, B8, F64]:
        """The ball's closing minus the part (``(ny, nx)``, 0 outside the window) on the
        seed's bounding box grown by ``2R`` and two cells, the window's mask, and the
        ball's drop-cutter CL on the window (``(h, w)``, the window's own shape).

        Where the window meets the grid's edge the part continues outwards with its slope
        there (odd reflection: no kink at the edge that would hold a ball up).
        """
        dx, dy = self.part.dx, self.part.dy
        ga = math.ceil(2.0 * tool.radius / dy) + 2
        gb = math.ceil(2.0 * tool.radius / dx) + 2
        rows = np.flatnonzero(seed.any(axis=1))
        cols = np.flatnonzero(seed.any(axis=0))
        ny, nx = seed.shape
        r0, r1 = max(0, rows[0] - ga), min(ny, rows[-1] + ga + 1)
        c0, c1 = max(0, cols[0] - gb), min(nx, cols[-1] + gb + 1)
        pads = ((ga if r0 == 0 else 0, ga if r1 == ny else 0),
                (gb if c0 == 0 else 0, gb if c1 == nx else 0))
        key = (tool.id, tool.radius, r0, r1, c0, c1)
        cache = self.shared.closings
        if key not in cache:
            z = self.part.z[r0:r1, c0:c1]
            win = np.pad(z, pads, mode="reflect", reflect_type="odd")
            cl = drop_cutter(ZMap(np.ascontiguousarray(win), dx=dx, dy=dy), tool, "bilinear")
            closed = envelope(cl, tool, dx, dy, "bilinear")
            inner = (slice(pads[0][0], pads[0][0] + r1 - r0),
                     slice(pads[1][0], pads[1][0] + c1 - c0))
            cache[key] = (closed[inner] - z, cl[inner])
        out = np.zeros(seed.shape)
        inside = np.zeros(seed.shape, dtype=bool)
        out[r0:r1, c0:c1] = cache[key][0]
        inside[r0:r1, c0:c1] = True
        return out, inside, cache[key][1]
