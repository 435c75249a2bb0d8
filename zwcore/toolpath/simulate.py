"""Simulation of a parsed NC program on a stock z-map, and the verification figures.

Every move of :class:`~zwcore.toolpath.parse.ParsedProgram` is swept with the active tool
(ball or flat, looked up by tool number) on the stock grid at the part's resolution, in
program order: lines exactly on the nodes (:func:`~zwcore.toolpath.sweep.sweep_moves`),
arcs as chords with the radius grown by their sagitta (conservative). Each rapid is checked
against the stock as the earlier moves left it. A move that repeats, exactly, one the same
tool made and cut with before is not swept again: the stock is already at or under its
envelope (it removes nothing, ``<= 0`` over the stock) and its gouge is that move's.
"""

from __future__ import annotations

import functools
import itertools
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from zwcore.errors import InvalidInputError
from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.toolpath import sweep as sweep_mod
from zwcore.toolpath._repeats import RepeatTable
from zwcore.toolpath.parse import ParsedProgram
from zwcore.toolpath.sweep import BlockBounds, GridFrame, arc_chords, block_size, sweep_moves

__all__ = ["ProgramCheck", "ProgramSimulation", "StageCheck", "StretchRun", "simulate_program",
           "simulate_stretch", "stock_grid", "tool_spans"]

F64 = NDArray[np.float64]

#: Largest arc-to-chord distance in the simulation, as a fraction of the grid step.
ARC_SAGITTA_FRACTION = 1e-3
#: Removal below this (mm) is float rounding, not cutting.
CUT_EPS = 1e-9
#: Skip sweeping moves that repeat, end points and radius alike, a move of the same tool
#: stretch that cut before (:mod:`~zwcore.toolpath._repeats`): they remove nothing, their
#: gouge is that move's (a test checks every figure is the same without the skip).
SKIP_REPEATS = True
#: Skip blocks of nodes a move provably leaves alone (:class:`~zwcore.toolpath.sweep.
#: BlockBounds`): the stock and every figure are the same (a test compares).
SKIP_BLOCKS = True
#: Leave out of a feed move that continues the one before it the nodes only its start's
#: sphere reaches (:func:`~zwcore.toolpath.sweep.trailing_cuts`: the move before cut them at
#: least as low). The stock and every figure are the same (to float rounding; a node below
#: the part there counts for the move before); a test compares.
SKIP_TRAILING = True
#: A rapid touching the stock by less than this (mm) is a tie (a retract from the position
#: that just cut there), not a rapid through material.
TIE_EPS = 1e-6


@dataclass(frozen=True)
class StageCheck:
    """Figures of one tool's stretch of the program.

    Attributes
    ----------
    tool_number : int
    moves : int
    over_model_max : float or None
        Largest simulated stock minus the stage model after the stage (``None`` without
        a model), mm.
    over_model_p95 : float or None
    gouge : float
        Largest part minus simulated stock after the stage (> 0: cut into the part), mm.
    rapid_in_material : float
        Deepest a rapid of the stage went into the stock it met, mm (must be 0).
    removed_volume : float
        mm³ (node area times the height removed).
    air_feed_length : float
        Length of feed moves that met no material (stock as the earlier moves left it), mm.
    feed_length : float
    below_part_moves : int
        Moves whose sweep reaches below the part at some node.
    """

    tool_number: int
    moves: int
    over_model_max: float | None
    over_model_p95: float | None
    gouge: float
    rapid_in_material: float
    removed_volume: float
    air_feed_length: float
    feed_length: float
    below_part_moves: int


@dataclass(frozen=True, eq=False)
class ProgramCheck:
    """Verification of a program by simulation.

    Attributes
    ----------
    gouge : float
        ``max(part - machined)`` over the nodes, mm; 0 (to float rounding) when no move cut
        into the part.
    below_part_moves : int
        Moves whose sweep reaches below the part at some node.
    final_over_part_max, final_over_part_p95 : float
        Machined minus part over all the nodes, mm.
    finished_over_part_max : float
        The same over ``reach`` (where the plan says it finishes; all nodes when not
        given), mm.
    finished_area_fraction : float
        Share of the nodes in ``reach`` (1 when not given).
    within_tolerance : bool
        ``finished_over_part_max <= tolerance``.
    rapid_in_material : float
        Deepest any rapid went into the stock it met, mm (0: rapids run in air).
    arc_radius_mismatch : float
        From the parser, mm.
    stages : tuple of StageCheck
    machined : (ny, nx) float64
        The simulated stock after the program.
    """

    gouge: float
    below_part_moves: int
    final_over_part_max: float
    final_over_part_p95: float
    finished_over_part_max: float
    finished_area_fraction: float
    within_tolerance: bool
    rapid_in_material: float
    arc_radius_mismatch: float
    stages: tuple[StageCheck, ...]
    machined: F64 = field(repr=False)


