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
3. Tool choice (:mod:`zwcore.scanline._tool_choice`). Finishing: the estimate of
   reach on the part's nodes (:mod:`zwcore.scanline._regions`,
   :mod:`zwcore.scanline._reach`) ranks the main ball (least estimated finishing cut
   length), which machines the whole part; each smaller ball after it machines the
   region the simulated stock calls for when its stage begins
   (:mod:`zwcore.scanline._rest`); every finishing stage targets the part. The reach
   figures come from the final simulated stock (:mod:`zwcore.scanline._reach_figures`).
   Roughing: levels are taken from the
   finest towards the coarsest; a coarser level becomes a stage only when it admits a
   strictly larger ball than the stage after it, so radii never grow in machining
   order; a level that admits the same ball merges into the finer stage. A level
   admits a ball whose simulated rest on its nodes is at most a quarter of the next
   stage's flute length (balls spanning up to ``REST_MAX_CELLS`` level cells), or,
   beyond, one that fits its smallest concave radius (:mod:`zwcore.grid.curvature`).
4. The flute-length rule on the simulated stock
   (:mod:`zwcore.scanline._stage_passes`, :mod:`zwcore.scanline._stock`): every pass
   is simulated over the stock the earlier passes left (its real tool positions on its
   scan lines, CL from its model and never below the part's nodes); where a position
   would meet more than the flute length of stock within the ball's radius above its
   tip, the pass's model is raised there and another pass with the same tool at the
   same level follows, until one reaches the target (``pass_index`` of
   ``pass_count``). (It replaces the node-wise lift
   ``M_k = max(T_j, M_{k-1} + h_{k-1} + e_{k-1} - L_k)``, which held at the coarse
   nodes while the balls met far more between them.)
5. Pick-feeds strip by strip, extra lines cell by cell
   (:mod:`zwcore.scanline._passes`): the scallop rule with the slope *across*
   the scan lines; a strip between two grid lines that needs it gets extra
   lines, and each extra line runs only over the cells that need it (plus a
   lead-in and lead-out of one tool radius). The finishing pass must
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
from concurrent.futures import Future

import numpy as np
from numpy.typing import NDArray

from zwcore.errors import InvalidInputError
from zwcore.grid.tools import Tool, default_tools, tool_library
from zwcore.grid.zmap import ZMap, positive_number, stock_top_at_or_above
from zwcore.mrr.wavelets import Multiresolution, analyse
from zwcore.scanline._checks import figures
from zwcore.scanline._levels import default_stock as _default_stock
from zwcore.scanline._levels import first_level_and_guard as _first_level_and_guard
from zwcore.scanline._levels import targets_and_levels as _targets_and_levels
from zwcore.scanline._models import Target, nested_targets
from zwcore.scanline._passes import scallop_height
from zwcore.scanline._reach_figures import with_reach
from zwcore.scanline._regions import Chain, finishing_chain
from zwcore.scanline._stage_passes import MAX_MODEL_NODES, MAX_STAGES
from zwcore.scanline._stage_passes import passes as stage_passes
from zwcore.scanline._threads import both
from zwcore.scanline._tool_choice import (
    Level,
    Stage,
    ball_rest,
    choose,
    finishing_stages,
    levels,
)
from zwcore.scanline.results import (
    CHORD_SHARE,
    PATH_ALLOWANCE,
    SCALLOP_SHARE,
    ScanlineChecks,
    ScanlinePlan,
    ScanlineStage,
)

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

def _validate(tolerance: float, stock_top: float | None, top: float) -> tuple[float, float | None]:
    tol = positive_number(tolerance, "tolerance")
    return tol, None if stock_top is None else stock_top_at_or_above(stock_top, top)


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
        Finishing tolerance, mm, finite and > 0: what the finished surface may stand above
        the part where the plan finishes, the tool paths' chords included; the plan's
        scallops hold ``SCALLOP_SHARE`` of it (``ScanlinePlan.scallop_tolerance``).
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
    laps = _Laps()
    part = zmap.z
    top = float(part.max())
    user_tol, requested = _validate(tolerance, stock_top, top)
    # everything the plan decides holds its share; the rest is the tool paths' (results)
    tol = SCALLOP_SHARE * user_tol
    library = default_tools("ball") if tools is None else tool_library(tools, "ball")
    if not math.isfinite(curvature_smoothing) or curvature_smoothing < 0.0:
        raise InvalidInputError("curvature_smoothing",
                                f"must be finite and >= 0, got {curvature_smoothing!r}")
    laps("validate")

    mrr = analyse(part, "single_knot")
    laps("mrr")

    first, ceiling, g = _first_level_and_guard(zmap, mrr, library, requested)
    notes: list[str] = []
    # the first round's targets and levels (under the ceiling) do not depend on the
    # finishing chain: the plan's second thread builds them meanwhile (_threads)
    cache: dict[int, float] = {}
    # the ranking prices each main ball's roughing on these levels (under the default
    # stock: the ones it would build itself), asked for after its rests, when the second
    # thread has built them
    built: Future[tuple[list[Target], list[Level]]] = Future()

    def first_round() -> tuple[list[Target], list[Level]]:
        try:
            got = _targets_and_levels(zmap, mrr, first, ceiling, g, library,
                                      float(curvature_smoothing), cache)
        except BaseException as error:
            built.set_exception(error)
            raise
        built.set_result(got)
        return got

    early, chain = both(
        first_round,
        lambda: finishing_chain(part, zmap.dx, zmap.dy, list(library), tol,
                                levels=None if requested is not None
                                else lambda: built.result()[1]))
    laps("reach")
    st, chosen = _stages(zmap, mrr, first, ceiling, g, requested, library,
                         float(curvature_smoothing), notes, laps, chain, tol, early, cache)
    final: list[F64] = []
    # one choice for the plan and its paths (Chain.cell_bound: zwcore.sim.coarse_grid)
    passes = stage_passes(zmap, chosen, st, tol, g, notes, final, chain.cell_bound)
    laps("passes_simulated")

    stages, checks = figures(part, mrr.depth, zmap.dx, zmap.dy, passes, st, tol, g)
    stages, checks, reach = with_reach(zmap, stages, checks, chosen, chain, final[0], tol,
                                       notes)
    laps("figures_and_checks")
    notes.append(f"scallops, rest regions and the finished area planned to {tol:.4g} mm: "
                 f"{SCALLOP_SHARE:.0%} of the tolerance {user_tol:g} mm; the tool paths' "
                 f"chords take {CHORD_SHARE:.0%} of it and {PATH_ALLOWANCE:.0%} is kept for "
                 "their CL between the plan's positions")

    return ScanlinePlan(
        stock_top=st, stock_top_source="request" if requested is not None else "default",
        tolerance=user_tol, scallop_tolerance=tol, cell_bound=chain.cell_bound,
        depth=mrr.depth, stages=tuple(stages),
        tool_sequence=_tool_sequence(stages), checks=checks, notes=tuple(notes),
        timings=tuple(laps.timings), reach=reach, finished=_finished(zmap.z, final, tol))


def _finished(part: F64, final: list[F64], tol: float) -> NDArray[np.bool_]:
    """Where the simulated stock after the last pass lies within ``tol`` of the part *and*
    a finishing stage cut it: a node the roughing alone brought within the tolerance is
    not claimed (its paths may stand a twentieth of the ball's radius above their CL,
    :data:`zwcore.toolpath.plans.ROUGHING_REFINE`, where finishing paths keep to their
    chords)."""
    stock, roughed = final[0], final[1]
    return (stock - part <= tol) & (stock < roughed)


class _Laps:
    """Seconds per phase, in the order the phases end (a phase may recur)."""

    def __init__(self) -> None:
        self.timings: list[tuple[str, float]] = []
        self._last = time.perf_counter()

    def __call__(self, name: str) -> None:
        now = time.perf_counter()
        self.timings.append((name, now - self._last))
        self._last = now


def _stages(zmap: ZMap, mrr: Multiresolution, first: int, ceiling: float, g: float,
            requested: float | None, library: Sequence[Tool], smoothing: float,
            notes: list[str], laps: _Laps, chain: Chain, tol: float,
            early: tuple[list[Target], list[Level]] | None = None,
            cache: dict[int, float] | None = None) -> tuple[float, list[Stage]]:
    """The stock top and the chosen stages (coarse to fine), with ``notes`` filled.

    With a default stock the top follows the first stage's ball (its flute
    length), which may change the targets and so the tools: up to three
    rounds, then the tools are kept and the targets rebuilt under the stock.
    ``early``: the targets and levels under ``ceiling`` (the first round's), built
    already (:func:`_targets_and_levels`, with ``cache``).
    """
    approx = list(mrr.approximations)
    part = zmap.z
    top = float(part.max())
    depth = mrr.depth
    cache = {} if cache is None else cache
    st = ceiling
    built = math.nan
    chosen: list[Stage] = []
    for _ in range(3):
        if early is not None and st == ceiling:
            targets, levs = early
            built = st
        else:
            targets = nested_targets(approx, part, first, st, g)
            built = st
            laps("targets")
            levs = levels(zmap, depth, targets, smoothing, library, cache)
        laps("curvature")
        notes.clear()
        chosen = choose(levs, library, notes, chain, tol, zmap)
        laps("select")
        if requested is not None:
            break
        st = _default_stock(top, chosen[0].tool)
        if st == built:
            break
    if st != built:
        # The first tool kept changing with the stock: keep the tools, rebuild
        # the targets under the stock they imply.
        targets = nested_targets(approx, part, first, st, g)
        levs = levels(zmap, depth, targets, smoothing, library, cache)
        by_index = {lev.index: lev for lev in levs}
        # the finishing targets are capped by the finest roughing target: rebuilt too
        finishing = {c.tool.id: c for c in finishing_stages(levs, chain, tol, library, zmap)}
        chosen = [finishing[c.tool.id]._replace(merged=c.merged) if c.level.index == depth
                  else c._replace(
                      level=by_index[c.level.index],
                      rest=ball_rest(by_index[c.level.index], c.tool.radius) if c.rest > 0.0
                      else c.rest)
                  for c in chosen]
        laps("targets")
    return st, chosen


def _tool_sequence(stages: Sequence[ScanlineStage]) -> tuple[str, ...]:
    """Tool ids in machining order, one per tool change."""
    sequence: list[str] = []
    for s_ in stages:
        if not sequence or sequence[-1] != s_.tool.id:
            sequence.append(s_.tool.id)
    return tuple(sequence)
