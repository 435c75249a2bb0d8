"""Tool paths and the NC program of a whole plan, verified by simulating the program.

:func:`scanline_toolpaths` and :func:`contour_toolpaths` build every stage's path, write
the program (:mod:`zwcore.toolpath.writer`), read it back with the independent parser
(:mod:`zwcore.toolpath.parse`) and simulate it on the stock at the part's resolution
(:mod:`zwcore.toolpath.simulate`).
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from zwcore.contour.results import ContourPlan
from zwcore.errors import InvalidInputError, LimitExceededError
from zwcore.grid.feeds import DEFAULT_RAPID_FEED
from zwcore.grid.sampling import cells_at_fine_nodes
from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap, finite_number
from zwcore.scanline.results import (
    CHORD_SHARE,
    ScanlinePlan,
    ScanlineStage,
    stage_at_nodes,
)
from zwcore.toolpath._polyline import PartBounds
from zwcore.toolpath.contour_paths import contour_stage_path
from zwcore.toolpath.parse import ProgramReader
from zwcore.toolpath.program import CuttingData, ProgramSettings, StagePath
from zwcore.toolpath.scanline_paths import CLHeights, scanline_stage_path, sim_cl_heights
from zwcore.toolpath.simulate import ProgramCheck, ProgramSimulation
from zwcore.toolpath.writer import PROGRAM_HEAD, PROGRAM_TAIL, iter_stage

__all__ = ["Toolpaths", "contour_toolpaths", "scanline_toolpaths", "tool_numbers"]

F64 = NDArray[np.float64]

#: Default height of the clearance plane above the stock top, mm.
CLEARANCE_ABOVE_STOCK = 5.0
#: Scan-line chordal tolerance as a fraction of the plan's tolerance (the plan's scallops
#: hold the tolerance less this and an allowance: :data:`zwcore.scanline.results.CHORD_SHARE`).
CHORD_FRACTION = CHORD_SHARE
#: Gouge a roughing pass's segment may have before it is split, fraction of the ball radius.
ROUGHING_REFINE = 0.05


@dataclass(frozen=True, eq=False)
class Toolpaths:
    """A plan's tool paths, program and verification.

    Attributes
    ----------
    stages : tuple of StagePath
    settings : ProgramSettings
    program : str
        The NC program.
    check : ProgramCheck or None
        The program parsed back and simulated (``None`` when not verified).
    timings : tuple of (str, float)
        Seconds per phase (paths, program, parse, simulate).
    cpu_timings : tuple of (str, float)
        CPU seconds per phase, all threads of the process (on a shared machine the wall
        times swing with the load; these less so).
    """

    stages: tuple[StagePath, ...]
    settings: ProgramSettings
    program: str = field(repr=False)
    check: ProgramCheck | None
    timings: tuple[tuple[str, float], ...]
    cpu_timings: tuple[tuple[str, float], ...] = ()

    def stage_figures(self) -> list[dict[str, float]]:
        """Per stage: path lengths by kind, the time estimate (min) and the path's figures."""
        out = []
        for p in self.stages:
            ln = p.lengths()
            out.append({**{f"{k}_length": v for k, v in ln.items()},
                        "time_min": p.time_min(self.settings.rapid_feed), **p.figures})
        return out

    @property
    def time_min(self) -> float:
        return sum(p.time_min(self.settings.rapid_feed) for p in self.stages)

    @property
    def length(self) -> float:
        return sum(sum(p.lengths().values()) for p in self.stages)


def tool_numbers(tools: list[Tool], cutting: Mapping[str, CuttingData] | None
                 ) -> dict[str, CuttingData]:
    """Cutting data per tool id: as given, else defaults with ``tool_number`` the tool's
    1-based position in the sequence; numbers must be unique."""
    out: dict[str, CuttingData] = {}
    seen: dict[int, str] = {}
    for n, t in enumerate(tools, 1):
        cd = (cutting or {}).get(t.id) or CuttingData(tool_number=n)
        if cd.tool_number in seen and seen[cd.tool_number] != t.id:
            raise InvalidInputError("tools", f"tool_number {cd.tool_number} is given to both "
                                    f"{seen[cd.tool_number]} and {t.id}")
        seen[cd.tool_number] = t.id
        out[t.id] = cd
    return out


def _refine_tolerance(plan: ScanlinePlan, stage: ScanlineStage) -> float | None:
    """Finishing passes (the input's level) follow the part to the chordal tolerance; a
    roughing pass's lift may leave up to a twentieth of its ball radius (the next stage's
    stock), which keeps its refinement to a few splits."""
    if stage.level == plan.depth:
        return None
    return max(CHORD_FRACTION * plan.tolerance, ROUGHING_REFINE * stage.tool.radius)


