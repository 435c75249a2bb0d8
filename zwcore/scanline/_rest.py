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

The closings are computed on windows over block clusters of the seed, grown by ``2R``
and two cells (a node's closing depends on the part within ``2R`` of it), so a few
corners cost a few windows, not the grid; past work bounds the rule takes cheaper
supersets (this ball's closing on its tight band or not at all, the cutting test
skipped), never smaller regions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.scanline._chain import TOOL_CHANGE_MM
from zwcore.scanline._chain_time import flat_pick_feed
from zwcore.scanline._reach import concave_radii, within_distance
from zwcore.scanline._reach_cut import cutting_positions
from zwcore.sim import (
    drop_cutter,
    envelope,
    nodal_drop_cutter,
    simulation_work,
)

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

#: Most node-offset pairs this ball's closing on the seed's windows may take (about
#: half a second); beyond (a Ø3 ball over a whole 1025² grid after a thinned pass), it
#: is taken only near the nodes where the part bends about as sharply as the ball, and
#: elsewhere counted as reaching the part (the seed is then larger, never smaller).
MINE_WORK = 1 << 30

#: The cutting test's work is first judged on every this-many-th row and column.
SAMPLE = 8

#: Most windows (connected parts of a mask) a closing or CL is taken on one by one;
#: beyond, or when their area exceeds the bounding box's, on the bounding box.
MAX_WINDOWS = 64

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
        window): they depend on the part alone, so a ball's closing taken for its own
        seed serves again when it is the ball before (windows are block-aligned, so
        they often coincide).
    cell_bound : bool
        The plan's choice of the per-cell drop-cutter bound (:func:`zwcore.sim.coarse_grid`).
    """

    ran: list[Tool]
    closings: dict[tuple[object, ...], tuple[F64, F64]] = field(default_factory=dict)
    rho: F64 | None = field(default=None, repr=False)
    cell_bound: bool = False


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
    band_only : bool
        After the call: this ball's closing was over :data:`MINE_WORK` and was taken
        only near nodes where the part bends about as sharply as the ball (not at all
        when that too was over :data:`REST_CLOSING_WORK`).
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
    band_only: bool = False
    region: B8 | None = field(default=None, repr=False)

    def __call__(self, stock: F64) -> B8:
        """The region on the part's nodes, ``(ny, nx)`` bool, from the stock ``(ny, nx)``."""
        z = self.part.z
        rest = stock - z
        self.left_before = float(rest.max(initial=0.0))
        self.previous = self.shared.ran[-1]
        self.cut_tested = True
        self.band_only = False
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
        self.region = self._cutting(stock, grown) if self.grown_nodes else grown
        if self.region.any():
            self.shared.ran.append(self.tool)
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
            theirs = self._closing_near(seed, prev)
            seed = seed & (theirs > self.tolerance)
            if not seed.any():
                return seed
        else:  # too large a closing: compared with what the stock shows (more nodes)
            self.against_stock = True
            theirs = rest
        nodes = seed
        self.band_only = self._windows_work(nodes) > MINE_WORK
        if self.band_only:
            # this ball's closing exceeds the part mostly within 2R of where the part
            # bends about as sharply as it (same bound): there only; elsewhere 0, a
            # lower bound (more seed, never less); not at all when even that is over
            # the bound of the ball before's closing (the seed is then the stock's)
            nodes = seed & self._near_tight(self.tool)
            if self._windows_work(nodes) > REST_CLOSING_WORK:
                nodes = np.zeros(seed.shape, dtype=bool)
        mine = self._closing_near(nodes, self.tool)
        return seed & (mine < theirs - self.tolerance)

    def _windows_work(self, nodes: B8) -> int:
        """Node-offset pairs of this ball's closing on the windows of ``nodes``."""
        return sum(simulation_work((w[0].stop - w[0].start, w[1].stop - w[1].start),
                                   self.tool, self.part.dx, self.part.dy)
                   for w, _ in self._windows(nodes, 2.0 * self.tool.radius))

    def _cutting(self, stock: F64, grown: B8) -> B8:
        """Nodes of ``grown`` (``(ny, nx)`` bool) whose ball, at its drop-cutter CL on the
        part, lies below the stock ``(ny, nx)`` at some node where that stands more than
        the tolerance above the part: ``CL(c) < max over such nodes p within R of
        (stock(p) - h(|p - c|))``, the nodal drop of the ball on that stock."""
        z = self.part.z
        far = float(z.min()) - 1.0  # below every CL on the part: nothing to cut here
        material = np.where(stock - z > self.tolerance, stock, far)
        disc = math.pi * self.tool.radius ** 2 / (self.part.dx * self.part.dy)
        if self._surely_over(grown, material, disc):
            self.cut_tested = False
            return grown
        cl = self._cl_on(grown)
        # a ball whose tip lies below that stock at its own node cuts it (h(0) = 0): only
        # the other positions need the drop on the stock
        here = grown & (cl < material)
        asked = grown & ~here
        if int(asked.sum()) * disc > CUT_WORK:
            self.cut_tested = False
            return grown
        # the nodal drop on the stock sees every node of the grid: exact at every position.
        # Only whether it rises above the CL matters, so a query stops at its first node
        # above it and skips blocks without such material (``far`` nodes never are: the
        # same test as the whole drop, ``cl < max(material - h)``, far cheaper)
        above = np.where(material > far, material, -np.inf)
        return here | cutting_positions(above, cl, self.tool.radius, self.part.dx,
                                        self.part.dy, asked)

    def _surely_over(self, grown: B8, material: F64, disc: float) -> bool:
        """Whether the cutting test would be over :data:`CUT_WORK`, judged on every
        ``SAMPLE``-th row and column of ``grown`` with the nodal drop-cutter CL (never
        above the bilinear one the test uses, so it asks for no more positions than the
        test): a thinned pass before leaves stock over most of a large grid, and the
        bilinear CL over the whole grid alone costs seconds at 2049²."""
        s = SAMPLE
        sub = np.zeros(grown.shape, dtype=bool)
        sub[::s, ::s] = grown[::s, ::s]
        if int(sub.sum()) * s * s * disc <= CUT_WORK:
            return False
        low, _ = nodal_drop_cutter(self.part.z, self.tool.radius, self.part.dx, self.part.dy,
                                   sub)
        asked = sub & ~(low < material)
        return int(asked.sum()) * s * s * disc > CUT_WORK

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

    def _closing_near(self, nodes: B8, tool: Tool) -> F64:
        """The ball's bilinear closing minus the part at ``nodes`` (``(ny, nx)``, 0
        elsewhere), on each connected part's bounding box grown by ``2R`` and two cells."""
        out = np.zeros(nodes.shape)
        for win, own in self._windows(nodes, 2.0 * tool.radius):
            closed, _ = self._window_closing(win, tool)
            out[win][own] = closed[own]
        return out

    def _cl_on(self, nodes: B8) -> F64:
        """This ball's bilinear drop-cutter CL on the part at ``nodes`` (``(ny, nx)``,
        +inf elsewhere), on each connected part's bounding box grown by ``R`` and two
        cells."""
        out = np.full(nodes.shape, np.inf)
        for win, own in self._windows(nodes, self.tool.radius):
            out[win][own] = self._window_cl(win, self.tool)[own]
        return out

    def _windows(self, nodes: B8, reach: float
                 ) -> list[tuple[tuple[slice, slice], B8]]:
        """Windows over the clusters of ``nodes`` grown by ``reach`` and two cells, each
        with the mask of its own nodes (the nodes at least that far inside it).

        Clusters: connected parts of blocks of ``reach`` (one block apart: one window),
        so a speckled seed along a wall is one strip, not one box over the grid."""
        if not nodes.any():
            return []
        ga = math.ceil(reach / self.part.dy) + 2
        gb = math.ceil(reach / self.part.dx) + 2
        ny, nx = nodes.shape
        my, mx = -(-ny // ga), -(-nx // gb)
        pad = np.zeros((my * ga, mx * gb), dtype=bool)
        pad[:ny, :nx] = nodes
        blocks: B8 = np.asarray(pad.reshape(my, ga, mx, gb).any(axis=(1, 3)))
        labels, count = ndimage.label(blocks, structure=np.ones((3, 3), dtype=bool))

        def grow(sy: slice, sx: slice) -> tuple[slice, slice]:
            return (slice(max(0, sy.start * ga - ga), min(ny, sy.stop * ga + ga)),
                    slice(max(0, sx.start * gb - gb), min(nx, sx.stop * gb + gb)))

        wins = [grow(*b) for b in ndimage.find_objects(labels)]
        area = sum((w[0].stop - w[0].start) * (w[1].stop - w[1].start) for w in wins)
        rows = np.flatnonzero(blocks.any(axis=1))
        cols = np.flatnonzero(blocks.any(axis=0))
        whole = grow(slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1))
        if count > MAX_WINDOWS or area >= (whole[0].stop - whole[0].start) * (
                whole[1].stop - whole[1].start):
            return [(whole, nodes[whole])]
        fine = np.repeat(np.repeat(labels, ga, axis=0), gb, axis=1)[:ny, :nx]
        return [(w, nodes[w] & (fine[w] == n + 1)) for n, w in enumerate(wins)]

    def _padded(self, win: tuple[slice, slice], tool: Tool
                ) -> tuple[F64, tuple[slice, slice]]:
        """The part on ``win``, continued beyond the grid's edge by odd reflection (its
        slope there, no kink that would hold a ball up) by ``2R`` and two cells, and the
        window's place in it."""
        ny, nx = self.part.z.shape
        ga = math.ceil(2.0 * tool.radius / self.part.dy) + 2
        gb = math.ceil(2.0 * tool.radius / self.part.dx) + 2
        sy, sx = win
        pads = ((ga if sy.start == 0 else 0, ga if sy.stop == ny else 0),
                (gb if sx.start == 0 else 0, gb if sx.stop == nx else 0))
        z = self.part.z[win]
        padded = np.pad(z, pads, mode="reflect", reflect_type="odd")
        inner = (slice(pads[0][0], pads[0][0] + z.shape[0]),
                 slice(pads[1][0], pads[1][0] + z.shape[1]))
        return np.ascontiguousarray(padded), inner

    def _window_cl(self, win: tuple[slice, slice], tool: Tool) -> F64:
        padded, inner = self._padded(win, tool)
        part = ZMap(padded, dx=self.part.dx, dy=self.part.dy)
        return drop_cutter(part, tool, "bilinear", cell_bound=self.shared.cell_bound)[inner]

    def _window_closing(self, win: tuple[slice, slice], tool: Tool) -> tuple[F64, F64]:
        """Closing minus the part and drop-cutter CL on ``win`` (cached by window)."""
        key = (tool.id, tool.radius, win[0].start, win[0].stop, win[1].start, win[1].stop)
        cache = self.shared.closings
        if key not in cache:
            padded, inner = self._padded(win, tool)
            cl = drop_cutter(ZMap(padded, dx=self.part.dx, dy=self.part.dy), tool, "bilinear",
                             cell_bound=self.shared.cell_bound)
            closed = envelope(cl, tool, self.part.dx, self.part.dy, "bilinear")
            cache[key] = (closed[inner] - self.part.z[win], cl[inner])
        return cache[key]
