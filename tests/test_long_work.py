"""Long work: the compute deadline stops the work and frees its worker; arc fitting and
grid work have separate capacity, so a flood of one never starves the other."""

from __future__ import annotations

import asyncio
import concurrent.futures
import math
import os
import time

import httpx
import numpy as np
import pytest

from service.compute import ComputePool
from service.problems import Problem
from tests.live_server import live_server
from tests.test_compute import _gone


def _python_forever() -> None:
    # pure Python (like the planners' loops between numpy calls): interruptible
    while True:
        sum(range(1000))


def test_a_thread_past_its_deadline_is_stopped_and_its_worker_freed() -> None:
    async def scenario() -> None:
        pool = ComputePool(1, 0, timeout=0.5)  # one thread, no queue
        try:
            start = time.monotonic()
            with pytest.raises(Problem) as late:
                await pool.run("op", _python_forever)
            assert late.value.status == 503 and late.value.kind == "timeout"
            assert time.monotonic() - start < 5
            await asyncio.sleep(0.05)
            assert pool.busy == 0
            # the single thread is free again: a short job runs in it
            assert await pool.run("op", math.factorial, 5) == 120
        finally:
            pool.shutdown()

    asyncio.run(scenario())


def test_a_process_past_its_deadline_is_terminated_and_replaced() -> None:
    async def scenario() -> tuple[int, int]:
        pool = ComputePool(1, 0, processes=1, timeout=1.0)
        try:
            first = await pool.run("op", os.getpid, in_process=True)
            with pytest.raises(Problem) as late:
                await pool.run("op", time.sleep, 60, in_process=True)
            assert late.value.status == 503 and late.value.kind == "timeout"
            second = await pool.run("op", os.getpid, in_process=True)
            assert pool.busy == 0
            return first, second
        finally:
            pool.shutdown()

    start = time.monotonic()
    first, second = asyncio.run(scenario())
    assert time.monotonic() - start < 20
    assert first != second
    assert _gone(first, within=10), "the worker past its deadline still runs"


def _slow_polygon(n: int, seed: int) -> list[list[float]]:
    """A noisy sine at a fifth of the noise as tolerance: still seconds of fitting
    (issue 15 made the coarse polygons of issue 14 fast, so they no longer hold a
    worker, and its compiled kernels made the sine at the noise's own tolerance ten
    times faster; here the chain follows the noise, a segment every point or two:
    ``100 n`` points; n = 40: 3,200 segments, 3 s of fitting on the 2-core test machine;
    n = 80: about 10 s)."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 12.0 * np.pi, 100 * n)
    pts = np.c_[5.0 * t, 10.0 * np.sin(t)] + rng.uniform(-0.05, 0.05, (len(t), 2))
    return [[float(x), float(y)] for x, y in pts]


SLOW_TOLERANCE = 0.01


TINY_CONTOUR = {"grid": {"x0": 0, "y0": 0, "dx": 1, "dy": 1,
                         "z": [[0, 0, 0, 0], [0, 1, 1, 0], [0, 1, 1, 0], [0, 0, 0, 0]]}}


def test_slow_arc_fits_neither_starve_grid_work_nor_outlive_the_deadline() -> None:
    env = {"ZW_WORKERS": "1", "ZW_PROCESS_WORKERS": "1", "ZW_MAX_PENDING": "1",
           "ZW_COMPUTE_TIMEOUT_SECONDS": "3"}
    with live_server(env) as server, concurrent.futures.ThreadPoolExecutor(5) as ex:
        def post_arcs(seed: int) -> httpx.Response:
            body = {"points": _slow_polygon(80, seed), "tolerance": SLOW_TOLERANCE}
            return httpx.post(server.url + "/v1/arcs", json=body, timeout=60)

        flood = [ex.submit(post_arcs, seed) for seed in range(4)]
        time.sleep(1.0)  # one fit running, one queued, the rest shed
        start = time.monotonic()
        tiny = httpx.post(server.url + "/v1/plans/contour", json=TINY_CONTOUR, timeout=30)
        tiny_seconds = time.monotonic() - start
        assert tiny.status_code == 200, tiny.text
        assert tiny.json()["stages"]
        assert tiny_seconds < 2.5, f"grid request waited {tiny_seconds:.2f} s behind arc fits"

        answers = [f.result() for f in flood]
        kinds = sorted(r.json()["type"].rsplit("/", 1)[-1] for r in answers)
        assert all(r.status_code == 503 for r in answers), [r.text for r in answers]
        assert all(r.headers["content-type"].startswith("application/problem+json")
                   for r in answers)
        # capacity 2 (one worker, one queued): those two ran into the deadline
        assert kinds == ["busy", "busy", "timeout", "timeout"], kinds
        # the worker stopped at the deadline was replaced: a quick fit is served
        ok = httpx.post(server.url + "/v1/arcs", timeout=30,
                        json={"points": [[0, 0], [10, 0], [20, 1]], "tolerance": 0.1})
        assert ok.status_code == 200, ok.text
        assert ok.json()["summary"]["n_segments"] >= 1