def _clearance(clearance: float | None, stock_top: float) -> float:
    if clearance is None:
        return stock_top + CLEARANCE_ABOVE_STOCK
    c = finite_number(clearance, "clearance")
    if c <= stock_top:
        raise InvalidInputError("clearance", f"must be above the stock top ({stock_top:g} mm), "
                                f"got {c:g}")
    return c


def _cores() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (
        os.cpu_count() or 1)


class _ProgramRun:
    """The program written stage by stage as the paths come and, with ``verify``, each
    stage's text read back (:class:`~zwcore.toolpath.parse.ProgramReader`, modal state
    carried from stage to stage) and simulated on the running stock
    (:class:`~zwcore.toolpath.simulate.ProgramSimulation`).

    With ``overlap`` this runs on one worker thread, stage after stage in order, while the
    caller lays the next stage's paths (the kernels release the GIL): the text, the reading
    and the figures are those of the whole program written, read and simulated at once
    (the reader and the simulation carry everything across stages; tests compare).
    ``max_bytes`` is checked as each piece of text is written; a failure on the worker
    surfaces at the caller's next :meth:`submit` or at :meth:`close`.
    """

    def __init__(self, part: ZMap, settings: ProgramSettings, table: Mapping[int, Tool],
                 stock_top: float, tolerance: float, models: Callable[[int], F64 | None],
                 reach: NDArray[np.bool_] | None, verify: bool, max_bytes: int | None,
                 overlap: bool) -> None:
        self.settings, self.max_bytes = settings, max_bytes
        self.chunks: list[str] = []
        self.size = 0
        self.reader = ProgramReader() if verify else None
        self.sim = (ProgramSimulation(table, part, stock_top, tolerance=tolerance,
                                      stage_models=models, reach=reach) if verify else None)
        self.wall = dict.fromkeys(("program", "parse", "simulate"), 0.0)
        self.cpu = dict.fromkeys(("program", "parse", "simulate"), 0.0)
        self.pool = ThreadPoolExecutor(1, thread_name_prefix="verify") if overlap else None
        self.pending: list[Future[None]] = []
        #: the tool number of the stage submitted last (its successor's tool change)
        self.previous: int | None = None
        self._run([PROGRAM_HEAD])

    def submit(self, path: StagePath) -> None:
        """Write (and verify) the next stage."""
        self._raise_failed()
        previous, self.previous = self.previous, path.cutting.tool_number
        if self.pool is None:
            self._stage(path, previous)
        else:
            self.pending.append(self.pool.submit(self._stage, path, previous))

    def close(self) -> tuple[str, ProgramCheck | None]:
        """Wait for the stages, write the end; the text and the check."""
        try:
            for f in self.pending:
                f.result()
        finally:
            self.abort()
        self._run([PROGRAM_TAIL], final=True)
        check = None
        if self.reader is not None and self.sim is not None:
            if self.reader.rows == 0:
                raise InvalidInputError("program", "no motion blocks")
            t, c = time.perf_counter(), time.process_time()
            check = self.sim.check()
            self._took("simulate", t, c)
        return "".join(self.chunks), check

    def abort(self) -> None:
        """Stop the worker (stages not started are dropped)."""
        if self.pool is not None:
            self.pool.shutdown(wait=True, cancel_futures=True)
            self.pool = None

    def _raise_failed(self) -> None:
        done = [f for f in self.pending if f.done()]
        for f in done:
            f.result()  # raises the worker's error here, as early as it is known
        self.pending = [f for f in self.pending if not f.done()]

    def _took(self, phase: str, t: float, c: float) -> None:
        # CPU of the process: exact per phase when sequential; overlapped it also counts
        # the paths laid meanwhile (the caller reports the total instead)
        self.wall[phase] += time.perf_counter() - t
        self.cpu[phase] += time.process_time() - c

    def _stage(self, path: StagePath, previous: int | None) -> None:
        self._run(iter_stage(path, self.settings, previous))

    def _run(self, pieces: Iterable[str], final: bool = False) -> None:
        t, c = time.perf_counter(), time.process_time()
        text = []
        for chunk in pieces:
            self.size += len(chunk)
            if self.max_bytes is not None and self.size > self.max_bytes:
                raise LimitExceededError("program", f"the NC program exceeds {self.max_bytes} "
                                         "bytes")
            text.append(chunk)
        self.chunks.extend(text)
        self._took("program", t, c)
        if self.reader is None or self.sim is None:
            return
        t, c = time.perf_counter(), time.process_time()
        prog = self.reader.read("".join(text), final=final)
        self._took("parse", t, c)
        t, c = time.perf_counter(), time.process_time()
        if len(prog.motion):
            self.sim.add(prog)
        self._took("simulate", t, c)


