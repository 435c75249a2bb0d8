"""Small balls' per-cell drop-cutter bound (``zwcore.sim._cells``) and coarse grids.

1. How far the bilinear drop-cutter CL stands above the truth inside cells: the plane
   bound and the per-cell bound against dense sampling of the bilinear surface (a lower
   bound of the true CL), at sampled nodes of the bench part at 257² (0.39 mm); and the
   per-cell bound's cost on a whole 1025² grid against the dilation, one thread.
2. Plans of the bench part on grids coarse for the library's balls, with the per-cell
   bound (the plan's choice, ``cell_bound``) and without (``coarse_grid`` answering no),
   in the same run: the plan's finished area, where the verified program is within the
   tolerance, the most it leaves where the plan finishes, its length.

Run: ``PYTHONPATH=. .venv/bin/python bench/bench_coarse.py``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import zwcore.scanline._regions as regions  # noqa: E402
from bench.bench_scanline_core import synthetic  # noqa: E402
from zwcore import ZMap, plan_scanline  # noqa: E402
from zwcore.grid.tools import Tool  # noqa: E402
from zwcore.sim import drop_cutter  # noqa: E402
from zwcore.toolpath import scanline_toolpaths  # noqa: E402

SAMPLES = 200


def dense_cl(z: np.ndarray, d: float, radius: float, i: int, k: int, per: int = 24) -> float:
    """The CL at node ``(i, k)`` over the bilinear surface sampled ``per`` times a cell."""
    ny, nx = z.shape
    cx, cy = k * d, i * d
    xs = np.arange(max(0.0, cx - radius), min((nx - 1) * d, cx + radius) + 1e-12, d / per)
    ys = np.arange(max(0.0, cy - radius), min((ny - 1) * d, cy + radius) + 1e-12, d / per)
    xx, yy = np.meshgrid(xs, ys)
    d2 = (xx - cx) ** 2 + (yy - cy) ** 2
    m = d2 <= radius * radius
    fx, fy, d2 = xx[m] / d, yy[m] / d, d2[m]
    k0 = np.minimum(np.floor(fx).astype(int), nx - 2)
    i0 = np.minimum(np.floor(fy).astype(int), ny - 2)
    s, t = fx - k0, fy - i0
    zb = (z[i0, k0] * (1 - s) * (1 - t) + z[i0, k0 + 1] * s * (1 - t)
          + z[i0 + 1, k0] * (1 - s) * t + z[i0 + 1, k0 + 1] * s * t)
    return float((zb - (radius - np.sqrt(radius * radius - d2))).max())


def excess() -> None:
    part = synthetic(257)
    rng = np.random.default_rng(0)
    nodes = rng.integers(0, 257, (SAMPLES, 2))
    print(f"excess over dense sampling, bench part 257² ({part.dx:.3f} mm), {SAMPLES} nodes")
    print("| ball | planes p50 / p95 mm | per-cell p50 / p95 mm | per-cell never below |")
    print("| --- | --- | --- | --- |")
    for d in (8.0, 3.0, 1.0):
        tool = Tool(f"D{d:g}", "ball", d, 2 * d)
        planes = drop_cutter(part, tool)
        cells = drop_cutter(part, tool, cell_bound=True)
        ref = np.array([dense_cl(part.z, part.dx, d / 2, i, k) for i, k in nodes])
        a, b = planes[nodes[:, 0], nodes[:, 1]] - ref, cells[nodes[:, 0], nodes[:, 1]] - ref
        print(f"| Ø{d:g} | {np.median(a):.4f} / {np.percentile(a, 95):.4f} | "
              f"{np.median(b):.4f} / {np.percentile(b, 95):.4f} | {bool(b.min() >= 0)} |")
    big = synthetic(1025)
    for d in (1.0, 3.0):
        tool = Tool(f"D{d:g}", "ball", d, 2 * d)
        drop_cutter(ZMap(big.z[:64, :64], dx=big.dx, dy=big.dy), tool, threads=1,
                    cell_bound=True)  # compiled
        t = time.perf_counter()
        drop_cutter(big, tool, threads=1)
        t1 = time.perf_counter() - t
        t = time.perf_counter()
        drop_cutter(big, tool, threads=1, cell_bound=True)
        t2 = time.perf_counter() - t
        print(f"whole 1025² grid, Ø{d:g}, one thread: planes {t1:.3f} s, with the per-cell "
              f"bound {t2:.3f} s ({t2 / t1:.1f}x)")


def plans() -> None:
    print("\n| grid | tolerance | cell_bound | chain | finished | program within | "
          "most left where finished mm | within_tolerance | program min | plan s |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    chosen = regions.coarse_grid
    for n, tol in ((257, 0.01), (193, 0.02), (513, 0.01)):
        part = synthetic(n)
        for on in (True, False):
            regions.coarse_grid = chosen if on else (lambda *_: False)
            try:
                t = time.perf_counter()
                plan = plan_scanline(part, tolerance=tol)
                took = time.perf_counter() - t
                tp = scanline_toolpaths(part, plan)
            finally:
                regions.coarse_grid = chosen
            assert tp.check is not None
            left = tp.check.machined - part.z
            fin = plan.finished if plan.finished is not None else np.zeros(left.shape, bool)
            most = float(left[fin].max()) if fin.any() else float("nan")
            print(f"| {n}² | {tol:g} | {plan.cell_bound} | {'>'.join(plan.tool_sequence)} | "
                  f"{fin.mean():.1%} | {(left <= tol).mean():.1%} | {most:.4f} | "
                  f"{tp.check.within_tolerance} | {tp.time_min:.0f} | {took:.2f} |")


if __name__ == "__main__":
    excess()
    plans()
