"""Load test: concurrent clients sending a mix of requests to a live zwplan server.

    .venv/bin/python bench/load.py            # 30 s, 8 clients, own server
    .venv/bin/python bench/load.py --quick    # 5 s
    .venv/bin/python bench/load.py --url http://127.0.0.1:8000 --api-key KEY [--pid PID]

Every operation of openapi/openapi.json that has a request generator below
is exercised (``/v1/mrr`` always; ``/v1/plans/*`` and ``/v1/arcs`` once they
are in the document), plus ``GET /v1/tasks/{id}`` of earlier results. About
30 % of the requests repeat an earlier body, so the cache answers them.
The mix holds large work too (issue 14): ``LARGE_SHARE`` of the grid requests
are 2048² float32 grids (scan-line plans with and without models, MRR, contour
plans; their names end in ``_2048``), and ``COARSE_SHARE`` of the arc requests
are coarse polygons (8-16 vertices, 10 mm edges, 12° zigzag turns: the arc
fitter's slow case; ``fit_arcs_coarse``).

Prints throughput, p50/p99 latency per operation and overall, the errors
(every non-2xx answer; the 503s among them are sheds), the cache hit ratio,
and the server's resident memory: at start, its peak (VmHWM) and after the
burst (VmRSS ``--settle`` seconds after the last request). Exits 1 if any
request failed with other than a 503 shed.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import math
import random
import sys
import time
from collections import Counter, defaultdict
from collections.abc import Callable
from contextlib import AbstractContextManager, nullcontext
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import httpx

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from tests.live_server import live_server  # noqa: E402

SPEC = ROOT / "openapi" / "openapi.json"
REPEAT_SHARE = 0.30
TASK_SHARE = 0.10


def _surface(rng: random.Random, ny: int, nx: int) -> list[list[float]]:
    """A smooth part with a pocket and a boss, plus noise: realistic, cheap, varied."""
    cx, cy = rng.uniform(0.3, 0.7) * nx, rng.uniform(0.3, 0.7) * ny
    r = rng.uniform(0.2, 0.4) * min(nx, ny)
    depth, boss = rng.uniform(1, 5), rng.uniform(0.5, 3)
    rows = []
    for i in range(ny):
        row = []
        for k in range(nx):
            d2 = ((k - cx) ** 2 + (i - cy) ** 2) / (r * r)
            h = 10 - depth * math.exp(-d2) + boss * math.exp(-4 * ((k - 0.2 * nx) ** 2
                                                                 + (i - 0.8 * ny) ** 2) / (r * r))
            row.append(round(h + rng.uniform(-0.01, 0.01), 4))
        rows.append(row)
    return rows


LARGE_SHARE = 0.1
COARSE_SHARE = 0.3
LARGE_N = 2048


def _large_grid(rng: random.Random) -> dict[str, Any]:
    """A 2048² part as float32 base64 (numpy: a Python loop over 4M nodes is too slow)."""
    import numpy as np
    import pybase64

    n = LARGE_N
    y, x = np.mgrid[0:n, 0:n].astype(np.float32) / n
    cx, cy, r = rng.uniform(0.3, 0.7), rng.uniform(0.3, 0.7), rng.uniform(0.2, 0.4)
    z = (10 - rng.uniform(1, 5) * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (r * r))
         + 0.2 * np.sin(rng.uniform(5, 30) * x) * np.cos(rng.uniform(5, 30) * y))
    return {"x0": 0.0, "y0": 0.0, "dx": 0.05, "dy": 0.05, "shape": [n, n],
            "dtype": "float32", "z_b64": pybase64.b64encode(z.astype("<f4").tobytes()).decode()}


def _grid(rng: random.Random) -> dict[str, Any]:
    ny, nx = rng.randint(8, 32), rng.randint(8, 32)
    return {"x0": 0.0, "y0": 0.0, "dx": 0.5, "dy": 0.5, "z": _surface(rng, ny, nx)}


def _mrr(rng: random.Random) -> dict[str, Any]:
    return {"grid": _grid(rng), "wavelet": rng.choice(["haar", "single_knot"]),
            "include_models": rng.random() < 0.5}


def _scanline(rng: random.Random) -> dict[str, Any]:
    return {"grid": _grid(rng), "tolerance": rng.choice([0.01, 0.05, 0.1]),
            "include_models": rng.random() < 0.3}


def _contour(rng: random.Random) -> dict[str, Any]:
    return {"grid": _grid(rng), "include_models": rng.random() < 0.3}


def _coarse_polygon(rng: random.Random) -> dict[str, Any]:
    n = rng.randint(8, 16)
    pts, heading = [[0.0, rng.uniform(0, 100)]], rng.uniform(0, 6.28)
    for i in range(n - 1):
        heading += math.radians(12) * (1 if (i // 3) % 2 else -1)
        x, y = pts[-1]
        pts.append([round(x + 10 * math.cos(heading), 5), round(y + 10 * math.sin(heading), 5)])
    return {"points": pts, "tolerance": 0.05, "closed": False}


def _arcs(rng: random.Random) -> dict[str, Any]:
    n = rng.randint(30, 200)
    a, b = rng.uniform(10, 40), rng.uniform(5, 30)
    pts = [[round(a * math.cos(2 * math.pi * t / n) + rng.uniform(-0.002, 0.002), 5),
            round(b * math.sin(2 * math.pi * t / n) + rng.uniform(-0.002, 0.002), 5)]
           for t in range(n)]
    return {"points": pts, "tolerance": rng.choice([0.01, 0.05]), "closed": True,
            "gcode": rng.random() < 0.3}


# operationId -> body generator, for the POST operations the benchmark knows how to feed.
GENERATORS: dict[str, Callable[[random.Random], dict[str, Any]]] = {
    "compute_mrr": _mrr, "plan_scanline": _scanline, "plan_contour": _contour,
    "fit_arcs": _arcs,
}


def _large(name: str, rng: random.Random) -> dict[str, Any]:
    body = GENERATORS[name](rng)
    body["grid"] = _large_grid(rng)
    if name == "plan_scanline":
        body["include_models"] = rng.random() < 0.5
    return body


def generate(name: str, rng: random.Random) -> tuple[str, dict[str, Any]]:
    """(label, body): the label names the large and coarse variants apart."""
    if name == "fit_arcs" and rng.random() < COARSE_SHARE:
        return "fit_arcs_coarse", _coarse_polygon(rng)
    if name != "fit_arcs" and rng.random() < LARGE_SHARE:
        body = _large(name, rng)
        models = "_models" if body.get("include_models") else ""
        return f"{name}_2048{models}", body
    return name, GENERATORS[name](rng)


def post_operations() -> dict[str, str]:
    """operationId -> path of every POST operation in the document that we can generate."""
    spec = json.loads(SPEC.read_text())
    return {op["operationId"]: path for path, item in spec["paths"].items()
            for method, op in item.items()
            if method == "post" and op.get("operationId") in GENERATORS}


@dataclass
class Stats:
    latencies: dict[str, list[float]] = field(default_factory=lambda: defaultdict(list))
    cache: Counter[str] = field(default_factory=Counter)
    statuses: Counter[int] = field(default_factory=Counter)
    errors: list[str] = field(default_factory=list)
    task_ids: list[tuple[str, bool]] = field(default_factory=list)  # (id, large)
    error_ops: Counter[str] = field(default_factory=Counter)


async def client_loop(http: httpx.AsyncClient, ops: dict[str, str], seed: int, stop_at: float,
                      stats: Stats, history: list[tuple[str, str, dict[str, Any]]]) -> None:
    rng = random.Random(seed)
    names = sorted(ops)
    while time.monotonic() < stop_at:
        roll = rng.random()
        if roll < TASK_SHARE and stats.task_ids:
            tid, large = rng.choice(stats.task_ids)
            # large results as float32 (as rows one is over a gigabyte of text)
            name, method, body = ("get_task_2048" if large else "get_task"), "GET", None
            url = f"/v1/tasks/{tid}" + ("?grid_encoding=float32" if large else "")
        elif roll < TASK_SHARE + REPEAT_SHARE and history:
            name, op, body = rng.choice(history)
            method, url = "POST", ops[op]
        else:
            op = rng.choice(names)
            name, body = generate(op, rng)
            method, url = "POST", ops[op]
            history.append((name, op, body))
        start = time.perf_counter()
        try:
            r = await http.request(method, url, json=body)
        except httpx.HTTPError as exc:
            stats.errors.append(f"{name}: {type(exc).__name__}: {exc}")
            stats.error_ops[name] += 1
            continue
        elapsed = time.perf_counter() - start
        stats.statuses[r.status_code] += 1
        if r.status_code != 200:
            stats.errors.append(f"{name}: {r.status_code} {r.text[:200]}")
            stats.error_ops[name] += 1
            continue
        stats.latencies[name].append(elapsed)
        stats.cache[r.headers.get("x-cache", "none")] += 1
        if method == "POST" and len(stats.task_ids) < 500:
            stats.task_ids.append((r.json()["task_id"], "_2048" in name))


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    index = max(0, min(len(ordered) - 1, math.ceil(q / 100 * len(ordered)) - 1))
    return ordered[index]


def report(stats: Stats, elapsed: float, clients: int) -> str:
    all_lat = [v for vs in stats.latencies.values() for v in vs]
    total = len(all_lat) + len(stats.errors)
    w = 28
    lines = [f"duration {elapsed:.1f} s, {clients} clients, {total} requests, "
             f"throughput {total / elapsed:.1f} req/s",
             f"{'operation':<{w}}{'count':>7}{'errors':>7}{'p50 ms':>10}{'p99 ms':>10}"
             f"{'max ms':>10}"]
    for name in sorted(set(stats.latencies) | set(stats.error_ops)):
        vs = stats.latencies.get(name) or [math.nan]
        count = len(stats.latencies.get(name, []))
        lines.append(f"{name:<{w}}{count:>7}{stats.error_ops[name]:>7}"
                     f"{percentile(vs, 50) * 1e3:>10.1f}{percentile(vs, 99) * 1e3:>10.1f}"
                     f"{max(vs) * 1e3:>10.1f}")
    if all_lat:
        lines.append(f"{'overall':<{w}}{len(all_lat):>7}{len(stats.errors):>7}"
                     f"{percentile(all_lat, 50) * 1e3:>10.1f}"
                     f"{percentile(all_lat, 99) * 1e3:>10.1f}{max(all_lat) * 1e3:>10.1f}")
    answered = sum(stats.cache.values())
    hits = stats.cache["hit"] + stats.cache["shared"]
    shed = stats.statuses[503]
    lines.append(f"errors {len(stats.errors)} (503 sheds {shed}, "
                 f"other {len(stats.errors) - shed}); "
                 f"statuses {dict(sorted(stats.statuses.items()))}")
    lines.append(f"cache {dict(sorted(stats.cache.items()))}; hit ratio "
                 f"{hits / answered if answered else 0:.2f} (hit + shared over all answers)")
    lines += [f"  error: {e}" for e in stats.errors[:10]]
    return "\n".join(lines)


async def run(url: str, seconds: float, clients: int, api_key: str | None, seed: int) -> Stats:
    ops = post_operations()
    headers = {"Authorization": f"Bearer {api_key}"} if api_key else {}
    stats = Stats()
    history: list[tuple[str, str, dict[str, Any]]] = []
    limits = httpx.Limits(max_connections=clients, max_keepalive_connections=clients)
    async with httpx.AsyncClient(base_url=url, headers=headers, timeout=300,
                                 limits=limits) as http:
        r = await http.get("/readyz")
        r.raise_for_status()
        stop_at = time.monotonic() + seconds
        await asyncio.gather(*(client_loop(http, ops, seed + i, stop_at, stats, history)
                               for i in range(clients)))
    return stats


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=30.0, help="duration (default 30)")
    parser.add_argument("--quick", action="store_true", help="5 s run")
    parser.add_argument("--clients", type=int, default=8, help="concurrent clients (default 8)")
    parser.add_argument("--url", help="an already running server (default: start one)")
    parser.add_argument("--api-key", help="bearer key for --url")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--pid", type=int, help="server process id for --url (memory figures)")
    parser.add_argument("--settle", type=float, default=5.0,
                        help="seconds idle before the after-burst RSS (default 5)")
    args = parser.parse_args(argv)
    seconds = 5.0 if args.quick else args.seconds

    server: AbstractContextManager[Any]
    if args.url:
        server = nullcontext(None)
    else:
        server = live_server({"ZW_MAX_GRID_CELLS": str(LARGE_N * LARGE_N),
                              "ZW_MAX_POINTS": "2000", "ZW_LOG_LEVEL": "WARNING"})
    with server as live:
        url = args.url or live.url
        pid = args.pid or (live.process.pid if live else None)
        print(f"target {url}; operations {sorted(post_operations())} + get_task")
        start_rss = _memory(pid)
        start = time.monotonic()
        stats = asyncio.run(run(url, seconds, args.clients, args.api_key, args.seed))
        elapsed = time.monotonic() - start
        time.sleep(args.settle)
        end_mem = _memory(pid)
    print(report(stats, elapsed, args.clients))
    if pid and start_rss and end_mem:
        print(f"server RSS: start {start_rss['VmRSS'] / 2**20:.0f} MiB, "
              f"peak {end_mem['VmHWM'] / 2**20:.0f} MiB, "
              f"after burst (+{args.settle:g} s idle) {end_mem['VmRSS'] / 2**20:.0f} MiB")
    return 1 if len(stats.errors) > stats.statuses[503] else 0


def _memory(pid: int | None) -> dict[str, int] | None:
    """VmRSS and VmHWM (peak) of the server process, in bytes (Linux /proc)."""
    if not pid:
        return None
    try:
        text = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return None
    out = {}
    for line in text.splitlines():
        key, _, value = line.partition(":")
        if key in ("VmRSS", "VmHWM"):
            out[key] = int(value.split()[0]) * 1024
    return out


if __name__ == "__main__":
    sys.exit(main())
