"""End-to-end HTTP timings against a live server, with in-run reference ratios.

- POST /v1/mrr, 2048² float32 z_b64, include_models false, vs pywt.wavedec2 on the same grid;
  the same call with the grid as an ``application/x-npy`` body;
- POST /v1/plans/scanline on 513², 1025², 2049² (z_b64, include_models false);
- POST /v1/plans/contour with four flat end mills on 512², 1024², 2048².

Each call sends a grid not seen before (a different offset), so nothing is served from
the cache. Run: ``.venv/bin/python bench/bench_http.py [--quick]``.
"""

from __future__ import annotations

import argparse
import base64
import io
import sys
import time
from collections.abc import Callable
from pathlib import Path

import httpx
import numpy as np
import orjson

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bench._server import live_server
from bench.bench_contour_core import sculpted
from bench.bench_scanline_core import synthetic


def part(n: int, seed: int = 0) -> np.ndarray:
    """A free-form part: smooth hills and a pocket, heights in mm over a 100 mm square."""
    y, x = np.mgrid[0:1:n * 1j, 0:1:n * 1j]
    z = (8 * np.sin(3 * np.pi * x) * np.cos(2 * np.pi * y)
         + 10 * np.exp(-((x - .3) ** 2 + (y - .6) ** 2) * 20)
         - 12 * np.exp(-((x - .7) ** 2 + (y - .3) ** 2) * 40))
    return z + seed * 1e-3


def grid_b64(z: np.ndarray, dtype: str = "float32", dx: float | None = None) -> dict:
    arr = np.ascontiguousarray(z, dtype="<f4" if dtype == "float32" else "<f8")
    step = dx if dx is not None else 100.0 / (z.shape[1] - 1)
    return {"x0": 0.0, "y0": 0.0, "dx": step, "dy": step,
            "shape": list(arr.shape), "dtype": dtype,
            "z_b64": base64.b64encode(arr.tobytes()).decode()}


def best(fn: Callable[[int], object], repeat: int) -> float:
    times = []
    for k in range(repeat):
        t = time.perf_counter()
        fn(k)
        times.append(time.perf_counter() - t)
    return min(times)


NPY = "application/x-npy"


def npy_body(z: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, z, allow_pickle=False)
    return buf.getvalue()


def post(client: httpx.Client, url: str, body: bytes, fresh: bool = True,
         media: str = "application/json") -> dict:
    r = client.post(url, content=body, headers={"content-type": media}, timeout=600)
    r.raise_for_status()
    assert not fresh or r.headers["x-cache"] != "hit", "timed a cache hit"
    return r.json()