def _as_segments(prog: ParsedProgram, a: int, b: int, sagitta: float
                 ) -> tuple[F64, F64, F64, NDArray[np.int64]]:
    """Straight pieces of moves ``a..b-1`` in program order: ``p0, p1, radius growth,
    owner move``; arcs become chords, moves from an unknown position are left out."""
    idx = np.arange(a, b)
    known = np.isfinite(prog.start[a:b]).all(axis=1) & np.isfinite(prog.end[a:b]).all(axis=1)
    arc = prog.motion[a:b] >= 2
    if known.all() and not arc.any():  # views, no copies
        return prog.start[a:b], prog.end[a:b], np.zeros(b - a), idx
    idx = idx[known]
    arcs = idx[prog.motion[idx] >= 2]
    if not len(arcs):
        return prog.start[idx], prog.end[idx], np.zeros(len(idx)), idx
    c0, c1, g, o = arc_chords(prog.start[arcs], prog.end[arcs], prog.center[arcs],
                              prog.motion[arcs] == 3, sagitta)
    lines = idx[prog.motion[idx] < 2]
    owner = np.concatenate([lines, arcs[o]])
    p0 = np.concatenate([prog.start[lines], c0])
    p1 = np.concatenate([prog.end[lines], c1])
    grow = np.concatenate([np.zeros(len(lines)), g])
    order = np.argsort(owner, kind="stable")  # program order; an arc's chords stay in order
    return p0[order], p1[order], grow[order], owner[order]


def tool_spans(prog: ParsedProgram) -> list[tuple[int, int]]:
    """The program's tool stretches: ``(a, b)`` for moves ``a..b-1`` between tool changes."""
    changes = ([0, *(np.flatnonzero(prog.tool[1:] != prog.tool[:-1]) + 1).tolist(),
                len(prog.tool)] if len(prog.tool) else [])
    return list(itertools.pairwise(changes))


def stock_grid(stock: F64 | float, part: ZMap) -> F64:
    """A fresh (writable) stock grid on the part's nodes from a flat top or a grid."""
    grid = np.broadcast_to(np.asarray(stock, np.float64), part.shape)
    if grid.shape != part.shape:
        raise InvalidInputError("stock", "must be a number or a grid of the part's shape")
    return np.ascontiguousarray(grid, dtype=np.float64).copy()


class _Grow:
    """A 1-d array appended to in pieces (doubling; a view of what is in it)."""

    def __init__(self, dtype: type) -> None:
        self._a: NDArray[Any] = np.empty(0, dtype)
        self._n = 0

    def extend(self, v: NDArray[Any]) -> None:
        n = self._n + len(v)
        if n > len(self._a):
            a = np.empty(max(2 * n, 1024), self._a.dtype)
            a[:self._n] = self._a[:self._n]
            self._a = a
        self._a[self._n:n] = v
        self._n = n

    @property
    def values(self) -> NDArray[Any]:
        return self._a[:self._n]


