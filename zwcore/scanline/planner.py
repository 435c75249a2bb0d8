"""Scan-line plan for ball end mills (design section 3; seed 000, 6.1 and 6.2).

Everything comes off one lifted single-knot MRR of the part:

1. ``analyse(z, "single_knot")``: level ``j`` is a bilinear model of spacing
   ``(dx, dy) * 2**(J-j)`` that contains every finer level and the part.
   Levels whose spacing is at least the widest ball's diameter are of no use
   (no ball follows lines that far apart) and are dropped.
2. Nested targets (:mod:`zwcore.scanline._models`): the lift compounds at
   cliffs (on Mount Rushmore the coarse levels rise to 330 mm over a part top
   of 1.6 mm), so each level is clipped node by node to the target of the
   level before it (the first one to the stock top) and then minimally
   repaired upwards where the clip broke containment, checked at every input
   node the level's cells cover: ``T_j = repair(min(A_j, T_{j-1}))``. The
   targets nest exactly (``T_{j-1} >= T_j >= part`` at every input node, so
   at every point), never rise above the stock, and are the lifted level
   wherever that was already below the level before. Without the clip every
   coarse level of a walled part rose above the stock and was skipped, and
   the whole part was machined with the finishing ball.
3. Tool choice per level from its target (:mod:`zwcore.grid.curvature`): the
   largest library ball whose radius is at most the target's smallest concave
   radius. Levels are taken from the finest (the part, which fixes the
   finishing tool) towards the coarsest; a coarser level becomes a stage only
   when it admits a strictly larger ball than the stage after it, so radii
   never grow in machining order; a level that admits the same ball merges
   into the finer stage. A roughing level may also take a ball larger than
   its concave radius when the material that ball cannot reach there (a grey
   closing of the target by the ball, on the level's nodes) is at most a
   quarter of the next stage's flute length: steep walls make every coarse
   model sharp at its own grid scale.
4. Flute-length lift (Fig. 6) on the stage's own nodes:
   ``M_k = max(T_j, M_{k-1} + h_{k-1} + e_{k-1} - L_k + g)``, where
   ``h_{k-1}`` and ``e_{k-1}`` are the previous pass's scallop and rest
   (stock the flutes also have to take) and ``g`` a few ulps, upward. Where
   ``M_k`` still lies above ``T_j`` the part was out of reach: another pass
   with the same tool at the same level follows, until the target is reached
   (``pass_index`` of ``pass_count``).
5. Pick-feeds strip by strip (:mod:`zwcore.scanline._passes`): the scallop
   rule with the slope *across* the scan lines in each strip between two grid
   lines; only strips that need it get extra lines. The finishing pass must
   meet ``tolerance``; any other pass may leave at most half of the next
   pass's flute length (its scallops are stock for that pass).

The checks (:mod:`zwcore.scanline._checks`) evaluate every stage model once at
every input node, with the operations of
:func:`zwcore.grid.sampling.bilinear_at_fine_nodes`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from zwcore.errors import InvalidInputError, PlanningError
from zwcore.grid.curvature import min_concave_radius, steepest_slope
from zwcore.grid.sampling import bilinear_at_fine_nodes
from zwcore.grid.tools import Tool, default_tools, tool_library
from zwcore.grid.zmap import ZMap, positive_number, stock_top_at_or_above
from zwcore.mrr.wavelets import analyse
from zwcore.scanline._checks import PassSpec, axis_weights, eval_rows, figures
from zwcore.scanline._models import Target, nested_targets
from zwcore.scanline._passes import cross_slopes, plan_strips, scallop_height
from zwcore.scanline.results import ScanlineChecks, ScanlinePlan, ScanlineStage

__all__ = [
    "MAX_MODEL_NODES",
    "MAX_STAGES",
    "ScanlineChecks",
    "ScanlinePlan",
    "ScanlineStage",
    "plan_scanline",
    "scallop_height",
]

F64 = NDArray[np.float64]

#: A plan needing more passes than this is a stock/flute mismatch, not a plan
#: (and its stage models would not fit in memory for a large grid).
MAX_STAGES = 400

#: Stage-model nodes a plan may hold in all (2 GiB of float64): deep stock with
#: short flutes on a large grid means many full-resolution passes, and the plan
#: keeps every pass's model. Beyond this the request is refused, not the server.
MAX_MODEL_NODES = 1 << 28

#: An intermediate pass's scallops and rest may take at most this share of the
#: next pass's flute length (the rest of it is for the model difference).
SCALLOP_FLUTE_SHARE = 0.5

#: Rest material a roughing ball may leave in its model's sharper valleys, as a
#: share of the next stage's flute length.
REST_FLUTE_SHARE = 0.25

#: The rest of an oversized ball is computed only where it spans at most this
#: many nodes of its level each way (beyond, the concave-radius rule decides).
REST_MAX_CELLS = 4

#: Nodes per block of rows for the full-resolution work on pass models.
_BLOCK_NODES = 1 << 15


@dataclass
class _Level:
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


def _validate(tolerance: float, stock_top: float | None, top: float) -> tuple[float, float | None]:
    tol = positive_number(tolerance, "tolerance")
    return tol, None if stock_top is None else stock_top_at_or_above(stock_top, top)


def _largest_fitting(library: Sequence[Tool], radius: float) -> Tool | None:
    for tool in library:  # largest first
        if tool.radius <= radius:
            return tool
    return None


def _guard(*values: float) -> float:
    # A few ulps of the largest magnitude in play: covers the rounding of one
    # subtraction and of evaluating the models at the input nodes.
    return 64.0 * float(np.finfo(np.float64).eps) * max(1.0, *(abs(v) for v in values))


def _default_stock(top: float, tool: Tool) -> float:
    # A few ulps under top + L, so that the first pass's flute lift lands on
    # the top itself rather than a rounding above it (which would call for an
    # empty extra pass).
    st = top + tool.flute_length
    return st - 2.0 * _guard(st, top, tool.flute_length)


def _levels(zmap: ZMap, depth: int, targets: list[Target], smoothing: float,
            library: Sequence[Tool], cache: dict[int, float]) -> list[_Level]:
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
        out.append(_Level(j, tg.model, sx, sy, extent, cells, rho,
                          _largest_fitting(library, rho), tg.clipped, tg.raised))
    return out


def _ball_rest(lev: _Level, radius: float) -> float:
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


def _choose(levels: list[_Level], library: Sequence[Tool],
            notes: list[str]) -> list[tuple[_Level, Tool, list[int], float]]:
    """Stages (level, tool, merged levels, rest) from coarse to fine; radii non-increasing."""
    finest = levels[-1]
    finish = finest.fit
    if finish is None:
        finish = library[-1]
        notes.append(
            f"no tool fits the smallest concave radius of the part "
            f"({finest.concave_radius:.4g} mm); finishing with the smallest ball "
            f"{finish.id} (R {finish.radius:g} mm) leaves material in the sharpest corners")
    chosen: list[tuple[_Level, Tool, list[int], float]] = [(finest, finish, [], 0.0)]
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
                rest = _ball_rest(lev, tool.radius)
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


def _upsampled(coarse: F64, scale: int, shape: tuple[int, int]) -> F64:
    """``bilinear_at_fine_nodes(coarse, scale, shape)``, bit for bit, in blocks of rows.

    The whole-array version makes several full-size temporaries; on a large
    grid those cost more than the arithmetic (fresh pages, no cache reuse).
    """
    if scale == 1:
        return bilinear_at_fine_nodes(coarse, scale, shape)
    ny, nx = shape
    ya = axis_weights(scale, ny, coarse.shape[0])
    xa = axis_weights(scale, nx, coarse.shape[1])
    out = np.empty(shape)
    rows = max(1, _BLOCK_NODES // max(nx, 1))
    for a in range(0, ny, rows):
        b = min(a + rows, ny)
        out[a:b] = eval_rows(coarse, scale, a, b, ya, xa)
    return out


def _lift(on: F64, target: F64, shift: float) -> tuple[F64, bool]:
    """``max(target, on + shift)`` and whether ``on + shift`` stays at or below the target.

    In blocks of rows into the one array the pass keeps (no full-size
    temporaries); the same operations, node by node, as the whole-array form.
    """
    ny, nx = target.shape
    model = np.empty(target.shape)
    reached = True
    rows = max(1, _BLOCK_NODES // max(nx, 1))
    for a in range(0, ny, rows):
        b = min(a + rows, ny)
        lifted = on[a:b] + shift
        t = target[a:b]
        if reached and bool((lifted > t).any()):
            reached = False
        np.maximum(t, lifted, out=model[a:b])
    return model, reached


def _passes(zmap: ZMap, chosen: list[tuple[_Level, Tool, list[int], float]],
            stock_top: float, tolerance: float, g: float) -> list[PassSpec]:
    ny, nx = zmap.shape
    extent_mm = ((ny - 1) * zmap.dy, (nx - 1) * zmap.dx)
    out: list[PassSpec] = []
    prev: F64 | None = None
    prev_level = 0
    leaves = 0.0  # scallops and rest of the previous pass
    for n, (lev, tool, merged, rest) in enumerate(chosen):
        flute = tool.flute_length
        target = lev.model
        if prev is None:
            on = np.full(target.shape, stock_top)
        else:
            on = _upsampled(prev, 1 << (lev.index - prev_level), target.shape)
        next_flute = chosen[n + 1][1].flute_length if n + 1 < len(chosen) else None
        # Every pass of this stage is max(T, S + c) with S the incoming model
        # (or an earlier pass, itself such a max): the difference across any
        # cell edge is at most the larger of the two, so one bound per strip
        # serves every pass (an upper bound: the scallop is never
        # underestimated). The last pass is the target itself and gets its own
        # slopes.
        ax_t, ay_t = cross_slopes(target, lev.sx, lev.sy, lev.cells)
        if prev is None:
            ax_b, ay_b = ax_t, ay_t
        else:
            ax_o, ay_o = cross_slopes(on, lev.sx, lev.sy, lev.cells)
            ax_b, ay_b = np.maximum(ax_t, ax_o), np.maximum(ay_t, ay_o)
        slope_t = steepest_slope(target, lev.sx, lev.sy, extent=lev.cells)
        slope_b = slope_t if prev is None else max(
            slope_t, steepest_slope(on, lev.sx, lev.sy, extent=lev.cells))
        while True:
            model, reached = _lift(on, target, leaves - flute + g)
            finishing = reached and next_flute is None
            if finishing:
                budget = tolerance
                what = f"the tolerance {tolerance:g} mm"
            else:
                following = flute if not reached or next_flute is None else next_flute
                budget = SCALLOP_FLUTE_SHARE * min(flute, following) - rest
                what = f"half the next pass's flute length ({budget:g} mm)"
            ax, ay = (ax_t, ay_t) if reached else (ax_b, ay_b)
            strips = plan_strips(ax, ay, lev.sx, lev.sy, extent_mm, tool.radius, budget, what)
            out.append(PassSpec(lev.index, lev.sx, lev.sy, tool, model, strips,
                                slope_t if reached else slope_b, rest, tuple(merged),
                                lev.concave_radius, lev.clipped, lev.raised))
            if len(out) > MAX_STAGES:
                raise PlanningError(
                    "tools", f"reaching the part within the flute lengths needs more than "
                    f"{MAX_STAGES} passes (stock top {stock_top:g} mm, lowest point "
                    f"{float(zmap.z.min()):g} mm); use longer flutes or a lower stock")
            if sum(p.model.size for p in out) > MAX_MODEL_NODES:
                raise PlanningError(
                    "grid", f"the plan's {len(out)}+ passes would hold more than "
                    f"{MAX_MODEL_NODES} model nodes; send a coarser grid, longer flutes or "
                    f"a lower stock")
            leaves = out[-1].leaves
            if reached:
                break
            on = model
        prev = model
        prev_level = lev.index
    return out


def plan_scanline(zmap: ZMap, tools: Sequence[Tool] | None = None, *, tolerance: float = 0.01,
                  stock_top: float | None = None,
                  curvature_smoothing: float = 0.0) -> ScanlinePlan:
    """Plan scan-line machining of a z-map with ball end mills.

    Parameters
    ----------
    zmap : ZMap
        The finished part, ``(ny, nx)`` heights.
    tools : sequence of Tool, optional
        Ball end mills in the crib (default: the shipped library).
    tolerance : float
        Finishing scallop height, mm, finite and > 0.
    stock_top : float, optional
        Height of the flat stock; at least the part's highest point. Default:
        the highest point plus the first tool's flute length.
    curvature_smoothing : float
        Gaussian smoothing in cells before estimating concave radii (0: none;
        see :mod:`zwcore.grid.curvature`, for noisy scans).

    Returns
    -------
    ScanlinePlan

    Raises
    ------
    InvalidInputError
        Bad ``tolerance``, ``stock_top`` or tool library.
    PlanningError
        The flute lengths would need more than :data:`MAX_STAGES` passes.
    """
    clock = [time.perf_counter()]
    timings: list[tuple[str, float]] = []

    def lap(name: str) -> None:
        now = time.perf_counter()
        timings.append((name, now - clock[0]))
        clock[0] = now

    part = zmap.z
    top = float(part.max())
    tol, requested = _validate(tolerance, stock_top, top)
    library = default_tools("ball") if tools is None else tool_library(tools, "ball")
    if not math.isfinite(curvature_smoothing) or curvature_smoothing < 0.0:
        raise InvalidInputError("curvature_smoothing",
                                f"must be finite and >= 0, got {curvature_smoothing!r}")
    lap("validate")

    mrr = analyse(part, "single_knot")
    approx = list(mrr.approximations)
    depth = mrr.depth
    lap("mrr")

    widest = library[0].diameter
    first = depth
    for j in range(depth + 1):
        s = mrr.scale(j)
        if min(zmap.dx * s, zmap.dy * s) < widest:
            first = j
            break
    longest = max(t.flute_length for t in library)
    ceiling = requested if requested is not None else _default_stock(top, library[0])
    if requested is None:
        ceiling = max(ceiling, _default_stock(top, max(library, key=lambda t: t.flute_length)))
    magnitude = max(abs(top), abs(float(part.min())), abs(ceiling), longest,
                    *(max(abs(float(a.max())), abs(float(a.min()))) for a in approx[first:]))
    g = _guard(magnitude)
    # The nested margins need room under the stock: a stock at (or a hair
    # above) the part's top leaves none, and then only the finishing level is
    # planned (the flute lift alone reaches the part).
    if ceiling - top < 8.0 * (depth - first + 2) * 4.0 * g:
        first = depth

    notes: list[str] = []
    cache: dict[int, float] = {}
    st = ceiling
    built = math.nan
    chosen: list[tuple[_Level, Tool, list[int], float]] = []
    for _ in range(3):
        targets = nested_targets(approx, part, first, st, g)
        built = st
        lap("targets")
        levels = _levels(zmap, depth, targets, float(curvature_smoothing), library, cache)
        lap("curvature")
        notes = []
        chosen = _choose(levels, library, notes)
        lap("select")
        if requested is not None:
            break
        st = _default_stock(top, chosen[0][1])
        if st == built:
            break
    if st != built:
        # The first tool kept changing with the stock: keep the tools, rebuild
        # the targets under the stock they imply.
        targets = nested_targets(approx, part, first, st, g)
        levels = _levels(zmap, depth, targets, float(curvature_smoothing), library, cache)
        by_index = {lev.index: lev for lev in levels}
        chosen = [(by_index[lev.index], tool, merged,
                   _ball_rest(by_index[lev.index], tool.radius) if rest > 0.0 else rest)
                  for lev, tool, merged, rest in chosen]
        lap("targets")
    passes = _passes(zmap, chosen, st, tol, g)
    lap("flute_lift")

    stages, checks = figures(part, depth, zmap.dx, zmap.dy, passes, st, tol)
    lap("figures_and_checks")

    sequence: list[str] = []
    for s_ in stages:
        if not sequence or sequence[-1] != s_.tool.id:
            sequence.append(s_.tool.id)
    return ScanlinePlan(
        stock_top=st, stock_top_source="request" if requested is not None else "default",
        tolerance=tol, depth=depth, stages=tuple(stages),
        tool_sequence=tuple(sequence), checks=checks, notes=tuple(notes),
        timings=tuple(timings))
