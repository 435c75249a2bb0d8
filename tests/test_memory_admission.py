"""Admission by memory: a request whose estimated peak would pass ZW_MEMORY_BUDGET_BYTES
waits for room, then is shed with a 503 problem and Retry-After; the budget's default
follows the container's memory limit."""

from __future__ import annotations

import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from service.routers import mrr as mrr_router
from tests.conftest import make_client
from tests.test_observability import (
    gated,  # noqa: F401 - the fixture
    grid,
)

PROBLEM = "application/problem+json"


def test_a_request_larger_than_the_whole_budget_is_shed_at_once(tmp_path: Path) -> None:
    n = 40  # 1600 nodes: about 1600 * MRR_BYTES estimated
    need = n * n * mrr_router.MRR_BYTES
    with make_client(tmp_path, memory_budget_bytes=need - 1, memory_wait_seconds=30) as c:
        start = time.monotonic()
        r = c.post("/v1/mrr", json=grid(1.0, n))
        assert time.monotonic() - start < 10  # not the 30 s wait: it can never fit
        assert r.status_code == 503 and r.headers["content-type"] == PROBLEM
        assert int(r.headers["retry-after"]) > 0
        assert r.json()["type"].endswith("/memory")
        # a smaller grid fits and is computed
        ok = c.post("/v1/mrr", json=grid(1.0, 20))
        assert ok.status_code == 200, ok.text
        assert len(ok.json()["levels"]) >= 1


def test_requests_wait_for_room_then_are_shed(
        tmp_path: Path, gated: tuple[threading.Event, threading.Event]) -> None:  # noqa: F811
    entered, release = gated
    one = 30 * 30 * mrr_router.MRR_BYTES  # the budget holds one such request at a time
    with make_client(tmp_path, workers=2, memory_budget_bytes=one + one // 2,
                     memory_wait_seconds=0.5) as c, ThreadPoolExecutor(2) as threads:
        first = threads.submit(c.post, "/v1/mrr", json=grid(1.0, 30))
        assert entered.wait(10)
        start = time.monotonic()
        second = c.post("/v1/mrr", json=grid(2.0, 30))  # a different task: no sharing
        waited = time.monotonic() - start
        assert second.status_code == 503 and second.headers["retry-after"]
        assert second.json()["type"].endswith("/busy")
        assert waited >= 0.45  # it waited for room before giving up
        # a waiting request gets in as soon as the room is freed
        third = threads.submit(c.post, "/v1/mrr", json=grid(3.0, 30))
        time.sleep(0.2)
        release.set()
        assert first.result(30).status_code == 200
        assert third.result(30).status_code == 200


@pytest.mark.parametrize(("files", "machine", "expected"), [
    ({"memory.max": "4294967296\n"}, 16 << 30, 3 << 30),      # cgroup v2, 4 GiB limit
    ({"memory.max": "max\n"}, 16 << 30, 12 << 30),            # v2, unlimited: the machine
    ({"memory/memory.limit_in_bytes": "2147483648\n"}, 16 << 30, (2 << 30) * 3 // 4),  # v1
    ({"memory/memory.limit_in_bytes": "9223372036854771712\n"}, 8 << 30, 6 << 30),  # v1 "none"
    ({}, 8 << 30, 6 << 30),
])
def test_memory_budget_default_follows_the_container(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, files: dict[str, str], machine: int,
        expected: int) -> None:
    from service import settings

    for name, text in files.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text)
    real = settings._cgroup_memory_limit
    monkeypatch.setattr(settings, "_cgroup_memory_limit", lambda: real(tmp_path))
    monkeypatch.setattr(settings, "_machine_memory", lambda: machine)
    assert settings._memory_budget() == expected