class StretchRun:
    """One tool stretch simulated on a stock grid in place, its moves coming in pieces
    (:meth:`add`, in program order); :meth:`check` measures it. Repeats are looked up among
    every earlier piece's moves and a piece's first move trails the last one swept before
    it, so any split gives the stock and the figures of the whole stretch at once.

    Parameters
    ----------
    stock : (ny, nx) float64
        C-contiguous, lowered in place.
    part : ZMap
    tool : Tool
    model : (ny, nx) float64 or None, or a callable giving it
        The stretch's stage model (called by :meth:`check`).
    """

    def __init__(self, stock: F64, part: ZMap, tool: Tool,
                 model: F64 | Callable[[], F64 | None] | None) -> None:
        self.stock, self.part, self.tool, self.model = stock, part, tool, model
        self.before = stock.copy()
        self.frame = GridFrame(part.x0, part.y0, part.dx, part.dy, part.shape)
        spacing = min(part.dx, part.dy)
        self.sagitta = ARC_SAGITTA_FRACTION * spacing
        # blocks of nodes a move provably leaves alone are skipped (the same stock, the
        # same figures wherever they are > 0: ``sweep_moves``)
        self.bounds = (BlockBounds(self.frame, stock, part.z, block_size(tool.radius, spacing))
                       if SKIP_BLOCKS and tool.radius >= sweep_mod.MIN_BLOCK_RADIUS * spacing
                       else None)
        self.repeats = RepeatTable()
        self.last: tuple[F64, F64, float, bool] | None = None  # the last move swept
        self.number = -1
        self.moves = 0
        self.over_part = _Grow(np.float64)  # per straight piece, for repeats' lookups
        self.rapid_pen = -np.inf
        self.below = _Grow(np.int64)
        self.lengths = _Grow(np.float64)
        self.feed = _Grow(np.bool_)
        self.met = _Grow(np.bool_)

    def add(self, prog: ParsedProgram, a: int, b: int) -> None:
        """Run moves ``a..b-1`` of ``prog`` (the stretch's next ones) on the stock."""
        if self.number < 0:
            self.number = int(prog.tool[a])
        p0, p1, grow, owner = _as_segments(prog, a, b, self.sagitta)
        rapid = prog.motion[owner] == 0
        radius = self.tool.radius + grow
        over_stock, over_part = np.zeros(len(p0)), np.full(len(p0), -np.inf)
        # a move that repeats one that already cut removes nothing and gouges as that one did
        first = len(self.over_part.values)
        src = (self.repeats.add(p0, p1, radius, ~rapid) if SKIP_REPEATS
               else np.full(len(p0), -1, np.int64))
        new = np.flatnonzero(src < 0)
        over_stock[new], over_part[new] = sweep_moves(
            self.frame, p0[new], p1[new], radius[new], self.tool.kind == "ball", self.stock,
            ref=self.part.z, apply=~rapid[new], bounds=self.bounds, trail=SKIP_TRAILING,
            before=self.last)
        if len(new):
            k = new[-1]
            self.last = (p0[k].copy(), p1[k].copy(), float(radius[k]), bool(~rapid[k]))
        self.over_part.extend(over_part)
        every = self.over_part.values  # a repeat's source was swept (here or before)
        rep = np.flatnonzero(src >= 0)
        every[first + rep] = every[src[rep]]
        over_part = every[first:]
        met = np.zeros(b - a, bool)
        met[owner[over_stock > CUT_EPS] - a] = True
        self.met.extend(met)
        self.below.extend(owner[over_part > CUT_EPS] - a + self.moves)
        d = prog.end[a:b] - prog.start[a:b]
        lengths = np.sqrt(np.einsum("ij,ij->i", d, d))
        lengths[~np.isfinite(lengths)] = 0.0
        self.lengths.extend(lengths)
        self.feed.extend(prog.motion[a:b] != 0)
        pen = over_stock[rapid]
        if len(pen):
            self.rapid_pen = max(self.rapid_pen, float(pen.max()))
        self.moves += b - a

    def check(self) -> StageCheck:
        """The stretch's figures, its moves so far run."""
        stock, part = self.stock, self.part
        model = self.model() if callable(self.model) else self.model
        over = None if model is None else stock - model
        feed, met, lengths = self.feed.values, self.met.values, self.lengths.values
        return StageCheck(
            tool_number=self.number, moves=self.moves,
            over_model_max=None if over is None else float(over.max()),
            over_model_p95=None if over is None else float(np.percentile(over, 95)),
            gouge=float(max(0.0, (part.z - stock).max())),
            # a retract from a cutting position touches the stock it just cut (a tie)
            rapid_in_material=self.rapid_pen if self.rapid_pen > TIE_EPS else 0.0,
            removed_volume=float((self.before - stock).sum() * part.cell_area),
            air_feed_length=float(lengths[feed & ~met].sum()),
            feed_length=float(lengths[feed].sum()),
            below_part_moves=len(np.unique(self.below.values)))


