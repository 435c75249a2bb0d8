"""The contour plan: flat end mills, waterline roughing and semi-finishing
(design section 4; seed 000, sections 5.2 and 6.3, Fig. 7 and 8).

Pipeline:

1. Lifted Haar MRR of the part: level ``j`` holds block maxima, so every
   level model contains the part (design 2).
2. Each tool works at the finest level whose cell is at least its diameter, so
   every region of the stage model is wide enough for it. Tools that land on
   the same level are redundant: the largest is kept.
3. Heavy roughing (first, largest tool): evenly spaced contour heights from the
   stock top down to the lowest point of its level model, the fewest slabs no
   thicker than the flute length.
4. Later stages: contour heights between the previous stage model and the own
   level model such that every slab removes the same volume (``uniform_load``),
   or evenly spaced (``even_step``). The slab count aims at a nominal step-down
   of ``min(diameter, flute length)`` (an axial depth of about one diameter, the
   usual limit for solid-carbide end mills in full engagement); no spacing
   exceeds the flute length. Where no slab within the flute removes the stage's
   slab volume, the slab is exactly the flute length and flagged; every other
   slab removes the same volume, the bottom one included
   (:func:`zwcore.contour.heights.place_equal_volume` states the rule). A
   stage with no slab (the stages before it already reached its level model)
   removes nothing and is dropped, with a note; the others are as if it were
   there (its model would be the previous one).
5. The stage model is produced from the part's lifted Haar representation from
   the stage level up: the level's approximation coefficients raised onto the
   contour grid, the finer details set to zero, synthesised to the input nodes
   (:mod:`zwcore.mrr.terraces`); the checks compare it with the terrace rule applied
   on its own.

Models use ``cell`` semantics: a level-``j`` value is a flat cell over a
``2**s x 2**s`` block of input nodes (``s = J - j``), and models are compared at
every input node.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from zwcore.contour.heights import (
    QUANTUM,
    SlabVolumes,
    ceil_units,
    even_heights,
    floor_units,
    place_equal_volume,
    removed_between,
    volume_spread,
)
from zwcore.contour.results import VOLUME_SPREAD_LIMIT, ContourChecks, ContourPlan, ContourStage
from zwcore.errors import InvalidInputError
from zwcore.grid.sampling import cells_at_fine_nodes
from zwcore.grid.tools import Tool, default_tools, tool_library
from zwcore.grid.zmap import ZMap, stock_top_at_or_above
from zwcore.mrr.terraces import cell_weights, edit_coefficients, terrace
from zwcore.mrr.wavelets import Multiresolution, analyse

__all__ = [
    "STRATEGIES",
    "VOLUME_SPREAD_LIMIT",
    "ContourChecks",
    "ContourPlan",
    "ContourStage",
    "level_for_tool",
    "plan_contour",
]

F64 = NDArray[np.float64]
Strategy = Literal["uniform_load", "even_step"]

#: ``uniform_load``: the seed's equal-volume heights (default). ``even_step``:
#: a constant step-down per stage, as most CAM systems offer.
STRATEGIES: tuple[Strategy, ...] = ("uniform_load", "even_step")

# Relative tolerance for "cell at least the diameter" (0.1 mm x 64 vs 6.4 mm).
_SIZE_RTOL = 1e-12


def _strategy(name: str) -> Strategy:
    key = str(name).strip().lower().replace("-", "_")
    for s in STRATEGIES:
        if key == s:
            return s
    raise InvalidInputError("strategy", f"unknown strategy {name!r}; valid: "
                            f"{', '.join(STRATEGIES)}")


def level_for_tool(tool: Tool, depth: int, dx: float, dy: float) -> tuple[int, str]:
    """The finest level whose cell is at least the tool's diameter.

    Parameters
    ----------
    tool : Tool
    depth : int
        ``J``, the input's level.
    dx, dy : float
        Input node spacing, mm.

    Returns
    -------
    level : int
    rule : str
        The rule in words, with the cell size. When even the coarsest cell
        (which covers the whole part) is narrower than the tool, the coarsest
        level is used and the rule says so.
    """
    need = tool.diameter * (1.0 - _SIZE_RTOL)
    for j in range(depth, -1, -1):
        s = 1 << (depth - j)
        cx, cy = dx * s, dy * s
        if min(cx, cy) >= need:
            return j, (f"finest level whose cell ({cx:g} x {cy:g} mm) is at least the tool "
                       f"diameter ({tool.diameter:g} mm)")
    s = 1 << depth
    return 0, (f"coarsest level (cell {dx * s:g} x {dy * s:g} mm): no level's cell reaches "
               f"the tool diameter ({tool.diameter:g} mm); the whole part is one cell")


def _stock_top(value: float | None, part_top: float, first: Tool,
               ) -> tuple[float, Literal["request", "default"], str]:
    if value is None:
        top = part_top + first.flute_length
        return top, "default", (f"stock_top defaults to the part's highest point "
                                f"({part_top:g} mm) plus the first tool's flute length "
                                f"({first.flute_length:g} mm): {top:g} mm")
    v = stock_top_at_or_above(value, part_top)
    return v, "request", f"stock_top {v:g} mm as requested"


def _select(tools: Sequence[Tool], depth: int, dx: float, dy: float,
            ) -> tuple[list[tuple[Tool, int, str]], list[str]]:
    """Keep the largest tool per level (the library is sorted largest first)."""
    kept: dict[int, tuple[Tool, int, str]] = {}
    notes = []
    for tool in tools:
        j, rule = level_for_tool(tool, depth, dx, dy)
        if j in kept:
            notes.append(f"{tool.id} not used: it lands on level {j} with {kept[j][0].id}, "
                         f"and the largest tool on a level is kept")
            continue
        kept[j] = (tool, j, rule)
    return sorted(kept.values(), key=lambda t: t[1]), notes


@dataclass
class _Heights:
    units: list[int]
    capped: list[bool]
    rule: str
    nominal: float


def _heights(k: int, strategy: Strategy, tool: Tool, level_model: F64, previous: F64,
             weight: F64) -> _Heights:
    """Contour heights of one stage, in units of QUANTUM (descending)."""
    # Cells the stage lowers: a cell whose level model rounds up (to the height
    # quantum) onto its previous model stays where it is, and nothing is removed
    # there at any height, so it must not stretch the range (a flat part of the
    # volume function, at the bottom or the top, would only get empty slabs).
    cut = np.ceil(level_model / QUANTUM) * QUANTUM < previous
    if not cut.any():  # the previous model already is this level's model here
        return _Heights([], [], "even_flute" if k == 0 else strategy, tool.flute_length)
    lower, upper = level_model[cut], previous[cut]
    top_u = floor_units(float(upper.max()))  # previous heights are on the quantum grid
    bottom_u = ceil_units(float(lower.min()))
    cap_u = max(1, floor_units(tool.flute_length))
    span = top_u - bottom_u
    if k == 0:
        n = -(-span // cap_u)
        units = even_heights(top_u, bottom_u, n) if n else [top_u]
        # Evenly spaced (design 4.3), not equal volume; a slab counts as capped
        # only where the even spacing is the flute length itself.
        return _Heights(units, [a - b == cap_u for a, b in itertools.pairwise(units)],
                        "even_flute", tool.flute_length)
    nominal = min(tool.flute_length, tool.diameter)
    step_u = max(1, floor_units(nominal))
    n = max(1, -(-span // step_u))
    if span <= 0:
        return _Heights([top_u], [], strategy, nominal)
    if strategy == "even_step":
        return _Heights(even_heights(top_u, bottom_u, n), [False] * n, "even_step", nominal)
    sv = SlabVolumes(lower, upper, weight[cut])
    res = place_equal_volume(sv, top_u, bottom_u, cap_u, n)
    return _Heights(res.heights, res.capped, "equal_volume", nominal)


def plan_contour(zmap: ZMap, tools: Sequence[Tool] | None = None, *,
                 stock_top: float | None = None, strategy: str = "uniform_load",
                 timings: dict[str, float] | None = None) -> ContourPlan:
    """Plan waterline roughing and semi-finishing with flat end mills.

    Parameters
    ----------
    zmap : ZMap
        The finished part, ``(ny, nx)`` heights.
    tools : sequence of Tool, optional
        Flat end mills (default: the shipped library). Sorted largest first; the
        largest tool per level is used.
    stock_top : float, optional
        Top of the stock, at or above the part's highest point (default: that
        point plus the first tool's flute length).
    strategy : {"uniform_load", "even_step"}
        Height placement of the stages after heavy roughing.
    timings : dict, optional
        When given, receives the seconds spent per phase (``mrr``, ``heights``,
        ``terraces``, ``checks``).

    Returns
    -------
    ContourPlan

    Raises
    ------
    InvalidInputError
        Unknown strategy, bad stock top, bad tool library.
    """
    t0 = time.perf_counter()
    strat = _strategy(strategy)
    lib = default_tools("flat") if tools is None else tool_library(tools, "flat")
    if not isinstance(zmap, ZMap):
        raise InvalidInputError("grid", "must be a ZMap")
    z = zmap.z
    part_top = float(z.max())
    top, source, top_note = _stock_top(stock_top, part_top, lib[0])
    mrr = analyse(z, "haar")
    depth = mrr.depth
    chosen, notes = _select(lib, depth, zmap.dx, zmap.dy)
    notes = [top_note, *notes]
    phase = {"mrr": time.perf_counter() - t0, "heights": 0.0, "terraces": 0.0, "checks": 0.0}

    stages: list[ContourStage] = []
    prev: tuple[F64, int] | None = None
    top_q = ceil_units(top) * QUANTUM
    acc = _Checks(zmap, top_q)
    for k, (tool, j, rule) in enumerate(chosen):
        # A stage that would remove nothing is dropped without changing the
        # others: the next one starts from the same model and keeps its rule.
        stage = _stage(zmap, mrr, k, (tool, j, rule), strat, prev, top_q, acc, phase)
        if stage is None:
            notes.append(f"{tool.id} not used: at level {j} it would remove nothing (the "
                         f"stages before it already reached that level's model)")
            continue
        stages.append(stage)
        prev = (stage.model, j)

    checks = acc.result(stages)
    if timings is not None:
        timings.update(phase)
    notes.extend(_closing_notes(stages, depth, strat))
    return ContourPlan(
        stock_top=top, stock_top_source=source, strategy=strat, stages=tuple(stages),
        contour_spacings=tuple(sp for st in stages for sp in st.spacings), checks=checks,
        notes=tuple(notes))


def _stage(zmap: ZMap, mrr: Multiresolution, k: int, choice: tuple[Tool, int, str],
           strat: Strategy, prev: tuple[F64, int] | None, top_q: float, acc: _Checks,
           phase: dict[str, float]) -> ContourStage | None:
    """Stage ``k``: heights, the edited model, slab volumes and its checks.

    ``prev`` is the previous stage's model and level (``None``: the stock at
    ``top_q``); ``phase`` accumulates the seconds per phase. ``None`` when the
    stage has no slab or its slabs remove no volume: it would remove nothing,
    and is no stage.
    """
    tool, j, rule = choice
    z = zmap.z
    t1 = time.perf_counter()
    level_model = mrr.approximations[j]
    s = mrr.scale(j)
    weight = cell_weights(level_model.shape, s, z.shape, zmap.cell_area)
    if prev is None:
        previous = np.full(level_model.shape, top_q)
    else:
        previous = cells_at_fine_nodes(prev[0], 1 << (j - prev[1]), level_model.shape)
    h = _heights(k, strat, tool, level_model, previous, weight)
    z_levels = np.array(h.units, dtype=np.float64) * QUANTUM
    t2 = time.perf_counter()
    phase["heights"] += t2 - t1
    if len(h.units) < 2:
        return None
    # The stage model: the part's representation from level j up, edited
    # (approximation raised onto the contour grid, finer details zeroed)
    # and synthesised to the input nodes.
    edited = edit_coefficients(mrr, j, previous, z_levels)
    model = edited.approximation
    fine = edited.synthesize()
    vols = removed_between(previous.ravel(), model.ravel(), weight.ravel(), z_levels)
    t3 = time.perf_counter()
    phase["terraces"] += t3 - t2
    if not float(vols.sum()) > 0.0:  # it lowers only cells outside the grid
        return None
    # The terrace rule applied on its own (cells, then every input node).
    rule_fine = cells_at_fine_nodes(terrace(level_model, previous, z_levels), s, z.shape)
    exact = bool(fine.shape == rule_fine.shape and np.array_equal(fine, rule_fine))
    left = acc.stage(fine, float(vols.sum()), exact)
    t4 = time.perf_counter()
    phase["checks"] += t4 - t3
    return ContourStage(
        tool=tool, level=j, scale=s, cell_size=(zmap.dx * s, zmap.dy * s),
        origin=(zmap.x0 + 0.5 * (s - 1) * zmap.dx, zmap.y0 + 0.5 * (s - 1) * zmap.dy),
        level_rule=rule, spacing_rule=h.rule, nominal_step=float(h.nominal),
        z_levels=tuple(float(v) for v in z_levels),
        spacings=tuple(float(v) for v in (z_levels[:-1] - z_levels[1:])),
        slab_volumes=tuple(float(v) for v in vols),
        volume_spread=volume_spread(vols, h.capped),
        flute_cap_binds=tuple(bool(c) for c in h.capped), removed_volume=float(vols.sum()),
        max_stock_left=left[0], mean_stock_left=left[1],
        edited_coefficients=edited.edited, model=model)


def _closing_notes(stages: Sequence[ContourStage], depth: int, strat: Strategy) -> list[str]:
    """What the plan leaves and how it placed its heights, in words."""
    notes = []
    if stages and stages[-1].level < depth:
        last = stages[-1]
        notes.append(f"the smallest tool works at level {last.level} (cell "
                     f"{last.cell_size[0]:g} x {last.cell_size[1]:g} mm); up to "
                     f"{last.max_stock_left:g} mm of stock is left for finishing")
    if len(stages) > 1:
        notes.append(
            "after heavy roughing, each stage aims at a step-down of min(diameter, flute "
            "length) and places its heights " + ("for equal slab volumes (uniform load)"
                                                 if strat == "uniform_load" else "evenly"))
    notes.append(f"contour heights lie on a {QUANTUM:g} mm grid, rounded up (never into the "
                 f"part), so the edited Haar coefficients synthesise the terraces exactly")
    return notes


class _Checks:
    """The invariants at every input node, stage by stage (one fine model held)."""

    def __init__(self, zmap: ZMap, top_q: float) -> None:
        self.zmap = zmap
        self.top_q = top_q
        self.prev: F64 | None = None
        self.margin = math.inf
        self.add_up = True
        self.exact = True

    def stage(self, fine: F64, removed: float, exact: bool) -> tuple[float, float]:
        """Check one stage's synthesised model; returns (max, mean) stock left."""
        zm = self.zmap
        z = zm.z
        if self.prev is None:
            between = float((self.top_q - fine).sum()) * zm.cell_area
        else:
            self.margin = min(self.margin, float((self.prev - fine).min()))
            between = float((self.prev - fine).sum()) * zm.cell_area
        scale = max(abs(between), float(np.abs(fine).max()) * zm.cell_area * z.size, 1.0)
        self.add_up &= abs(removed - between) <= 1e-9 * scale
        self.exact &= exact
        left = fine - z
        self.margin = min(self.margin, float(left.min()))
        self.prev = fine
        return float(left.max()), float(left.mean())

    def result(self, stages: list[ContourStage]) -> ContourChecks:
        spacings = [(sp, st.tool.flute_length) for st in stages for sp in st.spacings]
        spreads = [st.volume_spread for st in stages if st.spacing_rule == "equal_volume"]
        margin = self.margin
        return ContourChecks(
            containment=bool(margin >= 0.0),
            min_containment_margin=float(margin) if math.isfinite(margin) else 0.0,
            spacings_within_flute=all(sp <= fl for sp, fl in spacings),
            spacings_positive=all(sp > 0.0 for sp, _ in spacings),
            max_volume_spread=max(spreads, default=0.0),
            volumes_add_up=bool(self.add_up),
            terraces_from_coefficients=bool(self.exact))
