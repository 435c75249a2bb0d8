"""Tool choice by reach and rest regions: plan time before/after, and Mount Rushmore.

Prints, in one run: the whole scan-line plan's time (best of ``--repeat``) with its
phases on the synthetic part of ``bench_scanline_core.py`` at 513² and 1025², for the
code of another checkout (``--before PATH``, e.g. a ``git worktree`` of the commit before
reach; without it only this tree is timed) and of this one, each in its own process,
and the ratios after/before and 1025²/513²; then
Mount Rushmore (../shared/data) with this tree: the tool sequence, each finishing
ball's region area, and the finishing cut length against finishing the whole part with
the smallest ball (both region area over the flat pick-feed that holds the tolerance).
Usage: ``python bench/bench_reach.py [--before ../zwplan-old] [--sizes 513 1025]``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "mount_rush_zmap_0.1mm.npy"


def _child(sizes: list[int], repeat: int) -> None:
    """Time the plans with the code on ``sys.path`` (run in a subprocess)."""
    sys.path.insert(0, str(ROOT / "bench"))
    from bench_scanline_core import synthetic

    from zwcore.scanline.planner import plan_scanline

    plan_scanline(synthetic(65))  # compile / load the kernels outside the timing
    out = {}
    for n in sizes:
        zmap = synthetic(n)
        best, phases = float("inf"), {}
        for _ in range(repeat):
            t = time.perf_counter()
            plan = plan_scanline(zmap)
            took = time.perf_counter() - t
            if took < best:
                best = took
                phases = {}
                for name, sec in plan.timings:
                    phases[name] = phases.get(name, 0.0) + sec
        out[n] = {"seconds": best, "phases": phases, "passes": len(plan.stages),
                  "tools": list(plan.tool_sequence)}
    print(json.dumps(out))


def _run(tree: str, sizes: list[int], repeat: int) -> dict[str, dict]:
    env = dict(os.environ, PYTHONPATH=tree)
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", "--repeat", str(repeat),
           "--sizes", *map(str, sizes)]
    done = subprocess.run(cmd, env=env, cwd=tree, capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def _sizes(before: str | None, sizes: list[int], repeat: int) -> None:
    runs = {"after": _run(str(ROOT), sizes, repeat)}
    if before is not None:
        runs = {"before": _run(before, sizes, repeat), **runs}
    print("| code | cells | plan s | passes | tools | phases (s) |")
    print("| --- | --- | --- | --- | --- | --- |")
    for name, run in runs.items():
        for n in sizes:
            r = run[str(n)]
            ph = ", ".join(f"{k} {v:.2f}" for k, v in r["phases"].items() if v >= 0.01)
            print(f"| {name} | {n}² | {r['seconds']:.2f} | {r['passes']} | "
                  f"{' > '.join(r['tools'])} | {ph} |")
    for n in sizes if "before" in runs else []:
        b, a = runs["before"][str(n)]["seconds"], runs["after"][str(n)]["seconds"]
        print(f"after / before at {n}²: {a / b:.2f}")
    if len(sizes) > 1:
        for name, run in runs.items():
            lo, hi = run[str(sizes[0])]["seconds"], run[str(sizes[-1])]["seconds"]
            print(f"{name}: {sizes[-1]}² / {sizes[0]}²: {hi / lo:.2f}")


def _rushmore() -> None:
    import numpy as np

    sys.path.insert(0, str(ROOT))
    from zwcore import ZMap, plan_scanline

    if not DATA.exists():
        print(f"no data at {DATA}")
        return
    z = np.load(DATA).astype(np.float64)
    zmap = ZMap(z, dx=0.1, dy=0.1)
    t = time.perf_counter()
    plan = plan_scanline(zmap)
    took = time.perf_counter() - t
    area = z.size * 0.01
    print(f"\nMount Rushmore {z.shape[0]} x {z.shape[1]} at 0.1 mm: plan {took:.2f} s, "
          f"{len(plan.stages)} passes, {' > '.join(plan.tool_sequence)}")
    print("phases: " + ", ".join(f"{k} {v:.2f}" for k, v in plan.timings if v >= 0.01))
    for s in plan.stages:
        if s.level == plan.depth and s.pass_index == 1:
            print(f"  {s.tool.id}: region {100 * s.region_area_fraction:.1f} % "
                  f"({s.region_area_fraction * area:.0f} mm²), {s.pass_count} passes, "
                  f"estimated cut {s.estimated_cut_length:.0f} mm")
    r = plan.reach
    if r is not None:
        print(f"finishing cut {r.finishing_cut_length:.0f} mm, smallest ball everywhere "
              f"{r.smallest_ball_cut_length:.0f} mm: factor "
              f"{r.smallest_ball_cut_length / r.finishing_cut_length:.2f}")
        print(f"left above the tolerance: {r.unreachable_area:.0f} mm², up to "
              f"{r.unreachable_max_height:.2f} mm")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--before", default=None)
    ap.add_argument("--sizes", type=int, nargs="*", default=[513, 1025])
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--child", action="store_true")
    ap.add_argument("--no-rushmore", action="store_true")
    args = ap.parse_args()
    if args.child:
        _child(args.sizes, args.repeat)
        return
    if args.sizes:
        _sizes(args.before, args.sizes, args.repeat)
    if not args.no_rushmore:
        _rushmore()


if __name__ == "__main__":
    main()
