"""The plan's "finished" holds on the machine beside steep walls (session 9).

On the scan-line bench part (bench/bench_scanline_core.py: bumps, a pocket with a steep
rim, a 10 mm wall) at 513², the large balls' finishing passes are too large to drop on the
whole part, and their positions were dropped on the part's nodes only: beside a wall at a
ball's rim the bilinear surface between nodes stands higher than any node, so the plan's
ball sank up to 1.9 mm below the CL the tool paths take, and the plan said "finished" at
946 nodes where its own program left up to 4.68 mm. The program is simulated here by the
verification (parsed back, swept at the input resolution), independent of the plan's
simulation.
"""

from __future__ import annotations

import numpy as np

from zwcore import ZMap, plan_scanline
from zwcore.toolpath import scanline_toolpaths


def bench_part(n: int) -> ZMap:
    x = np.linspace(0.0, 100.0, n)
    xx, yy = np.meshgrid(x, x)
    z = 8.0 * np.sin(xx / 9.0) * np.cos(yy / 13.0) + 0.002 * (xx - 50.0) ** 2
    pocket = np.hypot(xx - 60.0, yy - 40.0)
    z = np.where(pocket < 15.0, np.minimum(z, -12.0 + 15.0 - np.sqrt(
        np.maximum(15.0**2 - pocket**2, 0.0))), z)
    z = np.where(xx > 85.0, z + 10.0, z)
    step = 100.0 / (n - 1)
    return ZMap(z, dx=step, dy=step)


def test_program_finishes_where_the_plan_says_it_does_beside_steep_walls() -> None:
    part = bench_part(513)
    plan = plan_scanline(part)
    # one thread for the program's verification: this test is heavy, and a live server's
    # latency test may run beside it on the other core
    tp = scanline_toolpaths(part, plan, overlap=False)
    assert tp.check is not None and tp.check.gouge <= 1e-9
    left = tp.check.machined - part.z
    assert plan.finished.mean() > 0.85
    # where the plan finishes, the program leaves the tolerance and at most what the
    # paths' chords add (a fraction of it: 0.0112 at 0.01 here, as on Mount Rushmore)
    assert left[plan.finished].max() <= 1.2 * plan.tolerance
    assert tp.check.finished_over_part_max == left[plan.finished].max()
    # and the plan does not leave out much the program finishes (it is not made safe by
    # claiming nothing)
    assert (left <= plan.tolerance).mean() - plan.finished.mean() < 0.05
