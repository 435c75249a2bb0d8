"""STL to z-map: parse and rasterise a synthetic 1-million-triangle STL at 2048².

The mesh is a free-form relief (the part of bench_http) triangulated on a 708 x 708
vertex lattice, jittered so that triangle edges fall between grid nodes, written as a
binary STL with numpy-stl. Prints the parse and rasterise times, the pairs per second,
and the in-run reference of one ``np.maximum.at`` over as many pairs (the scatter
step alone), so the ratio is machine-independent. Run:
``PYTHONPATH=. .venv/bin/python bench/bench_zmap.py [--quick]``.
"""

from __future__ import annotations

import argparse
import io
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from zwcore.io import rasterise, read_stl, zmap_grid


def relief_stl(m: int, seed: int = 0) -> bytes:
    """Binary STL of an m x m vertex lattice over 100 mm: 2 (m-1)² triangles."""
    from stl import mesh as stl_mesh

    rng = np.random.default_rng(seed)
    u = np.linspace(0.0, 100.0, m)
    x, y = np.meshgrid(u, u)
    h = 100.0 / (m - 1)
    x[1:-1, 1:-1] += rng.uniform(-0.3, 0.3, (m - 2, m - 2)) * h
    y[1:-1, 1:-1] += rng.uniform(-0.3, 0.3, (m - 2, m - 2)) * h
    s, t = x / 100, y / 100
    z = (8 * np.sin(3 * np.pi * s) * np.cos(2 * np.pi * t)
         + 10 * np.exp(-((s - .3) ** 2 + (t - .6) ** 2) * 20))
    v = np.stack([x, y, z], axis=-1)
    a, b, c, d = v[:-1, :-1], v[:-1, 1:], v[1:, 1:], v[1:, :-1]
    tri = np.concatenate([np.stack([a, b, c], -2).reshape(-1, 3, 3),
                          np.stack([a, c, d], -2).reshape(-1, 3, 3)])
    out = stl_mesh.Mesh(np.zeros(len(tri), dtype=stl_mesh.Mesh.dtype))
    out.vectors[:] = tri
    buf = io.BytesIO()
    out.save("relief.stl", fh=buf, mode=stl_mesh.stl.Mode.BINARY)
    return buf.getvalue()


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    m, n = (355, 1024) if args.quick else (708, 2048)
    data = relief_stl(m)
    t = time.perf_counter()
    tri = read_stl(data)
    t_parse = time.perf_counter() - t
    grid = zmap_grid(tri, nx=n, ny=n)
    times = []
    for _ in range(2 if args.quick else 3):
        t = time.perf_counter()
        res = rasterise(tri, grid)
        times.append(time.perf_counter() - t)
    t_rast = min(times)
    pairs = int(res.covered.sum())
    # reference: the scatter maximum alone over as many (node, height) pairs as nodes x 1.5
    rng = np.random.default_rng(1)
    idx = rng.integers(0, n * n, int(1.5 * n * n))
    val = rng.random(len(idx))
    out = np.full(n * n, -np.inf)
    t = time.perf_counter()
    np.maximum.at(out, idx, val)
    t_ref = time.perf_counter() - t
    print(f"STL to z-map: {len(tri):,} triangles ({len(data) / 1e6:.0f} MB binary STL) "
          f"at {n}x{n} ({n * n:,} nodes, {pairs:,} covered)")
    print(f"  parse (numpy-stl):   {t_parse:6.2f} s")
    print(f"  rasterise (best of {len(times)}): {t_rast:6.2f} s   target: seconds")
    print(f"  one np.maximum.at over {len(idx):,} pairs, same run: {t_ref:6.2f} s   "
          f"ratio rasterise / that = {t_rast / t_ref:5.1f}")


if __name__ == "__main__":
    main()