def mrr_phases(body: bytes, repeat: int) -> dict[str, float]:
    """Phase times of one POST /v1/mrr, run in process on the same body."""
    import base64
    import json

    import pybase64

    from service.grids import decode_grid
    from service.hashing import task_id
    from service.routers.mrr import _haar_margins, mrr_result
    from service.schemas.mrr import MrrRequest
    from zwcore import analyse

    def ms(fn: Callable[[], object]) -> float:
        return 1e3 * best(lambda k: fn(), repeat + 1)

    data = json.loads(body)
    req = MrrRequest.model_validate(data)
    zmap = decode_grid(req.grid, 1 << 30)
    mrr = analyse(zmap.z, "haar")
    text = req.grid.z_b64 or ""
    return {
        "JSON parse (stdlib, as FastAPI)": ms(lambda: json.loads(body)),
        "base64 decode (pybase64)": ms(lambda: pybase64.b64decode(text, validate=True)),
        "base64 decode (stdlib, for reference)": ms(lambda: base64.b64decode(text,
                                                                             validate=True)),
        "decode + validate grid": ms(lambda: decode_grid(req.grid, 1 << 30)),
        "task id (SHA-256)": ms(lambda: task_id("mrr", {}, {"z": zmap.z}, {"z": True})),
        "lifted Haar MRR": ms(lambda: analyse(zmap.z, "haar")),
        "containment margins (independent)": ms(lambda: _haar_margins(mrr.approximations,
                                                                      zmap.z)),
        "whole result (MRR + figures)": ms(lambda: mrr_result(zmap, "haar", None, False)),
    }


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--only", choices=["mrr", "scanline", "contour", "arcs"], default=None)
    args = ap.parse_args()
    repeat = 2 if args.quick else 4
    with live_server() as base, httpx.Client(base_url=base) as client:
        spec = client.get("/openapi.json").json()["paths"]
        if args.only in (None, "mrr"):
            import pywt

            n = 2048
            z32 = part(n).astype(np.float32)
            # Bodies are serialised before timing: an MES sends bytes it already has.
            bodies = [orjson.dumps({"grid": grid_b64(z32 + np.float32(k)), "include_models": False})
                      for k in range(repeat + 1)]
            post(client, "/v1/mrr", bodies[-1])  # warm up imports and the pool
            t_http = best(lambda k: post(client, "/v1/mrr", bodies[k]), repeat)
            t_pywt = best(lambda k: pywt.wavedec2(z32, "haar"), repeat)
            print(f"POST /v1/mrr 2048² float32 b64 (haar): {t_http * 1e3:8.1f} ms   "
                  f"pywt.wavedec2 same grid: {t_pywt * 1e3:8.1f} ms   "
                  f"ratio pywt/http = {t_pywt / t_http:5.2f} (target >= 1)")
            # The same grid as an .npy body (x0, y0, dx, dy in the query): no JSON, no base64.
            npys = [npy_body(z32 + np.float32(k + repeat + 1)) for k in range(repeat + 1)]
            query = f"/v1/mrr?x0=0&y0=0&dx={100.0 / (n - 1)!r}&dy={100.0 / (n - 1)!r}"
            post(client, query, npys[-1], media=NPY)
            # interleaved, so both see the same load on a shared machine
            t_npy, t_pywt2 = np.inf, np.inf
            for k in range(repeat):
                t_npy = min(t_npy, best(lambda _, k=k: post(client, query, npys[k], media=NPY),
                                        1))
                t_pywt2 = min(t_pywt2, best(lambda _: pywt.wavedec2(z32, "haar"), 1))
            print(f"POST /v1/mrr 2048² float32 .npy  (haar): {t_npy * 1e3:8.1f} ms   "
                  f"pywt.wavedec2 same grid: {t_pywt2 * 1e3:8.1f} ms   "
                  f"ratio http/pywt = {t_npy / t_pywt2:5.2f} (target <= 1.0)")
            print("  where the server's time goes, in process, same grid (best of N):")
            for name, ms in mrr_phases(bodies[0], repeat).items():
                print(f"    {name:34s} {ms:7.1f} ms")
        if args.only in (None, "arcs"):
            # The ellipse (100 x 50) sampled at 0.02 mm: 24,223 points, tol 0.1.
            n = 24223
            t = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
            bodies = [orjson.dumps({"points": np.c_[100 * np.cos(t) + k * 1e-6,
                                                     50 * np.sin(t)].tolist(),
                                    "tolerance": 0.1, "closed": True, "gcode": True})
                      for k in range(repeat)]
            t_arcs = best(lambda k: post(client, "/v1/arcs", bodies[k]), repeat)
            res = post(client, "/v1/arcs", bodies[0], fresh=False)
            print(f"POST /v1/arcs ellipse {n} points, G-code: {t_arcs:.3f} s "
                  f"({res['summary']['n_segments']} segments; target <= 1 s)")
        # The parts of the core benchmarks: a 100 mm free-form part with bumps, a fillet
        # pocket and a wall (scan-line); a sculpted relief at 0.1 mm (contour).
        for op, sizes, extra in (
            ("scanline", (513, 1025, 2049), {}),
            ("contour", (512, 1024, 2048), {"tools": [
                {"id": "FEM-D20", "diameter": 20, "flute_length": 38},
                {"id": "FEM-D10", "diameter": 10, "flute_length": 22},
                {"id": "FEM-D6", "diameter": 6, "flute_length": 13},
                {"id": "FEM-D3", "diameter": 3, "flute_length": 8}]}),
        ):
            if args.only not in (None, op) or f"/v1/plans/{op}" not in spec:
                continue
            prev = None
            for n in sizes[:2] if args.quick else sizes:
                if op == "scanline":
                    zm = synthetic(n)
                    z, dx = zm.z, zm.dx
                else:
                    z, dx = sculpted(n), 0.1
                bodies = [orjson.dumps({"grid": grid_b64(z + k * 1e-3, dx=dx),
                                        "include_models": False, **extra})
                          for k in range(repeat)]
                url = f"/v1/plans/{op}"
                t_op = best(lambda k, url=url, bodies=bodies: post(client, url, bodies[k]),
                            repeat)
                growth = ("" if prev is None else
                          f"  x{t_op / prev[1]:4.2f} time for x{n * n / prev[0]:4.2f} cells")
                plan = post(client, url, bodies[0], fresh=False)
                tools = ">".join(dict.fromkeys(s["tool"]["id"] for s in plan["stages"]))
                print(f"POST /v1/plans/{op:8s} {n:5d}²: {t_op:7.3f} s{growth}   "
                      f"[{len(plan['stages'])} stages: {tools}]")
                prev = (n * n, t_op)


if __name__ == "__main__":
    main()
