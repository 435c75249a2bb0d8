"""Rest regions from the simulated stock: where a smaller finishing ball machines.

A rest ball's region is decided when its stage begins, from the stock the passes before
it really left (:mod:`zwcore.scanline._stock`), not from an estimate:

- *seed*: the input nodes where that stock lies more than ``tolerance`` above the part,
  and where this ball does better than what is there by more than ``tolerance``: its
  closing of the part (:func:`zwcore.sim.closing`, ``bilinear``, the surface meaning
  the passes drop the ball on, so a ball the wall chords hold up is held up here too)
  lies below the stock by more than ``tolerance``;
- *region*: the seed grown by the ball's radius (every position whose ball reaches a seed
  node is in it), on the part's nodes, which are the finishing stages' model nodes.

An empty region means the ball has nothing to do: its stage is dropped. So is a ball
that is not the last candidate when its seed is worth less than a tool change (its area
over the ball's flat pick-feed at the tolerance below :data:`TOOL_CHANGE_MM`): the
smaller balls after it do better there too (their closing is lower still), and the
smallest one is never dropped while it does better anywhere, so sharp corners are not
left for that reason. The closing is
computed on the seed's bounding box grown by ``2R`` and two cells (a node's closing
depends on the part within ``2R`` of it), so a few corners cost a few windows, not the
grid.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.scanline._reach import within_distance
from zwcore.scanline._regions import TOOL_CHANGE_MM, flat_pick_feed
from zwcore.sim import closing

__all__ = ["RestRegion"]

F64 = NDArray[np.float64]
B8 = NDArray[np.bool_]


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
    last : bool
        The smallest candidate (never dropped while it does better anywhere).
    seed_nodes : int
        After the call: the seed's node count (0 before, or when nothing is left).
    left_before : float
        After the call: most stock over the part when the stage began, mm.
    """

    part: ZMap
    tool: Tool
    tolerance: float
    last: bool = False
    seed_nodes: int = 0
    left_before: float = 0.0
    region: B8 | None = field(default=None, repr=False)

    def __call__(self, stock: F64) -> B8:
        """The region on the part's nodes, ``(ny, nx)`` bool, from the stock ``(ny, nx)``."""
        z = self.part.z
        rest = stock - z
        self.left_before = float(rest.max(initial=0.0))
        seed = rest > self.tolerance
        if seed.any():
            seed = self._better(seed, rest)
        self.seed_nodes = int(seed.sum())
        worth = self.seed_nodes * self.part.dx * self.part.dy / flat_pick_feed(
            self.tool.radius, self.tolerance)
        if not self.last and worth < TOOL_CHANGE_MM:
            seed = np.zeros(seed.shape, dtype=bool)
        self.region = within_distance(seed, self.tool.radius, self.part.dx, self.part.dy)
        return self.region

    def _better(self, seed: B8, rest: F64) -> B8:
        """Seed nodes where the ball's closing lies more than the tolerance below the stock."""
        dx, dy = self.part.dx, self.part.dy
        r = self.tool.radius
        ga, gb = math.ceil(2.0 * r / dy) + 2, math.ceil(2.0 * r / dx) + 2
        rows = np.flatnonzero(seed.any(axis=1))
        cols = np.flatnonzero(seed.any(axis=0))
        r0, r1 = max(0, rows[0] - ga), min(seed.shape[0], rows[-1] + ga + 1)
        c0, c1 = max(0, cols[0] - gb), min(seed.shape[1], cols[-1] + gb + 1)
        win = self.part.z[r0:r1, c0:c1]
        mine = closing(ZMap(np.ascontiguousarray(win), dx=dx, dy=dy), self.tool,
                       "bilinear") - win
        out = np.zeros(seed.shape, dtype=bool)
        out[r0:r1, c0:c1] = seed[r0:r1, c0:c1] & (mine < rest[r0:r1, c0:c1] - self.tolerance)
        return out
