"""Tool choice by reach: speed at 513², 1025², 2049² and the Mount Rushmore chain.

Prints, in one run: the whole scan-line plan's time and its reach phase (the
finishing-ball choice and rest regions) on the synthetic part of
``bench_scanline_core.py`` at three sizes with the ratios between them; then Mount
Rushmore (../shared/data): the tool sequence, each finishing ball's region area and
estimated cut length, and the finishing cut length against finishing the whole
part with the smallest ball (both at the flat pick-feed that holds the tolerance).
Usage: ``python bench/bench_reach.py [--tolerance 0.01] [--no-sizes]``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from bench_scanline_core import synthetic  # noqa: E402

from zwcore import ZMap, plan_scanline  # noqa: E402
from zwcore.grid.tools import default_tools  # noqa: E402
from zwcore.scanline._regions import finishing_chain, flat_pick_feed  # noqa: E402

DATA = ROOT.parent / "shared" / "data" / "mount_rush_zmap_0.1mm.npy"


def _timed(zmap: ZMap, tol: float, repeat: int) -> tuple[float, float, object]:
    best, reach, plan = float("inf"), float("inf"), None
    for _ in range(repeat):
        t = time.perf_counter()
        plan = plan_scanline(zmap, tolerance=tol)
        took = time.perf_counter() - t
        if took < best:
            best = took
            reach = dict(plan.timings).get("reach", float("nan"))
    return best, reach, plan


def sizes(tol: float) -> None:
    print("synthetic part (bench_scanline_core.py), whole plan and its reach phase:")
    times = {}
    for n in (513, 1025, 2049):
        best, reach, plan = _timed(synthetic(n), tol, 3 if n < 2049 else 2)
        times[n] = (best, reach)
        r = plan.reach  # type: ignore[attr-defined]
        regions = ", ".join(f"{s.tool.id} {100 * s.region_area_fraction:.1f} %"
                            for s in plan.stages  # type: ignore[attr-defined]
                            if s.region is not None and s.pass_index == 1)
        print(f"  {n}x{n}: plan {best:.3f} s, reach {reach:.3f} s, finishing "
              f"{' > '.join(r.finishing_tools)} (regions: {regions or 'none'}), "
              f"cut {r.finishing_cut_length:.0f} mm vs {r.smallest_ball_cut_length:.0f} mm "
              f"with the smallest ball everywhere (factor "
              f"{r.smallest_ball_cut_length / r.finishing_cut_length:.2f})")
    for a, b in ((513, 1025), (1025, 2049)):
        print(f"  ratio {b}/{a} (cells x4): plan {times[b][0] / times[a][0]:.2f}, "
              f"reach {times[b][1] / times[a][1]:.2f}")


def rushmore(tol: float) -> None:
    if not DATA.exists():
        print(f"no data at {DATA}")
        return
    z = np.load(DATA).astype(np.float64)
    zmap = ZMap(z, x0=-40.958, y0=-24.696, dx=0.1, dy=0.1)
    best, reach, plan = _timed(zmap, tol, 1)
    r = plan.reach  # type: ignore[attr-defined]
    area = (z.shape[0] - 1) * (z.shape[1] - 1) * 0.01
    print(f"\nMount Rushmore {z.shape[0]}x{z.shape[1]}, tolerance {tol:g}: plan {best:.2f} s "
          f"(reach {reach:.2f} s), checks ok {plan.checks.ok}")  # type: ignore[attr-defined]
    print(f"  tool sequence: {' > '.join(plan.tool_sequence)}")  # type: ignore[attr-defined]
    print("  | finishing ball | region % | region mm² | est. cut length mm | regions |")
    print("  | --- | --- | --- | --- | --- |")
    seen = set()
    for s in plan.stages:  # type: ignore[attr-defined]
        if s.level != plan.depth or s.tool.id in seen:  # type: ignore[attr-defined]
            continue
        seen.add(s.tool.id)
        print(f"  | {s.tool.id} | {100 * s.region_area_fraction:.1f} | "
              f"{s.region_area_fraction * area:.0f} | {s.estimated_cut_length:.0f} | "
              f"{s.region_count} |")
    small = r.finishing_tools[-1]
    last = next(s for s in plan.stages if s.tool.id == small)  # type: ignore[attr-defined]
    print(f"  finishing cut length {r.finishing_cut_length:.0f} mm against "
          f"{r.smallest_ball_cut_length:.0f} mm with the smallest ball everywhere: "
          f"factor {r.smallest_ball_cut_length / r.finishing_cut_length:.2f}")
    if len(r.finishing_tools) > 1:
        whole = area / flat_pick_feed(last.tool.radius, tol)
        print(f"  {small} alone: {last.estimated_cut_length:.0f} mm in its regions against "
              f"{whole:.0f} mm over the whole part: "
              f"factor {whole / last.estimated_cut_length:.2f}")
    chain = finishing_chain(z, 0.1, 0.1, list(default_tools("ball")), tol)
    print("  least estimated finishing cut length with each ball as the main one, mm: "
          + ", ".join(f"{k} {v:.0f}" for k, v in chain.by_main.items()))
    print(f"  unreachable by every ball: {r.unreachable_area:.1f} mm², up to "
          f"{r.unreachable_max_height:.2f} mm")
    for note in plan.notes:  # type: ignore[attr-defined]
        print(f"  note: {note}")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--tolerance", type=float, nargs="*", default=[0.01])
    ap.add_argument("--no-sizes", action="store_true")
    args = ap.parse_args()
    if not args.no_sizes:
        sizes(args.tolerance[0])
    for tol in args.tolerance:
        rushmore(tol)


if __name__ == "__main__":
    main()