def simulate_stretch(stock: F64, part: ZMap, prog: ParsedProgram, a: int, b: int, tool: Tool,
                     model: F64 | None) -> StageCheck:
    """Run moves ``a..b-1`` of one tool on ``stock`` (in place) and measure them."""
    run = StretchRun(stock, part, tool, model)
    run.add(prog, a, b)
    return run.check()


class ProgramSimulation:
    """A parsed program simulated as it comes, piece by piece (:meth:`add`: what
    :class:`~zwcore.toolpath.parse.ProgramReader` returns for each piece of text);
    :meth:`check` gives what :func:`simulate_program` gives for the whole program.

    Parameters are those of :func:`simulate_program`; ``stage_models`` may be a callable
    ``s -> model`` of the ``s``-th tool stretch (called when the stretch is measured, so that
    it needs to exist only then).
    """

    def __init__(self, tools: Mapping[int, Tool], part: ZMap, stock: F64 | float, *,
                 tolerance: float,
                 stage_models: Sequence[F64 | None] | Callable[[int], F64 | None] | None = None,
                 reach: NDArray[np.bool_] | None = None) -> None:
        self.tools, self.part, self.tolerance, self.reach = tools, part, tolerance, reach
        self.models = stage_models
        self.machined = stock_grid(stock, part)
        self.stages: list[StageCheck] = []
        self.run: StretchRun | None = None
        self.mismatch = 0.0

    def _model(self, s: int) -> F64 | None:
        m = self.models
        if m is None:
            return None
        if callable(m):
            return m(s)
        return m[s] if s < len(m) else None

    def add(self, prog: ParsedProgram) -> None:
        """Run the next piece's moves; a tool change closes the stretch before it."""
        self.mismatch = max(self.mismatch, prog.arc_radius_mismatch)
        for a, b in tool_spans(prog):
            number = int(prog.tool[a])
            if self.run is not None and self.run.number != number:
                self.stages.append(self.run.check())
                self.run = None
            if self.run is None:
                if number not in self.tools:
                    raise InvalidInputError("tools", f"the program uses T{number}, not in the "
                                            "tool table")
                self.run = StretchRun(self.machined, self.part, self.tools[number],
                                      functools.partial(self._model, len(self.stages)))
            self.run.add(prog, a, b)

    def check(self) -> ProgramCheck:
        """The figures of the program run so far (the last stretch closed)."""
        if self.run is not None:
            self.stages.append(self.run.check())
            self.run = None
        machined, part, reach = self.machined, self.part, self.reach
        stages = self.stages
        left = machined - part.z
        region = left if reach is None else left[reach]
        fmax = float(region.max()) if region.size else 0.0
        return ProgramCheck(
            gouge=float(max(0.0, -left.min())),
            below_part_moves=sum(x.below_part_moves for x in stages),
            final_over_part_max=float(left.max()),
            final_over_part_p95=float(np.percentile(left, 95)),
            finished_over_part_max=fmax, finished_area_fraction=region.size / left.size,
            within_tolerance=fmax <= self.tolerance,
            rapid_in_material=max((x.rapid_in_material for x in stages), default=0.0),
            arc_radius_mismatch=self.mismatch, stages=tuple(stages), machined=machined)


def simulate_program(prog: ParsedProgram, tools: Mapping[int, Tool], part: ZMap,
                     stock: F64 | float, *, tolerance: float,
                     stage_models: Sequence[F64 | None] | None = None,
                     reach: NDArray[np.bool_] | None = None) -> ProgramCheck:
    """Simulate a parsed program and measure it against the part and the stage models.

    Parameters
    ----------
    prog : ParsedProgram
    tools : mapping of int to Tool
        Tool by tool number (every number the program activates).
    part : ZMap
        The part, ``(ny, nx)``; the simulation runs on its nodes.
    stock : float or (ny, nx) float64
        Stock before the program (flat top or a grid).
    tolerance : float
        Finishing tolerance for ``within_tolerance``.
    stage_models : sequence of (ny, nx) float64 or None, optional
        Per tool change, in order: the stage model at the part's nodes.
    reach : (ny, nx) bool, optional
        Where the finishing tolerance applies (where the plan says it finishes); all the
        nodes when not given.

    Returns
    -------
    ProgramCheck
    """
    sim = ProgramSimulation(tools, part, stock, tolerance=tolerance, stage_models=stage_models,
                            reach=reach)
    sim.add(prog)
    return sim.check()
