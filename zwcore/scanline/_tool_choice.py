"""Tool choice of the scan-line plan: which level becomes a stage, with which ball.

Levels are taken from the finest (the part, which fixes the finishing tool)
towards the coarsest; a coarser level becomes a stage only when it admits a
strictly larger ball than the stage after it, so radii never grow in
machining order; a level that admits the same ball merges into the finer
stage. A level admits the largest library ball whose radius is at most its
target's smallest concave radius (:mod:`zwcore.grid.curvature`), or a larger
roughing ball when the material that ball cannot reach there (a grey closing
of the target by the ball, on the level's nodes) is at most a quarter of the
next stage's flute length: steep walls make every coarse model sharp at its
own grid scale.

:func:`choose` is the one place that decides tools; it sees only the level
models and the library, so another rule (a simulated choice, say) can
replace it without touching the passes or the figures.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from zwcore.grid.curvature import min_concave_radius
from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.scanline._models import Target

__all__ = ["REST_FLUTE_SHARE", "REST_MAX_CELLS", "Level", "Stage", "ball_rest", "choose",
           "levels"]

F64 = NDArray[np.float64]

#: Rest material a roughing ball may leave in its model's sharper valleys, as a
#: share of the next stage's flute length.
REST_FLUTE_SHARE = 0.25

#: The rest of an oversized ball is computed only where it spans at most this
#: many nodes of its level each way (beyond, the concave-radius rule decides).
REST_MAX_CELLS = 4


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


#: A chosen stage: its level, its ball, the coarser levels merged into it, and
#: the rest the ball leaves (0 when it fits the level's concave radius).
Stage = tuple[Level, Tool, list[int], float]


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

    Drop-cutter on the level's own nodes: the tool tip rests at
    ``max_y (A(x+y) - b(y))`` over the ball's footprint ``y``, with ``b`` the
    ball's lower hemisphere above its tip, and cuts down to
    ``min_y (tip(x-y) + b(y))``: a grey closing of ``A`` by ``-b``. The rest
    is that minus ``A``, over the nodes inside the input.
    """
    mx = math.floor(radius / lev.sx)
    my = math.floor(radius / lev.sy)
    oy, ox = np.mgrid[-my:my + 1, -mx:mx + 1]
    r2 = (ox * lev.sx) ** 2 + (oy * lev.sy) ** 2
    inside = r2 <= radius * radius
    hemi = radius - np.sqrt(np.where(inside, radius * radius - r2, 0.0))
    closed = ndimage.grey_closing(lev.model, footprint=inside, structure=-hemi, mode="nearest")
    rest = (closed - lev.model)[: lev.extent[0], : lev.extent[1]]
    return max(float(rest.max()), 0.0)


def choose(levels: list[Level], library: Sequence[Tool],
            notes: list[str]) -> list[Stage]:
    """Stages (level, tool, merged levels, rest) from coarse to fine; radii non-increasing."""
    finest = levels[-1]
    finish = finest.fit
    if finish is None:
        finish = library[-1]
        notes.append(
            f"no tool fits the smallest concave radius of the part "
            f"({finest.concave_radius:.4g} mm); finishing with the smallest ball "
            f"{finish.id} (R {finish.radius:g} mm) leaves material in the sharpest corners")
    chosen: list[Stage] = [(finest, finish, [], 0.0)]
    current = finish
    for lev in reversed(levels[:-1]):
        spacing = min(lev.sx, lev.sy)
        # An intermediate stage may use a ball larger than its model's concave
        # radius when what the ball cannot reach (its rest, grey closing on the
        # level's nodes) fits in a quarter of the next stage's flute length;
        # that rest counts against it like scallops do. Only tried where the
        # ball spans a few nodes (cheap, and the node sampling is fair).
        pick: tuple[Tool, float] | None = None
        for tool in library:
            if tool.radius <= current.radius:
                break
            allowance = REST_FLUTE_SHARE * min(current.flute_length, tool.flute_length)
            if spacing >= tool.diameter:
                continue  # the ball cannot follow this level's scan lines
            if tool.radius <= lev.concave_radius:
                pick = (tool, 0.0)
                break
            if tool.radius <= REST_MAX_CELLS * spacing:
                rest = ball_rest(lev, tool.radius)
                if rest <= allowance:
                    pick = (tool, rest)
                    break
        if pick is not None:
            chosen.append((lev, pick[0], [], pick[1]))
            current = pick[0]
        elif lev.fit is not None and lev.fit.id == current.id:
            chosen[-1][2].append(lev.index)
    chosen.reverse()
    return chosen
