"""The plan's first-round levels: the coarsest useful level, the stock ceiling and the
rounding guard, and the nested targets with their levels under a stock. The planner builds
them (:mod:`zwcore.scanline.planner`), and so does the finishing chain's ranking
(:mod:`zwcore.scanline._regions`) when it prices the roughing before a main ball on its
own."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.mrr.wavelets import Multiresolution
from zwcore.scanline._models import Target, nested_targets
from zwcore.scanline._tool_choice import Level, levels

__all__ = ["default_stock", "first_level_and_guard", "rounding_guard", "targets_and_levels"]


def rounding_guard(*values: float) -> float:
    # A few ulps of the largest magnitude in play: covers the rounding of one
    # subtraction and of evaluating the models at the input nodes.
    return 64.0 * float(np.finfo(np.float64).eps) * max(1.0, *(abs(v) for v in values))


def default_stock(top: float, tool: Tool) -> float:
    # A few ulps under top + L, so that the first pass's flute lift lands on
    # the top itself rather than a rounding above it (which would call for an
    # empty extra pass).
    st = top + tool.flute_length
    return st - 2.0 * rounding_guard(st, top, tool.flute_length)


def first_level_and_guard(zmap: ZMap, mrr: Multiresolution, library: Sequence[Tool],
                           requested: float | None) -> tuple[int, float, float]:
    """The coarsest useful level, the stock ceiling and the rounding guard ``g``.

    Levels whose spacing is at least the widest ball's diameter are of no use.
    """
    part = zmap.z
    top = float(part.max())
    approx = mrr.approximations
    depth = mrr.depth
    widest = library[0].diameter
    first = depth
    for j in range(depth + 1):
        s = mrr.scale(j)
        if min(zmap.dx * s, zmap.dy * s) < widest:
            first = j
            break
    longest = max(t.flute_length for t in library)
    ceiling = requested if requested is not None else default_stock(top, library[0])
    if requested is None:
        ceiling = max(ceiling, default_stock(top, max(library, key=lambda t: t.flute_length)))
    magnitude = max(abs(top), abs(float(part.min())), abs(ceiling), longest,
                    *(max(abs(float(a.max())), abs(float(a.min()))) for a in approx[first:]))
    g = rounding_guard(magnitude)
    # The nested margins need room under the stock: a stock at (or a hair
    # above) the part's top leaves none, and then only the finishing level is
    # planned (the flute lift alone reaches the part).
    if ceiling - top < 8.0 * (depth - first + 2) * 4.0 * g:
        first = depth
    return first, ceiling, g


def targets_and_levels(zmap: ZMap, mrr: Multiresolution, first: int, stock: float,
                        g: float, library: Sequence[Tool], smoothing: float,
                        cache: dict[int, float]) -> tuple[list[Target], list[Level]]:
    """The nested targets under ``stock`` and their levels (``cache``: the part's concave
    radius, filled)."""
    targets = nested_targets(list(mrr.approximations), zmap.z, first, stock, g)
    return targets, levels(zmap, mrr.depth, targets, smoothing, library, cache)
