"""Benchmark: lifted Haar and single-knot MRR against pywt.wavedec2.

Run as ``.venv/bin/python bench/bench_mrr.py`` (``--quick`` for a fast mode).

For each grid (1024 x 1024 and 4096 x 4096 float64, a random-walk surface)
times, in the same run, best of N (each case runs 3 times back to back per
round, the rounds round-robin so machine noise hits every case alike):

- ``analyse(z, "haar")``: the lifted Haar MRR, all levels (also held to one thread);
- ``analyse(z, "single_knot")``: the lifted single-knot MRR, all levels;
- ``pywt.wavedec2(z, "haar")``: PyWavelets, all levels (the reference);
- a plain numpy 2 x 2 max-pool pyramid (only the block maxima; a yardstick).

and prints each time and pywt's time divided by it (``x`` = times faster than
pywt). Targets (issue): lifted Haar >= 15x, lifted single-knot >= 3x.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pywt

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from zwcore.mrr import _pyramid
from zwcore.mrr.wavelets import analyse

TARGETS = {"lifted haar": 15.0, "lifted single-knot": 3.0}


def max_pool_pyramid(z: np.ndarray) -> list[np.ndarray]:
    """Block maxima by strided np.maximum, level by level (even sides only)."""
    out = []
    a = z
    while a.shape[0] > 1 and a.shape[0] % 2 == 0 and a.shape[1] % 2 == 0:
        a = np.maximum(np.maximum(a[0::2, 0::2], a[1::2, 0::2]),
                       np.maximum(a[0::2, 1::2], a[1::2, 1::2]))
        out.append(a)
    return out


def surface(n: int) -> np.ndarray:
    rng = np.random.default_rng(n)
    return np.ascontiguousarray(rng.normal(size=(n, n)).cumsum(axis=0).cumsum(axis=1) * 0.01)


def best_of(cases: dict[str, Callable[[], object]], rounds: int, block: int = 3,
            ) -> dict[str, float]:
    """Best wall time (s) of each case. Each round runs every case ``block``
    times back to back (steady state, as timeit does), and the rounds go
    round-robin so a noisy spell on a shared machine hits every case alike."""
    best = dict.fromkeys(cases, float("inf"))
    for _ in range(rounds):
        for name, fn in cases.items():
            for _ in range(block):
                t = time.perf_counter()
                fn()
                best[name] = min(best[name], time.perf_counter() - t)
    return best


def one_thread_haar(z: np.ndarray) -> object:
    """The lifted Haar MRR with the fast path held to one thread (what one core gives)."""
    saved = _pyramid.worker_count
    _pyramid.worker_count = lambda: 1
    try:
        return analyse(z, "haar")
    finally:
        _pyramid.worker_count = saved


def grid_rows(n: int, repeats: int) -> list[tuple[str, str, float, float]]:
    """``(grid, case, ms, pywt_ms / ms)`` for one grid size."""
    z = surface(n)
    cases: dict[str, Callable[[], object]] = {
        "lifted haar": lambda: analyse(z, "haar"),
        "lifted haar, one thread": lambda: one_thread_haar(z),
        "lifted single-knot": lambda: analyse(z, "single_knot"),
        "pywt.wavedec2 haar": lambda: pywt.wavedec2(z, "haar"),
        "numpy max-pool pyramid": lambda: max_pool_pyramid(z),
    }
    for fn in cases.values():  # warm up: imports, thread pool, allocator
        fn()
    best = best_of(cases, repeats)
    ref = best["pywt.wavedec2 haar"]
    return [(f"{n}x{n} f64", name, t * 1e3, ref / t) for name, t in best.items()]


def print_table(rows: list[tuple[str, str, float, float]]) -> None:
    print(f"{'grid':<14} {'case':<26} {'best ms':>9} {'vs pywt':>8}  target")
    for grid, name, ms, ratio in rows:
        target = TARGETS.get(name)
        verdict = "" if target is None else \
            f">= {target:g}x {'met' if ratio >= target else 'NOT met'}"
        print(f"{grid:<14} {name:<26} {ms:9.2f} {ratio:7.1f}x  {verdict}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repeats")
    parser.add_argument("--rounds", type=int, default=None,
                        help="round-robin rounds (each runs every case 3 times)")
    args = parser.parse_args()
    small = args.rounds or (2 if args.quick else 8)
    large = args.rounds or (1 if args.quick else 3)

    # (POST /v1/mrr end to end is timed by bench_http.py)
    print_table(grid_rows(1024, small) + grid_rows(4096, large))


if __name__ == "__main__":
    main()
