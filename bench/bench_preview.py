"""Benchmark of the previews: a 2048² stage model drawn as a PNG (issue 13: under 1 s).

Run: ``.venv/bin/python bench/bench_preview.py``.

Times, in one run, the whole preview of a stored plan result holding one 2048 x 2048
stage model (JSON parse, base64 decode, block-maximum reduction to 512², shading,
colour bar, scale bar, PNG encoding: :func:`service.routers.previews.render`), an
overview of four such stages, and as a same-run reference a bare matplotlib Agg
PNG of a 512² image without shading (the floor any matplotlib preview pays).
Best of five runs each.
"""

from __future__ import annotations

import io
import sys
import time
from pathlib import Path

import numpy as np
import orjson

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from matplotlib.figure import Figure

from service.grids import canonical_grid
from service.routers.previews import render

N = 2048


def _model(n: int, seed: int) -> np.ndarray:
    y, x = np.mgrid[0:n, 0:n] / n
    rng = np.random.default_rng(seed)
    return (20 * np.exp(-((x - 0.5) ** 2 + (y - 0.4) ** 2) / 0.05)
            + 2 * np.sin(9 * x) * np.cos(7 * y) + 0.01 * rng.standard_normal((n, n)))


def _plan(n_stages: int) -> bytes:
    stages = []
    for k in range(n_stages):
        grid = canonical_grid(_model(N, k) + 5.0 * (n_stages - k), x0=0.0, y0=0.0, dx=0.05,
                              dy=0.05, interpolation="bilinear")
        stages.append({"index": k, "level": 11 - k, "model": grid, "tool": {
            "id": f"BEM-D{10 - 2 * k}", "kind": "ball", "diameter": 10.0 - 2 * k,
            "flute_length": 20.0}})
    return orjson.dumps({"task_id": "0" * 64, "operation": "plan_scanline", "stages": stages})


def _best(fn, repeat: int = 5) -> tuple[float, bytes]:  # type: ignore[no-untyped-def]
    best, out = float("inf"), b""
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t)
    return best, out


def _floor() -> bytes:
    fig = Figure(figsize=(7.0, 5.6))
    fig.add_subplot().imshow(np.zeros((512, 512)), origin="lower")
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    return buf.getvalue()


def main() -> None:
    one, four = _plan(1), _plan(4)
    render(one, None, 0, None)  # warm: fonts, colour maps
    t_one, png = _best(lambda: render(one, None, 0, None))
    t_four, png4 = _best(lambda: render(four, None, None, None), repeat=3)
    t_floor, _ = _best(_floor)
    print(f"stage model {N}x{N} -> PNG ({len(png) // 1024} KiB): {t_one * 1000:.0f} ms "
          f"(target < 1000 ms: {t_one:.2f}x of the budget)")
    print(f"overview of 4 stages of {N}x{N} ({len(png4) // 1024} KiB): {t_four * 1000:.0f} ms")
    print(f"bare Agg PNG of a 512x512 image, same run: {t_floor * 1000:.0f} ms "
          f"(stage preview / bare = {t_one / t_floor:.1f}x)")


if __name__ == "__main__":
    main()