def _finish(run: _ProgramRun, stages: list[StagePath], settings: ProgramSettings,
            started: tuple[float, float], overlap: bool) -> Toolpaths:
    """Close the run (the paths are laid); the timings: sequential, per phase (wall and
    CPU); overlapped, the paths' wall, the worker's wall per phase (during the paths), the
    wall left after the paths (``verify_after_paths``) and the CPU of the whole
    (``total``)."""
    t = time.perf_counter()
    paths, paths_cpu = t - started[0], time.process_time() - started[1]
    if not overlap:  # the stages' programs were written and verified in between
        paths -= sum(run.wall.values())
        paths_cpu -= sum(run.cpu.values())
    timings, cpu = [("paths", paths)], [("paths", paths_cpu)]
    text, check = run.close()
    phases = ("program", "parse", "simulate") if check is not None else ("program",)
    timings += [(k, run.wall[k]) for k in phases]
    if overlap:
        timings.append(("verify_after_paths", time.perf_counter() - t))
        cpu = [("total", time.process_time() - started[1])]
    else:
        cpu += [(k, run.cpu[k]) for k in phases]
    return Toolpaths(tuple(stages), settings, text, check, tuple(timings), tuple(cpu))


def scanline_toolpaths(part: ZMap, plan: ScanlinePlan, cl_heights: CLHeights = sim_cl_heights,
                       *,
                       cutting: Mapping[str, CuttingData] | None = None,
                       clearance: float | None = None, rapid_feed: float = DEFAULT_RAPID_FEED,
                       verify: bool = True, max_bytes: int | None = None,
                       reach: NDArray[np.bool_] | None = None,
                       regions: Sequence[NDArray[np.bool_] | None] | None = None,
                       overlap: bool | None = None) -> Toolpaths:
    """Scan-line paths of every stage of a plan, the program and its simulation.

    Parameters
    ----------
    part : ZMap
        The plan's input.
    plan : ScanlinePlan
    cl_heights : CLHeights
        Drop-cutter on a stage model; default :func:`zwcore.sim.drop_cutter` (bilinear).
    cutting : mapping of tool id to CuttingData, optional
    clearance : float, optional
        Default: stock top + 5 mm; must be above the stock top.
    rapid_feed : float
    verify : bool
        Parse and simulate the program.
    max_bytes : int, optional
        Largest program (:class:`~zwcore.errors.LimitExceededError` beyond it).
    reach : (ny, nx) bool, optional
        Where the verification holds the program to the finishing tolerance
        (``within_tolerance``). Default: ``plan.finished``, where the plan's own simulated
        stock is within it.
    regions : sequence of (my, mx) bool or None, optional
        Per stage, where it cuts on its model's nodes; ``None`` entry: everywhere.
        Default: each stage's own ``region`` (the plan's rest regions, issue 11).
    overlap : bool, optional
        Write, read back and simulate each stage's program on a worker thread while the
        next stage's paths are laid (the same text and figures); default: when the process
        may use two cores or more.
    """
    clear = _clearance(clearance, plan.stock_top)
    tools = list(dict.fromkeys(s.tool for s in plan.stages))
    data = tool_numbers(tools, cutting)
    settings = ProgramSettings(clearance=clear, rapid_feed=rapid_feed)
    if regions is None:
        regions = [getattr(st, "region", None) for st in plan.stages]
    if len(regions) != len(plan.stages):
        raise InvalidInputError("regions", f"one per stage ({len(plan.stages)}), got "
                                f"{len(regions)}")
    overlap = _cores() >= 2 if overlap is None else overlap
    if reach is None:
        reach = plan.finished
    t, c = time.perf_counter(), time.process_time()
    numbers = [data[st.tool.id].tool_number for st in plan.stages]

    def model(i: int) -> F64:
        return stage_at_nodes(plan.stages[i], part)

    run = _ProgramRun(part, settings, {data[tl.id].tool_number: tl for tl in tools},
                      plan.stock_top, plan.tolerance, _stretch_models(numbers, model), reach,
                      verify, max_bytes, overlap)
    try:
        stages = _scanline_stages(part, plan, cl_heights, data, clear, rapid_feed, regions, run)
    except BaseException:
        run.abort()
        raise
    return _finish(run, stages, settings, (t, c), overlap)


