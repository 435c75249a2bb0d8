"""Tool choice of the scan-line plan: which level becomes a stage, with which ball.

Finishing (issue 11): the estimate of reach on the part's nodes
(:mod:`zwcore.scanline._regions`) ranks the main ball, which machines the whole part;
every smaller ball after it is a candidate whose region is decided from the simulated
stock when its stage begins (:mod:`zwcore.scanline._rest`). Every finishing stage
targets the part: the flute rule on the simulated stock sees the rest as depth of cut.

Roughing: levels are taken from the finest towards the coarsest; a coarser level
becomes a stage only when it admits a strictly larger ball than the stage after it,
so radii never grow in machining order; a level that admits the same ball merges
into the finer stage. A level admits the largest library ball whose radius is at
most its target's smallest concave radius (:mod:`zwcore.grid.curvature`, the fast
first guess), or a larger ball when its simulated rest on the level's nodes (the
nodal closing of :mod:`zwcore.sim._nodal`) is at most a quarter of the next stage's
flute length ("what the next tool can take"): steep walls make every coarse model
sharp at its own grid scale.

:func:`choose` is the one place that decides tools; it sees only the level
models and the library, so another rule (a simulated choice, say) can
replace it without touching the passes or the figures.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from functools import partial
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from zwcore.grid.curvature import min_concave_radius
from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.scanline._chain import Chain
from zwcore.scanline._models import Target
from zwcore.scanline._reach import ball_reach
from zwcore.scanline._rest import RestRegion, RestShared
from zwcore.scanline._threads import both, split

__all__ = ["REST_FLUTE_SHARE", "REST_MAX_CELLS", "Level", "Stage", "StageReach", "ball_rest",
           "choose", "finishing_stages", "levels"]

F64 = NDArray[np.float64]

#: Rest material a roughing ball may leave in its model's sharper valleys, as a
#: share of the next stage's flute length.
REST_FLUTE_SHARE = 0.25

#: The rest of an oversized roughing ball is simulated only where it spans at most
#: this many nodes of its level each way (beyond, the concave-radius rule decides).
REST_MAX_CELLS = 8

#: Roughing rest is simulated to this resolution, mm (it is compared with a quarter of a
#: flute length).
REST_RESOLUTION = 1e-3


@dataclass
class Level:
    """One MRR level's target with its spacing, extents and concave radius."""

    index: int
    model: F64
    sx: float
    sy: float
    extent: tuple[int, int]  # nodes inside the input's extent
    cells: tuple[int, int]  # cells touching the input's extent
    concave_radius: float
    fit: Tool | None
    clipped: int
    raised: int
    #: the balls' rests on the model's nodes inside the input, by radius
    #: (:func:`ball_rest`; the finishing ranking prices roughing with the same ones)
    rests: dict[float, F64] = field(default_factory=dict, compare=False, repr=False)


@dataclass(frozen=True)
class StageReach:
    """What the reach simulation says about one stage (reported per stage).

    Attributes
    ----------
    area_fraction : float
        Share of the part's nodes in the stage's region (1: everywhere).
    boxes : tuple of (x_min, y_min, x_max, y_max, area)
        Bounding boxes of the region's connected parts, mm from the grid's first
        node, largest first (empty for a stage over the whole part).
    region_count : int
    cut_length : float or None
        Estimated cut length (region area / pick-feed holding the tolerance on a
        flat), mm; None for roughing stages (their ``path_length`` is the real one).
    rest_max : float
        Most material the ball leaves over its target (finishing: over the part), mm.
    reason : str
    """

    area_fraction: float
    boxes: tuple[tuple[float, float, float, float, float], ...]
    region_count: int
    cut_length: float | None
    rest_max: float
    reason: str


class Stage(NamedTuple):
    """A chosen stage: its level (whose ``model`` is the stage's target), its ball, the
    coarser levels merged into it, the rest the ball leaves that the next pass's
    flutes also take (in the model for finishing stages: 0), where it machines (on
    the level's nodes; None: everywhere; a :class:`RestRegion`: decided from the
    simulated stock when the stage begins) and the reach figures."""

    level: Level
    tool: Tool
    merged: list[int]
    rest: float
    region: NDArray[np.bool_] | RestRegion | None = None
    reach: StageReach | None = None


def _largest_fitting(library: Sequence[Tool], radius: float) -> Tool | None:
    for tool in library:  # largest first
        if tool.radius <= radius:
            return tool
    return None


