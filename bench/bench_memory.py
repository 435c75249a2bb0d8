"""Memory after a burst of large plans: what malloc_trim hands back.

    .venv/bin/python bench/bench_memory.py [--n 2048] [--burst 4] [--threads 2]

Runs a burst of scan-line plans with models on an n² part in the compute pool's
threads (as the service does), encodes each result as the service stores it, drops
them, and prints the process's RSS: at start, at the peak, after the burst, and
after ``malloc_trim(0)`` (what the compute pool calls after each large request).
The difference of the last two is heap that glibc kept in its arenas.
"""

from __future__ import annotations

import argparse
import gc
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from service.compute import malloc_trim  # noqa: E402
from service.routers.plans import scanline_result  # noqa: E402
from service.tasks import encode_result  # noqa: E402
from zwcore import ZMap, default_tools  # noqa: E402


def rss() -> tuple[int, int]:
    """(VmRSS, VmHWM) in MiB."""
    out = {}
    for line in Path("/proc/self/status").read_text().splitlines():
        key, _, value = line.partition(":")
        if key in ("VmRSS", "VmHWM"):
            out[key] = int(value.split()[0]) // 1024
    return out["VmRSS"], out["VmHWM"]


def plan(n: int, seed: int) -> int:
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:n, 0:n] / n
    z = 10 - 4 * np.exp(-((x - rng.uniform(.3, .7)) ** 2 + (y - .5) ** 2) / .05) \
        + 0.3 * np.sin(20 * x) * np.cos(17 * y)
    zmap = ZMap(z, 0, 0, 0.05, 0.05)
    body, _ms = encode_result("t", "plan_scanline", scanline_result,
                              (zmap, list(default_tools("ball")), 0.05, None, True))
    return len(body)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=2048)
    parser.add_argument("--burst", type=int, default=4)
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args(argv)
    start, _ = rss()
    with ThreadPoolExecutor(args.threads) as pool:
        sizes = list(pool.map(lambda s: plan(args.n, s), range(args.burst)))
    gc.collect()
    after, peak = rss()
    t0 = time.perf_counter()
    malloc_trim()
    trim_ms = (time.perf_counter() - t0) * 1000
    trimmed, _ = rss()
    print(f"{args.burst} scan-line plans with models, {args.n}² in {args.threads} threads "
          f"(results {sum(sizes) / 2**20:.0f} MiB in all)")
    print(f"RSS MiB: start {start}, peak {peak}, after burst {after}, "
          f"after malloc_trim {trimmed} (returned {after - trimmed}; "
          f"the trim took {trim_ms:.1f} ms)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