def _scanline_stages(part: ZMap, plan: ScanlinePlan, cl_heights: CLHeights,
                     data: Mapping[str, CuttingData], clear: float, rapid_feed: float,
                     regions: Sequence[NDArray[np.bool_] | None], run: _ProgramRun
                     ) -> list[StagePath]:
    """Every stage's path in order, each handed to ``run`` as soon as it is laid."""
    stages: list[StagePath] = []
    before: F64 | None = None
    bounds = PartBounds(part)  # the part's block bounds, built once for every stage
    for i, st in enumerate(plan.stages):
        path = scanline_stage_path(
            part, st, i, data[st.tool.id], cl_heights, clearance=clear,
            chord_tolerance=CHORD_FRACTION * plan.tolerance, stock_top=plan.stock_top,
            refine_tolerance=_refine_tolerance(plan, st), region=regions[i],
            rapid_feed=rapid_feed,
            # the stock only falls: the bound after the stages before holds (rest stages
            # with no whole lines of their own come down to it, not to the stock top)
            stock_before=before, part_bounds=bounds, cell_bound=plan.cell_bound,
            # only the plan's last pass is re-cut from its own simulation: an earlier
            # ball's scallops are in the plan's simulated stock, so the rest regions of
            # the balls after it already cover them (and a large ball's closing at the
            # input resolution costs minutes: Ø20 at 1025², 114 s)
            scallop_tolerance=(plan.tolerance if i == len(plan.stages) - 1
                               and st.level == plan.depth else None))
        # the bound is a grid per stage: pass it on, keep none (Rushmore: 42 of 2.9 MB)
        before = path.stock_after
        stages.append(replace(path, stock_after=None))
        run.submit(stages[-1])
    return stages


def _stretch_models(numbers: Sequence[int], model: Callable[[int], F64]
                    ) -> Callable[[int], F64 | None]:
    """The model after each tool stretch (consecutive stages with the same tool number form
    one stretch in the parsed program: its last model) as ``s -> model``; ``model(i)`` the
    model of stage ``i`` at the part's nodes (built when the stretch is measured)."""
    last = [i for i in range(len(numbers))
            if i + 1 == len(numbers) or numbers[i + 1] != numbers[i]]

    def of(s: int) -> F64 | None:
        return model(last[s]) if s < len(last) else None

    return of


def contour_toolpaths(part: ZMap, plan: ContourPlan, *,
                      cutting: Mapping[str, CuttingData] | None = None,
                      clearance: float | None = None, tolerance: float = 0.05,
                      stepover_fraction: float = 0.4, rapid_feed: float = DEFAULT_RAPID_FEED,
                      verify: bool = True, max_bytes: int | None = None,
                      overlap: bool | None = None) -> Toolpaths:
    """Contour paths of every stage of a plan, the program and its simulation.

    Parameters
    ----------
    tolerance : float
        Arc fit tolerance, mm (the check's finishing tolerance too).
    stepover_fraction : float
        Clearing ring distance as a fraction of the tool diameter, in (0, 0.5] so that
        rings are less than a radius apart.
    overlap : bool, optional
        As :func:`scanline_toolpaths`.
    """
    if not (math.isfinite(stepover_fraction) and 0.0 < stepover_fraction <= 0.5):
        raise InvalidInputError("stepover", f"must lie in (0, 0.5] of the diameter, got "
                                f"{stepover_fraction!r}")
    clear = _clearance(clearance, plan.stock_top)
    tools = list(dict.fromkeys(s.tool for s in plan.stages))
    data = tool_numbers(tools, cutting)
    settings = ProgramSettings(clearance=clear, rapid_feed=rapid_feed)
    overlap = _cores() >= 2 if overlap is None else overlap
    t, c = time.perf_counter(), time.process_time()

    def model(i: int) -> F64:
        st = plan.stages[i]
        return cells_at_fine_nodes(st.model, st.scale, part.shape)

    run = _ProgramRun(part, settings, {data[tl.id].tool_number: tl for tl in tools},
                      plan.stock_top, tolerance,
                      _stretch_models([data[st.tool.id].tool_number for st in plan.stages],
                                      model), None, verify, max_bytes, overlap)
    stages: list[StagePath] = []
    try:
        for i, st in enumerate(plan.stages):
            stages.append(contour_stage_path(part, st, i, data[st.tool.id], clearance=clear,
                                             tolerance=tolerance,
                                             stepover=stepover_fraction * st.tool.diameter))
            run.submit(stages[-1])
    except BaseException:
        run.abort()
        raise
    return _finish(run, stages, settings, (t, c), overlap)
