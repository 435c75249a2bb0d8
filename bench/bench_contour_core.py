"""Benchmark of the contour planner's numeric core (no HTTP).

Times :func:`zwcore.contour.plan_contour` with four flat end mills (D20, D12,
D6, D3 from the default library) on synthetic sculpted z-maps of 512², 1024²
and 2048² nodes (dx = dy = 0.1 mm, so the part grows with the grid) and on the
Mount Rushmore relief when ``../shared/data`` is present. Prints the per-phase
breakdown (MRR, height placement, coefficient editing with synthesis to the
input nodes, checks at every input node) and the growth ratios measured in this
run; for Rushmore also each stage's spacings and slab volumes, ``*`` marking
the slabs the flute cap binds (exactly the flute length).

Run: ``.venv/bin/python bench/bench_contour_core.py [--repeat N]``
"""

from __future__ import annotations

import argparse
import pathlib
import statistics
import time

import numpy as np

from zwcore.contour.planner import plan_contour
from zwcore.grid.tools import default_tools
from zwcore.grid.zmap import ZMap

DATA = pathlib.Path(__file__).resolve().parents[2] / "shared" / "data"
PHASES = ("mrr", "heights", "terraces", "checks")


def sculpted(n: int, dx: float = 0.1, seed: int = 0) -> np.ndarray:
    """A relief: Gaussian bumps and dents on a tilted base, with a deep pocket."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:n, 0:n] * dx
    size = n * dx
    z = 0.05 * x - 0.02 * y
    for _ in range(24):
        cx, cy = rng.uniform(0, size, 2)
        r = rng.uniform(0.05, 0.2) * size
        z += rng.uniform(-15, 25) * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * r * r))
    lo, hi = int(0.35 * n), int(0.5 * n)
    z[lo:hi, lo:hi] -= 30.0
    return z


def run(name: str, zm: ZMap, repeat: int) -> dict[str, float]:
    tools = [t for t in default_tools("flat") if t.diameter in (20.0, 12.0, 6.0, 3.0)]
    totals, phases = [], {p: [] for p in PHASES}
    plan = None
    for _ in range(repeat):
        t: dict[str, float] = {}
        t0 = time.perf_counter()
        plan = plan_contour(zm, tools, timings=t)
        totals.append(time.perf_counter() - t0)
        for p in PHASES:
            phases[p].append(t[p])
    assert plan is not None
    med = {p: statistics.median(v) for p, v in phases.items()}
    med["total"] = statistics.median(totals)
    ny, nx = zm.shape
    print(f"{name:<22} {ny:>5}x{nx:<5} total {med['total'] * 1e3:8.1f} ms  "
          + "  ".join(f"{p} {med[p] * 1e3:7.1f}" for p in PHASES)
          + f"   slabs {len(plan.contour_spacings):3d}  ok {plan.checks.ok}"
          + f"  spread {plan.checks.max_volume_spread:.2e}")
    return med


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    print(f"plan_contour, 4 tools (D20 D12 D6 D3), median of {args.repeat}; phases in ms")
    res = {}
    for n in (512, 1024, 2048):
        res[n] = run(f"sculpted {n}^2", ZMap(sculpted(n), dx=0.1, dy=0.1), args.repeat)
    for a, b in ((512, 1024), (1024, 2048)):
        print(f"ratio {b}^2/{a}^2 (4x nodes): total {res[b]['total'] / res[a]['total']:.2f}x  "
              + "  ".join(f"{p} {res[b][p] / max(res[a][p], 1e-9):.2f}x" for p in PHASES))
    path = DATA / "mount_rush_zmap_0.1mm.npy"
    if path.exists():
        z = np.load(path).astype(np.float64)
        zm = ZMap(z, x0=-40.958, y0=-24.696, dx=0.1, dy=0.1)
        run("Mount Rushmore", zm, args.repeat)
        plan = plan_contour(zm)
        print("Rushmore, default library, default stock top "
              f"{plan.stock_top:.4f} mm:")
        for s in plan.stages:
            print(f"  {s.tool.id:<8} level {s.level} cell {s.cell_size[0]:g} mm "
                  f"flute {s.tool.flute_length:g} {s.spacing_rule:<12} spacings "
                  + ", ".join(f"{v:.3f}" + "*" * c
                              for v, c in zip(s.spacings, s.flute_cap_binds, strict=True))
                  + "  | slab volumes cm3 "
                  + ", ".join(f"{v / 1e3:.2f}" for v in s.slab_volumes)
                  + f"  | capped {sum(s.flute_cap_binds)}  spread {s.volume_spread:.1e}")
    else:
        print(f"Mount Rushmore: {path} not found, skipped")


if __name__ == "__main__":
    main()
