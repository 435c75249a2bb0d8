"""A stored scan-line plan simulated again (``POST /v1/simulate`` with a task id): time of
the replay of its passes and of its NC program against the time of planning it, in the
same run, and how far the replay's figures are from the plan's own.

Parts: Mount Rushmore (../shared/data, from OpenCAMLib's ``stl/mount_rush.stl``, LGPL 2.1,
read in place) and a synthetic 513² relief. Run: ``.venv/bin/python
bench/bench_simulate_plan.py``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from zwcore import ZMap, plan_scanline  # noqa: E402
from zwcore.scanline.replay import replay_passes  # noqa: E402
from zwcore.toolpath import scanline_toolpaths  # noqa: E402
from zwcore.toolpath.verify_plan import replay_program  # noqa: E402

DATA = ROOT.parent / "shared" / "data" / "mount_rush_zmap_0.1mm.npy"


def relief(n: int, dx: float) -> ZMap:
    y, x = np.mgrid[0:n, 0:n] * dx
    z = (4.0 * np.sin(x / 7.0) * np.cos(y / 9.0) + 3.0 * np.exp(-((x - 20) ** 2 + (y - 30) ** 2)
                                                               / 40.0) - 0.02 * x)
    return ZMap(z, dx=dx, dy=dx)


def run(name: str, part: ZMap) -> None:
    t = time.perf_counter()
    plan = plan_scanline(part)
    t_plan = time.perf_counter() - t
    t = time.perf_counter()
    rp = replay_passes(part, plan)
    t_pass = time.perf_counter() - t
    worst = max(max(abs(s.sim_max_depth_of_cut - p.depth_max),
                    abs(s.sim_left_over_next_max - p.left_over_next_max),
                    abs(s.sim_left_over_part_max - p.left_over_part_max))
                for s, p in zip(plan.stages, rp.passes, strict=True))
    gouge = float(max(0.0, (part.z - rp.machined).max()))
    t = time.perf_counter()
    tp = scanline_toolpaths(part, plan, verify=False)
    t_paths = time.perf_counter() - t
    numbers = {p.cutting.tool_number: p.tool for p in tp.stages}
    t = time.perf_counter()
    pr = replay_program(part, plan, tp.program, numbers)
    t_prog = time.perf_counter() - t
    pgouge = float(max(0.0, (part.z - pr.machined).max()))
    print(f"| {name} | {part.shape[0]}x{part.shape[1]} | {len(plan.stages)} | {t_plan:.2f} "
          f"| {t_pass:.2f} ({t_pass / t_plan:.2f}x) | {worst:.2e} | {gouge:.1e} "
          f"| {t_paths:.2f} | {t_prog:.2f} ({t_prog / t_plan:.2f}x) | {pgouge:.1e} "
          f"| {float((pr.machined - part.z).max()):.4f} |")


def main() -> None:
    print("| part | grid | passes | plan s | replay passes s (/plan) | max figure diff mm "
          "| passes gouge mm | paths+program s | replay program s (/plan) "
          "| program gouge mm | program left max mm |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    run("relief", relief(513, 0.1))
    if DATA.exists():
        z = np.load(DATA).astype(np.float64)
        run("Mount Rushmore", ZMap(z, x0=-40.958, y0=-24.696, dx=0.1, dy=0.1))
    else:
        print(f"(no {DATA}: Mount Rushmore skipped)")


if __name__ == "__main__":
    main()