def levels(zmap: ZMap, depth: int, targets: list[Target], smoothing: float,
            library: Sequence[Tool], cache: dict[int, float]) -> list[Level]:
    ny, nx = zmap.shape
    out = []
    for tg in targets:
        j = tg.level
        s = 1 << (depth - j)
        sx, sy = zmap.dx * s, zmap.dy * s
        extent = ((ny - 1) // s + 1, (nx - 1) // s + 1)
        cells = (-(-(ny - 1) // s), -(-(nx - 1) // s))
        rho = cache.get(j) if j == depth else None  # the part does not depend on the stock
        if rho is None:
            rho = min_concave_radius(tg.model, sx, sy, smoothing=smoothing, extent=extent)
            if j == depth:
                cache[j] = rho
        out.append(Level(j, tg.model, sx, sy, extent, cells, rho,
                          _largest_fitting(library, rho), tg.clipped, tg.raised))
    return out


def ball_rest(lev: Level, radius: float) -> float:
    """Largest height of material a ball of ``radius`` leaves in the level model's valleys.

    The ball's simulated reach on the level's own nodes
    (:func:`zwcore.scanline._reach.ball_reach`: the nodal closing, exact where the
    model bends more sharply than the ball and within ``2R`` of it, with a ball between
    nodes where node positions leave cusps), over the nodes inside the input.
    """
    return float(rest_map(lev, radius).max())


def rest_map(lev: Level, radius: float) -> F64:
    """:func:`ball_rest`'s map (kept on the level)."""
    got = lev.rests.get(radius)
    if got is None:
        model = lev.model[: lev.extent[0], : lev.extent[1]]
        got = ball_reach(model, lev.sx, lev.sy, radius, REST_RESOLUTION).rest
        lev.rests[radius] = got
    return got


def _rests(lev: Level, radii: list[float]) -> Iterator[float]:
    """:func:`ball_rest` of ``lev`` for ``radii`` in turn, computed as they are asked for;
    two at a time on two threads (:mod:`zwcore.scanline._threads`: the second alongside
    the first, maybe for nothing when the first is admitted). Each rest depends on the
    level and the radius alone: the same values as one by one."""
    n = 0
    while n < len(radii):
        if n + 1 < len(radii) and split() and radii[n] not in lev.rests:
            first, second = both(partial(ball_rest, lev, radii[n]),
                                 partial(ball_rest, lev, radii[n + 1]))
            yield first
            yield second
            n += 2
        else:
            yield ball_rest(lev, radii[n])
            n += 1


def finishing_stages(levels: list[Level], chain: Chain, tolerance: float,
                     library: Sequence[Tool], part: ZMap) -> list[Stage]:
    """The finishing stages (main ball first), all on the part itself.

    The main ball (the estimate's choice) machines the whole part; every later ball is
    a candidate whose region is decided from the simulated stock when its stage begins
    (:class:`zwcore.scanline._rest.RestRegion`): the estimate's chain, then every smaller
    library ball (a ball the estimate thought needless may be needed where the passes
    really leave material; an empty region drops the stage). Every stage's target is
    the part: the flute rule on the simulated stock sees the rest as depth of cut.
    """
    finest = levels[-1]
    balls = list(chain.balls)
    balls += [t for t in library if t.radius < balls[-1].radius]
    out: list[Stage] = []
    main = chain.main
    out.append(Stage(finest, main.tool, [], 0.0, None,
                     StageReach(1.0, (), 1, main.cut_length, main.rest_max, main.reason)))
    shared = RestShared([main.tool], rho=chain.rho, cell_bound=chain.cell_bound)
    for tool in balls[1:]:
        rule = RestRegion(part, tool, tolerance, shared, last=tool is balls[-1])
        out.append(Stage(finest, tool, [], 0.0, rule, None))
    return out


def choose(levels: list[Level], library: Sequence[Tool], notes: list[str],
           chain: Chain, tolerance: float, part: ZMap) -> list[Stage]:
    """Stages from coarse to fine; radii non-increasing; the finishing chain last."""
    finishing = finishing_stages(levels, chain, tolerance, library, part)
    chosen: list[Stage] = list(reversed(finishing))
    current = finishing[0].tool
    for lev in reversed(levels[:-1]):
        spacing = min(lev.sx, lev.sy)
        pick: tuple[Tool, float, str] | None = None
        # the simulated rests the loop below may ask for, in its order (library order,
        # radius descending)
        stop = next((n for n, t in enumerate(library) if t.radius <= current.radius),
                    len(library))
        rests = _rests(lev, [t.radius for t in library[:stop] if spacing < t.diameter
                             and t.radius <= REST_MAX_CELLS * spacing])
        for tool in library:
            if tool.radius <= current.radius:
                break
            allowance = REST_FLUTE_SHARE * min(current.flute_length, tool.flute_length)
            if spacing >= tool.diameter:
                continue  # the ball cannot follow this level's scan lines
            if tool.radius <= REST_MAX_CELLS * spacing:
                rest = next(rests)
                if rest <= allowance:
                    pick = (tool, rest, f"simulated reach on the level's nodes: leaves at most "
                            f"{rest:.4g} mm, within {allowance:g} mm (a quarter of the next "
                            f"flute length)")
                    break
            elif tool.radius <= lev.concave_radius:
                pick = (tool, 0.0, f"fits the level's concave radius "
                        f"({lev.concave_radius:.4g} mm; too large a footprint to simulate)")
                break
        if pick is not None:
            tool, rest, why = pick
            info = StageReach(1.0, (), 1, None, rest, why)
            chosen.append(Stage(lev, tool, [], rest, None, info))
            current = tool
        elif lev.fit is not None and lev.fit.id == current.id:
            chosen[-1].merged.append(lev.index)
    chosen.reverse()
    return chosen
