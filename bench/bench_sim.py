"""Cutting simulation speed: drop-cutter CL points per second against opencamlib.

Mount Rushmore (../shared/data, from OpenCAMLib's ``stl/mount_rush.stl``, LGPL 2.1,
read in place): a Ø6 ball's CL over the 0.1 mm z-map by :func:`zwcore.sim.drop_cutter`
against opencamlib's ``BatchDropCutter`` on the STL, in the same run; then a scaling
table over grid sizes and radii. Run: ``.venv/bin/python bench/bench_sim.py``.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from zwcore import Tool, ZMap  # noqa: E402
from zwcore.sim import closing, drop_cutter, simulation_work  # noqa: E402

X0, Y0, DX = -40.958, -24.696, 0.1


def data_dir() -> Path:
    for d in (ROOT.parent / "shared" / "data", ROOT.parent.parent / "shared" / "data"):
        if (d / "mount_rush.stl").exists():
            return d
    sys.exit("no ../shared/data with mount_rush.stl")


def read_stl(path: Path) -> np.ndarray:
    """Binary STL triangles, (n, 3, 3) float64."""
    rec = np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    raw = path.read_bytes()
    n = int(np.frombuffer(raw[80:84], "<u4")[0])
    return np.frombuffer(raw[84:84 + 50 * n], rec)["v"].astype(np.float64)


def ocl_rate(tri: np.ndarray, z: np.ndarray, diameter: float, step: int
             ) -> tuple[float, np.ndarray, np.ndarray] | None:
    try:
        import opencamlib as ocl
    except ImportError:
        return None
    surf = ocl.STLSurf()
    for t in tri:
        surf.addTriangle(ocl.Triangle(*(ocl.Point(*v) for v in t)))
    cutter = ocl.BallCutter(diameter, 4 * diameter)  # bdc keeps a pointer: keep it alive
    bdc = ocl.BatchDropCutter()
    bdc.setSTL(surf)
    bdc.setCutter(cutter)
    ii, kk = np.mgrid[0:z.shape[0]:step, 0:z.shape[1]:step]
    for i, k in zip(ii.ravel(), kk.ravel(), strict=True):
        bdc.appendPoint(ocl.CLPoint(X0 + k * DX, Y0 + i * DX, -1000.0))
    start = time.perf_counter()
    bdc.run()
    elapsed = time.perf_counter() - start
    cl = np.array([p.z for p in bdc.getCLPoints()]).reshape(ii.shape)
    return ii.size / elapsed, cl, np.stack([ii, kk])


def best_of(fn, n: int = 3) -> float:  # type: ignore[no-untyped-def]
    times = []
    for _ in range(n):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def main() -> None:
    d = data_dir()
    z = np.load(d / "mount_rush_zmap_0.1mm.npy").astype(np.float64)
    part = ZMap(z, X0, Y0, DX, DX)
    ball = Tool("BEM-D6", "ball", 6.0, 12.0)
    print(f"Mount Rushmore {z.shape[0]} x {z.shape[1]} at {DX} mm; Ø6 ball; "
          f"{os.cpu_count()} CPUs visible")
    t = best_of(lambda: drop_cutter(part, ball))
    ours = z.size / t
    print(f"zwcore.sim drop_cutter: {z.size} CL points in {t:.3f} s = {ours:,.0f} points/s")
    res = ocl_rate(read_stl(d / "mount_rush.stl"), z, 6.0, step=6)
    if res is None:
        print("opencamlib not installed: no comparison")
    else:
        rate, ocl_cl, (ii, kk) = res
        print(f"opencamlib BatchDropCutter: {ii.size} CL points, {rate:,.0f} points/s")
        print(f"ratio: {ours / rate:,.0f} x opencamlib's points per second")
        cl = drop_cutter(part, ball)[ii, kk]
        hit = ocl_cl > -999
        diff = (cl - ocl_cl)[hit]
        print(f"CL minus opencamlib's (STL vs z-map surfaces differ): "
              f"median {np.median(diff):+.4f}, p1 {np.percentile(diff, 1):+.4f}, "
              f"p99 {np.percentile(diff, 99):+.4f} mm")
    t = best_of(lambda: closing(part, ball), 1)
    print(f"closing (CL + envelope) Ø6: {t:.3f} s")
    print("\nscaling: drop_cutter seconds (ball, dx 0.1 mm, smooth random relief)")
    print(f"{'grid':>6} " + " ".join(f"{'Ø' + str(dd):>8}" for dd in (2, 6, 12))
          + "   ns/(node*footprint node) at Ø6")
    rng = np.random.default_rng(0)
    for n in (513, 1025, 2049):
        y, x = np.mgrid[0:n, 0:n] * DX
        f = rng.uniform(0.05, 0.3, 4)
        zz = 5 * np.sin(f[0] * x) * np.cos(f[1] * y) + 2 * np.sin(f[2] * x + f[3] * y)
        zm = ZMap(zz, dx=DX, dy=DX)
        row = []
        for dd in (2.0, 6.0, 12.0):
            row.append(best_of(lambda zm=zm, dd=dd: drop_cutter(zm, Tool("b", "ball", dd, 1)), 1))
        work = simulation_work(zm.shape, Tool("b", "ball", 6.0, 1), DX, DX)
        print(f"{n:>5}² " + " ".join(f"{s:8.3f}" for s in row)
              + f"   {row[1] / work * 1e9:.3f}")
    pruned_against_dilation()


def pruned_against_dilation() -> None:
    """Large balls: the branch and bound (``method="pruned"``) against the dilation on the
    1025² bench part of ``bench_scanline_core`` (0.098 mm), CPU seconds of all threads and
    the largest difference, in the same run."""
    from bench.bench_scanline_core import synthetic

    part = synthetic(1025)
    print(f"\npruned drop-cutter against the dilation, 1025² bench part at {part.dx:g} mm "
          "(CPU s, all threads; dilation - pruned mm)")
    for dd in (8.0, 12.0, 20.0):
        tool = Tool("b", "ball", dd, 1)
        drop_cutter(ZMap(part.z[:64, :64], dx=part.dx, dy=part.dy), tool, method="pruned")
        c = time.process_time()
        a = drop_cutter(part, tool, method="pruned")
        tp = time.process_time() - c
        c = time.process_time()
        b = drop_cutter(part, tool)
        td = time.process_time() - c
        print(f"Ø{dd:g}: pruned {tp:.2f} s, dilation {td:.2f} s ({td / tp:.1f}x); difference "
              f"{(b - a).min():.1e} .. {(b - a).max():.1e}")


if __name__ == "__main__":
    main()
