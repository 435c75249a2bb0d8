"""Asynchronous tasks: ``Prefer: respond-async`` gives 202 and a Location; the task's
state is pending/running then done (or failed, with the problem); a repeat is a hit."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from fastapi.testclient import TestClient

from tests.conftest import make_client

ASYNC = {"Prefer": "respond-async"}


def _grid(n: int, seed: int) -> dict[str, object]:
    rng = np.random.default_rng(seed)
    z = (10 + rng.uniform(-1, 1, (n, n))).round(3)
    return {"x0": 0, "y0": 0, "dx": 1, "dy": 1, "z": z.tolist()}


def _poll_done(client: TestClient, location: str, within: float = 60) -> dict:  # type: ignore[type-arg]
    deadline = time.monotonic() + within
    seen = []
    while time.monotonic() < deadline:
        r = client.get(location + "/status")
        assert r.status_code == 200, r.text
        state = r.json()
        seen.append(state["status"])
        assert 0 <= state["progress"] <= 1
        if state["status"] in ("done", "failed"):
            return {"final": state, "seen": seen}
        time.sleep(0.02)
    raise AssertionError(f"task not finished in {within} s: {seen[-5:]}")


def test_respond_async_gives_202_then_the_same_result_as_a_synchronous_call(
        tmp_path: Path) -> None:
    body = {"grid": _grid(64, 1), "tolerance": 0.05, "include_models": True}
    with make_client(tmp_path) as client:
        accepted = client.post("/v1/plans/scanline", json=body, headers=ASYNC)
        assert accepted.status_code == 202, accepted.text
        state = accepted.json()
        tid = state["task_id"]
        assert accepted.headers["location"] == f"/v1/tasks/{tid}"
        assert state["status"] == "pending" and state["progress"] == 0
        assert state["operation"] == "plan_scanline"
        # another replica sharing the store answers for the task too
        with make_client(tmp_path) as replica:
            polled = _poll_done(replica, accepted.headers["location"])
        assert polled["final"]["status"] == "done" and polled["final"]["progress"] == 1
        result = client.get(f"/v1/tasks/{tid}")
        assert result.status_code == 200 and result.json()["task_id"] == tid
        # the same request, synchronously: a cache hit with the very same body
        again = client.post("/v1/plans/scanline", json=body, headers=ASYNC)
        assert again.status_code == 200 and again.headers["x-cache"] == "hit"
    # independently: a fresh server computing it synchronously gives the same result
    with make_client(tmp_path / "fresh") as fresh:
        sync = fresh.post("/v1/plans/scanline", json=body)
        assert sync.status_code == 200 and sync.headers["x-cache"] == "miss"
        assert sync.json() == result.json()


def test_a_running_task_reports_202_with_its_state(tmp_path: Path) -> None:
    # a slow arc fit (zigzag polygon) keeps the task running while we look
    from tests.test_long_work import SLOW_TOLERANCE, _slow_polygon

    body = {"points": _slow_polygon(40, 0), "tolerance": SLOW_TOLERANCE}
    with make_client(tmp_path, process_workers=1) as client:
        accepted = client.post("/v1/arcs", json=body, headers=ASYNC)
        assert accepted.status_code == 202
        location = accepted.headers["location"]
        time.sleep(0.5)
        r = client.get(location)
        assert r.status_code == 202, r.text[:300]
        assert r.json()["status"] in ("pending", "running")
        assert r.headers["retry-after"] and r.headers["location"] == location
        # asking again while it runs does not start a second computation
        twice = client.post("/v1/arcs", json=body, headers=ASYNC)
        assert twice.status_code == 202 and twice.json()["created"] == r.json()["created"]


def test_a_failed_task_reports_failed_and_the_problem(tmp_path: Path) -> None:
    from tests.test_long_work import SLOW_TOLERANCE, _slow_polygon

    body = {"points": _slow_polygon(40, 1), "tolerance": SLOW_TOLERANCE}
    with make_client(tmp_path, process_workers=1, compute_timeout_seconds=0.5) as client:
        accepted = client.post("/v1/arcs", json=body, headers=ASYNC)
        assert accepted.status_code == 202
        location = accepted.headers["location"]
        final = _poll_done(client, location)["final"]
        assert final["status"] == "failed"
        assert final["error"]["status"] == 503 and final["error"]["type"].endswith("/timeout")
        r = client.get(location)
        assert r.status_code == 503
        assert r.headers["content-type"].startswith("application/problem+json")
        assert r.json()["type"].endswith("/timeout")


def test_unknown_tasks_are_404_on_both_paths(tmp_path: Path) -> None:
    with make_client(tmp_path) as client:
        for path in ("", "/status"):
            r = client.get("/v1/tasks/" + "0" * 64 + path)
            assert r.status_code == 404
            assert r.json()["type"].endswith("/unknown-task")
