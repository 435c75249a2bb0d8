"""What the plan lays around a chain's main ball: the facts the time ranking must price
(issue 11, session 10; docs/scanline.md).

The ranking (:mod:`zwcore.scanline._chain_time`) prices finishing only; on the 45° fillet
it picks Ø20 > Ø5 (22.3 min of program) over Ø12 > Ø3 (6.2 min) because the plan lays
the largest ball's stage over the whole stock at the finishing level, and a smaller main
ball's roughing at coarse levels (a level takes only a ball larger than the stage after
it). These tests pin that side of the plan: with the largest ball as main ball there is
no roughing stage, the stock top is the part's top plus its flute length and its stage
goes down in ``ceil(stock / flute)`` passes, all on the finishing level; with a smaller
main ball the roughing stages run larger balls on coarser levels only.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.test_reach import _fillet
from tests.test_time7_chain_time import _dome
from zwcore.grid.tools import Tool, default_tools
from zwcore.grid.zmap import ZMap
from zwcore.scanline import _chain_time, _regions
from zwcore.scanline.planner import plan_scanline
from zwcore.scanline.results import ScanlinePlan

BALLS = list(default_tools("ball"))


def _plan_with_main(zmap: ZMap, main: str, tolerance: float,
                    monkeypatch: pytest.MonkeyPatch) -> ScanlinePlan:
    """The plan whose finishing chain is ``main`` alone (the ranking replaced)."""
    def fixed(balls: list[Tool], reach: _regions._Reach, bound: bool = True
              ) -> tuple[list[int], list[_chain_time.BallTime]]:
        j = [b.id for b in balls].index(main)
        return [j], [reach.main_time(balls, j)]

    with monkeypatch.context() as m:
        m.setattr(_regions, "_plan", fixed)
        return plan_scanline(zmap, tolerance=tolerance)


@pytest.mark.parametrize(("name", "tolerance"), [("45° fillet", 0.01), ("dome", 0.005)])
def test_largest_main_ball_meets_the_whole_stock_at_the_finishing_level(
        name: str, tolerance: float, monkeypatch: pytest.MonkeyPatch) -> None:
    zmap = _fillet(45.0)[0] if name == "45° fillet" else _dome()
    largest = BALLS[0]
    plan = _plan_with_main(zmap, largest.id, tolerance, monkeypatch)
    assert all(s.level == plan.depth for s in plan.stages)  # no roughing before it
    top = float(zmap.z.max())
    assert plan.stock_top == pytest.approx(top + largest.flute_length, abs=1e-9)
    mains = [s for s in plan.stages if s.tool.id == largest.id]
    # the flute rule over the whole stock: ceil((stock - lowest part) / flute) passes,
    # each over the whole part (measured on the fillet: 2 passes, 13.6 min of program)
    want = math.ceil((plan.stock_top - float(zmap.z.min())) / largest.flute_length - 1e-9)
    assert len(mains) == mains[0].pass_count == want == 2
    assert all(s.region is None for s in mains)


def test_smaller_main_ball_is_roughed_by_larger_balls_on_coarser_levels(
        monkeypatch: pytest.MonkeyPatch) -> None:
    # The fillet with Ø12 as main ball: Ø20 roughs on a coarse level (measured: level 6 of
    # 9, spacing 1.6 mm, 2 passes, 3.0 min of program) and Ø12 takes one pass on the
    # finishing level.
    zmap = _fillet(45.0)[0]
    plan = _plan_with_main(zmap, "BEM-D12", 0.01, monkeypatch)
    rough = [s for s in plan.stages if s.level != plan.depth]
    assert rough and all(s.level < plan.depth for s in rough)
    assert all(s.tool.radius > 6.0 for s in rough)
    assert np.all(np.diff([s.level for s in rough]) >= 0)  # coarse to fine
    main = [s for s in plan.stages if s.tool.id == "BEM-D12"]
    assert len(main) == 1 and main[0].level == plan.depth and main[0].region is None
