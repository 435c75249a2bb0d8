"""Benchmark of the C1 arc fit: segment counts, deviations, kinks, time, scaling.

Run: ``.venv/bin/python bench/bench_arcs.py`` (``--quick`` skips the 1M-point run
and the greedy reference on the largest curves).

Columns: segments (arcs/lines), max deviation polyline->chain and chain->polyline
(dense), max kink at smooth junctions, corners, wall time of ``fit_arcs`` end to
end, ``greedy``: the minimum number of arcs/lines WITHOUT the C1 constraint when
breaks sit on input points (greedy: each piece extended as far as one circle or
line fits all its points within the tolerance; the minimum-width annulus is
found numerically), ``AW``: ArcWelder 2.0 at the same tolerance (issue text).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np
from scipy.optimize import minimize

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from curves import ARCWELDER_REFERENCE, BENCH_CURVES, ellipse

from zwcore.arcs import fit_arcs


def _band_width(pts: np.ndarray) -> float:
    """Half-width of the thinnest annulus or strip containing ``pts`` (numerical)."""
    c0 = pts.mean(axis=0)
    x = pts - c0
    # line: strip about the principal axis
    _, _, vt = np.linalg.svd(x, full_matrices=False)
    off = x @ vt[1]
    best = 0.5 * float(off.max() - off.min())
    if len(pts) < 3:
        return best
    mat = np.column_stack([x[:, 0], x[:, 1], np.ones(len(x))])
    sol, *_ = np.linalg.lstsq(mat, (x * x).sum(1), rcond=None)
    c = 0.5 * sol[:2]

    def width(cc: np.ndarray) -> float:
        d = np.hypot(x[:, 0] - cc[0], x[:, 1] - cc[1])
        return 0.5 * float(d.max() - d.min())

    if np.all(np.isfinite(c)) and np.hypot(*c) < 1e6 * (np.abs(x).max() + 1):
        scale = max(float(np.abs(x).max()), 1e-9)
        res = minimize(width, c, method="Nelder-Mead",
                       options={"xatol": 1e-7 * scale, "fatol": 1e-9, "maxiter": 2000})
        best = min(best, float(res.fun), width(c))
    return best


def greedy_min_pieces(points: np.ndarray, tol: float, closed: bool) -> int:
    """Greedy count of pieces (arcs or lines, no C1) with breaks at input points."""
    pts = np.vstack([points, points[:1]]) if closed else points
    n = len(pts)
    i, count = 0, 0
    while i < n - 1:
        lo, hi = i + 1, i + 2
        # gallop, then bisect for the last j such that pts[i..j] fits one circle/line
        while hi < n and _band_width(pts[i : hi + 1]) <= tol:
            lo, hi = hi, min(n - 1, i + 2 * (hi - i)) if hi < n - 1 else n
            if hi == lo:
                break
        hi = min(hi, n)
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if _band_width(pts[i : mid + 1]) <= tol:
                lo = mid
            else:
                hi = mid
        i = lo
        count += 1
    return count


def _timed(pts: np.ndarray, closed: bool, tol: float = 0.1) -> tuple[float, object]:
    t0 = time.perf_counter()
    chain = fit_arcs(pts, tol, closed=closed)
    return time.perf_counter() - t0, chain


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="skip the 1M-point run")
    args = ap.parse_args()
    tol = 0.1
    print(f"C1 arc fit, tolerance {tol} mm, curves sampled at 0.5 mm\n")
    head = (f"{'curve':10s} {'N':>6s} {'seg':>4s} {'arc':>4s} {'line':>4s} {'dev pts':>8s}"
            f" {'dev chain':>9s} {'kink':>8s} {'corners':>7s} {'time s':>7s}"
            f" {'greedy':>6s} {'AW':>7s}")
    print(head)
    print("-" * len(head))
    for name, make in BENCH_CURVES.items():
        pts, closed = make()
        dt, chain = _timed(pts, closed, tol)
        greedy = greedy_min_pieces(pts, tol, closed)
        aw_a, aw_l = ARCWELDER_REFERENCE[name]
        aw = "-" if aw_a is None else (f"{aw_a}" + (f"+{aw_l}L" if aw_l else ""))
        print(f"{name:10s} {len(pts):6d} {len(chain.segments):4d} {chain.n_arcs:4d}"
              f" {chain.n_lines:4d} {chain.max_deviation_points:8.4f}"
              f" {chain.max_deviation_chain:9.4f} {chain.max_kink_smooth:8.1e}"
              f" {len(chain.corners):7d} {dt:7.3f} {greedy:6d} {aw:>7s}")
    print("\nScaling (ellipse 100 x 50, closed, end to end incl. dense verification)")
    print(f"{'points':>9s} {'spacing mm':>10s} {'seg':>4s} {'time s':>7s} {'us/point':>9s}"
          f" {'ratio vs prev':>13s}")
    perimeter = 484.4224
    runs = [("0.02 mm", 0.02)]
    sizes = [10_000, 100_000] + ([] if args.quick else [1_000_000])
    runs += [(f"{n} pts", perimeter / n) for n in sizes]
    prev: tuple[int, float] | None = None
    for _, step in runs:
        pts, closed = ellipse(step)
        dt, chain = _timed(pts, closed, tol)
        ratio = ""
        if prev is not None:
            ratio = f"t x{dt / prev[1]:.1f} / N x{len(pts) / prev[0]:.1f}"
        print(f"{len(pts):9d} {step:10.5f} {len(chain.segments):4d} {dt:7.3f}"
              f" {1e6 * dt / len(pts):9.2f} {ratio:>13s}")
        prev = (len(pts), dt)
    print("\nArcWelder 2.0 on the 0.02 mm ellipse (24,223 points): 10.3 s (issue text)")
    _ = math.pi


if __name__ == "__main__":
    main()
