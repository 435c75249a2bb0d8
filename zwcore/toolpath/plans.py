"""Tool paths and the NC program of a whole plan, verified by simulating the program.

:func:`scanline_toolpaths` and :func:`contour_toolpaths` build every stage's path, write
the program (:mod:`zwcore.toolpath.writer`), read it back with the independent parser
(:mod:`zwcore.toolpath.parse`) and simulate it on the stock at the part's resolution
(:mod:`zwcore.toolpath.simulate`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from zwcore.contour.results import ContourPlan
from zwcore.errors import InvalidInputError, LimitExceededError
from zwcore.grid.feeds import DEFAULT_RAPID_FEED
from zwcore.grid.sampling import cells_at_fine_nodes
from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap, finite_number
from zwcore.scanline.results import ScanlinePlan, ScanlineStage, stage_at_nodes
from zwcore.toolpath._polyline import PartBounds
from zwcore.toolpath.contour_paths import contour_stage_path
from zwcore.toolpath.parse import parse_program
from zwcore.toolpath.program import CuttingData, ProgramSettings, StagePath
from zwcore.toolpath.scanline_paths import CLHeights, scanline_stage_path, sim_cl_heights
from zwcore.toolpath.simulate import ProgramCheck, simulate_program
from zwcore.toolpath.writer import iter_program

__all__ = ["Toolpaths", "contour_toolpaths", "scanline_toolpaths", "tool_numbers"]

F64 = NDArray[np.float64]

#: Default height of the clearance plane above the stock top, mm.
CLEARANCE_ABOVE_STOCK = 5.0
#: Scan-line chordal tolerance as a fraction of the plan's tolerance.
CHORD_FRACTION = 0.25
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


def _finish(part: ZMap, stages: list[StagePath], settings: ProgramSettings, stock_top: float,
            tolerance: float, models: list[F64 | None], verify: bool, max_bytes: int | None,
            reach: NDArray[np.bool_] | None, timings: list[tuple[str, float]],
            cpu: list[tuple[str, float]] | None = None) -> Toolpaths:
    cpu = [] if cpu is None else cpu
    t, c = time.perf_counter(), time.process_time()
    chunks, size = [], 0
    for chunk in iter_program(stages, settings):
        size += len(chunk)
        if max_bytes is not None and size > max_bytes:
            raise LimitExceededError("program", f"the NC program exceeds {max_bytes} bytes")
        chunks.append(chunk)
    text = "".join(chunks)
    timings.append(("program", time.perf_counter() - t))
    cpu.append(("program", time.process_time() - c))
    check = None
    if verify:
        t, c = time.perf_counter(), time.process_time()
        prog = parse_program(text)
        timings.append(("parse", time.perf_counter() - t))
        cpu.append(("parse", time.process_time() - c))
        t, c = time.perf_counter(), time.process_time()
        table = {p.cutting.tool_number: p.tool for p in stages}
        check = simulate_program(prog, table, part, stock_top, tolerance=tolerance,
                                 stage_models=models, reach=reach)
        timings.append(("simulate", time.perf_counter() - t))
        cpu.append(("simulate", time.process_time() - c))
    return Toolpaths(tuple(stages), settings, text, check, tuple(timings), tuple(cpu))


def scanline_toolpaths(part: ZMap, plan: ScanlinePlan, cl_heights: CLHeights = sim_cl_heights,
                       *,
                       cutting: Mapping[str, CuttingData] | None = None,
                       clearance: float | None = None, rapid_feed: float = DEFAULT_RAPID_FEED,
                       verify: bool = True, max_bytes: int | None = None,
                       reach: NDArray[np.bool_] | None = None,
                       regions: Sequence[NDArray[np.bool_] | None] | None = None) -> Toolpaths:
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
        Where the finishing tolerance applies.
    regions : sequence of (my, mx) bool or None, optional
        Per stage, where it cuts on its model's nodes; ``None`` entry: everywhere.
        Default: each stage's own ``region`` (the plan's rest regions, issue 11).
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
    t, c = time.perf_counter(), time.process_time()
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
            stock_before=before, part_bounds=bounds,
            # only the plan's last pass is re-cut from its own simulation: an earlier
            # ball's scallops are in the plan's simulated stock, so the rest regions of
            # the balls after it already cover them (and a large ball's closing at the
            # input resolution costs minutes: Ø20 at 1025², 114 s)
            scallop_tolerance=(plan.tolerance if i == len(plan.stages) - 1
                               and st.level == plan.depth else None))
        # the bound is a grid per stage: pass it on, keep none (Rushmore: 42 of 2.9 MB)
        before = path.stock_after
        stages.append(replace(path, stock_after=None))
    timings = [("paths", time.perf_counter() - t)]
    cpu = [("paths", time.process_time() - c)]

    def model(i: int) -> F64:
        return stage_at_nodes(plan.stages[i], part)

    return _finish(part, stages, settings, plan.stock_top, plan.tolerance,
                   _merge_models(stages, model) if verify else [], verify, max_bytes, reach,
                   timings, cpu)


def _merge_models(stages: list[StagePath], model: Callable[[int], F64]) -> list[F64 | None]:
    """The model after each tool stretch (consecutive stages with the same tool number form
    one stretch in the parsed program: its last model), ``model(i)`` the model of stage
    ``i`` at the part's nodes (built for the stretches' last stages only)."""
    out: list[F64 | None] = []
    for i, p in enumerate(stages):
        if i + 1 < len(stages) and stages[i + 1].cutting.tool_number == p.cutting.tool_number:
            continue
        out.append(model(i))
    return out


def contour_toolpaths(part: ZMap, plan: ContourPlan, *,
                      cutting: Mapping[str, CuttingData] | None = None,
                      clearance: float | None = None, tolerance: float = 0.05,
                      stepover_fraction: float = 0.4, rapid_feed: float = DEFAULT_RAPID_FEED,
                      verify: bool = True, max_bytes: int | None = None) -> Toolpaths:
    """Contour paths of every stage of a plan, the program and its simulation.

    Parameters
    ----------
    tolerance : float
        Arc fit tolerance, mm (the check's finishing tolerance too).
    stepover_fraction : float
        Clearing ring distance as a fraction of the tool diameter, in (0, 0.5] so that
        rings are less than a radius apart.
    """
    if not (math.isfinite(stepover_fraction) and 0.0 < stepover_fraction <= 0.5):
        raise InvalidInputError("stepover", f"must lie in (0, 0.5] of the diameter, got "
                                f"{stepover_fraction!r}")
    clear = _clearance(clearance, plan.stock_top)
    tools = list(dict.fromkeys(s.tool for s in plan.stages))
    data = tool_numbers(tools, cutting)
    settings = ProgramSettings(clearance=clear, rapid_feed=rapid_feed)
    t = time.perf_counter()
    stages = [contour_stage_path(part, st, i, data[st.tool.id], clearance=clear,
                                 tolerance=tolerance,
                                 stepover=stepover_fraction * st.tool.diameter)
              for i, st in enumerate(plan.stages)]
    timings = [("paths", time.perf_counter() - t)]

    def model(i: int) -> F64:
        st = plan.stages[i]
        return cells_at_fine_nodes(st.model, st.scale, part.shape)

    return _finish(part, stages, settings, plan.stock_top, tolerance,
                   _merge_models(stages, model) if verify else [], verify, max_bytes, None, timings)
