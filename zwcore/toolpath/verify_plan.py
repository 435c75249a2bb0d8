"""A scan-line plan's emitted NC program, read back and simulated on its part, tool stretch by
tool stretch (issue 11 part 5: the independent check of a plan with tool paths).

The program is read with :func:`~zwcore.toolpath.parse.parse_program` (what a control
executes, independent of the path generator) and every move is swept with the active ball
on the stock at the part's input nodes (:func:`~zwcore.toolpath.simulate.simulate_stretch`),
one tool stretch (the moves between two tool changes) at a time, so that each stretch's
result can be measured against the plan: the stretch's own stage model, the next stretch's
first model (what the next tool meets) and the part.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from zwcore.errors import InvalidInputError
from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.scanline.results import ScanlinePlan, stage_at_nodes
from zwcore.toolpath.parse import parse_program
from zwcore.toolpath.simulate import simulate_stretch, stock_grid, tool_spans

__all__ = ["ProgramReplay", "StretchReplay", "replay_program"]

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class StretchReplay:
    """Figures of one tool stretch of the program.

    Attributes
    ----------
    tool_number : int
    tool : Tool
    stages : tuple of int
        The plan's passes (indices in ``plan.stages``) this stretch machines.
    moves : int
    feed_length, air_feed_length : float
        Feed moves, and those that met no material, mm.
    rapid_in_material : float
        Deepest a rapid went into the stock it met, mm (0: rapids run in air).
    below_part_moves : int
        Moves whose sweep reaches below the part at some node.
    gouge : float
        ``max(part - stock after the stretch)``, clipped at 0, mm.
    removed_volume : float
        mm³.
    over_model_max, over_model_p95 : float
        Stock after the stretch minus its last pass's model, mm.
    left_over_next_max, left_over_next_p95 : float
        Stock after the stretch minus the next stretch's first model (the part after the
        last stretch), mm.
    left_over_part_max, left_over_part_p95 : float
        Stock after the stretch minus the part, mm.
    """

    tool_number: int
    tool: Tool
    stages: tuple[int, ...]
    moves: int
    feed_length: float
    air_feed_length: float
    rapid_in_material: float
    below_part_moves: int
    gouge: float
    removed_volume: float
    over_model_max: float
    over_model_p95: float
    left_over_next_max: float
    left_over_next_p95: float
    left_over_part_max: float
    left_over_part_p95: float


@dataclass(frozen=True, eq=False)
class ProgramReplay:
    """The program simulated on the part.

    Attributes
    ----------
    machined : (ny, nx) float64
        The simulated stock after the program.
    stretches : tuple of StretchReplay
    moves : int
    arc_radius_mismatch : float
        From the reader, mm.
    ended : bool
        The program ends with ``M30`` (or ``M2``).
    """

    machined: F64
    stretches: tuple[StretchReplay, ...]
    moves: int
    arc_radius_mismatch: float
    ended: bool


def _plan_stretches(plan: ScanlinePlan, numbers: Mapping[int, Tool]) -> list[tuple[int, list[int]]]:
    """The plan's passes grouped by tool change: ``(tool number, pass indices)``."""
    by_id = {tool.id: n for n, tool in numbers.items()}
    out: list[tuple[int, list[int]]] = []
    for i, s in enumerate(plan.stages):
        if s.tool.id not in by_id:
            raise InvalidInputError("tools", f"no tool number for {s.tool.id}")
        n = by_id[s.tool.id]
        if out and out[-1][0] == n:
            out[-1][1].append(i)
        else:
            out.append((n, [i]))
    return out


def _pair(d: F64) -> tuple[float, float]:
    return float(d.max()), float(np.percentile(d, 95.0))


def replay_program(part: ZMap, plan: ScanlinePlan, program: str, numbers: Mapping[int, Tool],
                   stock: F64 | float | None = None) -> ProgramReplay:
    """Read a scan-line plan's program back and simulate it on the part, stretch by stretch.

    Parameters
    ----------
    part : ZMap
        The plan's input, ``(ny, nx)``.
    plan : ScanlinePlan
        The plan the program was written for (its stage models).
    program : str
        The NC program.
    numbers : mapping of int to Tool
        The tool table: tool by ``T`` number.
    stock : float or (ny, nx) float64, optional
        Stock before the program; default the plan's flat stock top.

    Returns
    -------
    ProgramReplay

    Raises
    ------
    InvalidInputError
        ``program``: unreadable, or its tool changes do not follow the plan's.
    """
    prog = parse_program(program)
    groups = _plan_stretches(plan, numbers)
    spans = tool_spans(prog)
    used = [int(prog.tool[a]) for a, _ in spans]
    if used != [n for n, _ in groups]:
        raise InvalidInputError("program", f"its tool changes {used} do not follow the "
                                f"plan's {[n for n, _ in groups]}")
    # one stock grid, each stretch simulated on it in place (its figures against its model
    # come with it; the stock after it is measured against the next model and the part)
    current = stock_grid(plan.stock_top if stock is None else stock, part)
    stretches = []
    for k, ((a, b), (number, idx)) in enumerate(zip(spans, groups, strict=True)):
        model = stage_at_nodes(plan.stages[idx[-1]], part)
        st = simulate_stretch(current, part, prog, a, b, numbers[number], model)
        assert st.over_model_max is not None and st.over_model_p95 is not None
        over_model = (st.over_model_max, st.over_model_p95)
        nxt = (part.z if k + 1 == len(groups)
               else stage_at_nodes(plan.stages[groups[k + 1][1][0]], part))
        on_next, on_part = _pair(current - nxt), _pair(current - part.z)
        stretches.append(StretchReplay(
            tool_number=number, tool=numbers[number], stages=tuple(idx), moves=b - a,
            feed_length=st.feed_length, air_feed_length=st.air_feed_length,
            rapid_in_material=st.rapid_in_material, below_part_moves=st.below_part_moves,
            gouge=st.gouge, removed_volume=st.removed_volume, over_model_max=over_model[0],
            over_model_p95=over_model[1], left_over_next_max=on_next[0],
            left_over_next_p95=on_next[1], left_over_part_max=on_part[0],
            left_over_part_p95=on_part[1]))
    return ProgramReplay(current, tuple(stretches), len(prog.motion),
                         prog.arc_radius_mismatch, prog.ended)
