"""Replicas share results through Redis, and survive losing it.

A real ``redis-server`` (Debian package) is started on a free 127.0.0.1 port
without persistence; the module skips where it is not installed.
"""

from __future__ import annotations

import shutil
import subprocess
import time
from collections.abc import Iterator
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from tests.live_server import free_port

REDIS_SERVER = shutil.which("redis-server")
pytestmark = pytest.mark.skipif(REDIS_SERVER is None, reason="redis-server is not installed")

redis = pytest.importorskip("redis")

TTL = 4321
RETRY_WINDOW = 2.0  # service.store.RedisStore's default retry_seconds


@dataclass
class RedisProc:
    port: int
    workdir: Path
    process: subprocess.Popen[bytes] | None = None

    @property
    def url(self) -> str:
        return f"redis://127.0.0.1:{self.port}/0"

    def start(self) -> None:
        assert REDIS_SERVER is not None
        self.process = subprocess.Popen(
            [REDIS_SERVER, "--port", str(self.port), "--bind", "127.0.0.1", "--save", "",
             "--appendonly", "no", "--dir", str(self.workdir), "--protected-mode", "yes"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        client = redis.Redis(host="127.0.0.1", port=self.port, socket_timeout=0.5)
        deadline = time.monotonic() + 10
        while True:
            try:
                if client.ping():
                    break
            except redis.exceptions.ConnectionError:
                if time.monotonic() > deadline or self.process.poll() is not None:
                    raise RuntimeError("redis-server did not start") from None
                time.sleep(0.05)
        client.close()

    def kill(self) -> None:
        if self.process is not None:
            self.process.kill()
            self.process.wait(timeout=10)
            self.process = None

    def client(self) -> Any:
        return redis.Redis(host="127.0.0.1", port=self.port, socket_timeout=1)


@pytest.fixture
def redis_server(tmp_path: Path) -> Iterator[RedisProc]:
    proc = RedisProc(port=free_port(), workdir=tmp_path)
    proc.start()
    try:
        yield proc
    finally:
        proc.kill()


def _apps(redis_url: str, tmp_path: Path) -> tuple[ExitStack, TestClient, TestClient]:
    from service.main import create_app
    from service.settings import Settings

    stack = ExitStack()
    clients = []
    for name in ("a", "b"):
        overrides: dict[str, Any] = {"cache_url": redis_url, "data_dir": tmp_path / name,
                                     "cache_ttl_seconds": TTL, "api_keys": "", "workers": 2,
                                     "max_pending": 4}
        settings = Settings(**overrides)
        clients.append(stack.enter_context(TestClient(create_app(settings))))
    return stack, clients[0], clients[1]


def _grid(seed: int) -> dict[str, Any]:
    z = [[float((i * 7 + k * 3 + seed) % 11) for k in range(8)] for i in range(8)]
    return {"grid": {"dx": 1.0, "dy": 1.0, "z": z}, "wavelet": "haar"}


def test_replicas_share_tasks_and_survive_redis_loss(redis_server: RedisProc,
                                                     tmp_path: Path) -> None:
    stack, a, b = _apps(redis_server.url, tmp_path)
    with stack:
        assert a.get("/readyz").json()["cache_kind"] == "redis"

        # Computed on A ...
        first = a.post("/v1/mrr", json=_grid(1))
        assert first.status_code == 200 and first.headers["x-cache"] == "miss"
        tid = first.json()["task_id"]
        # ... served by B, from Redis, in both ways of asking.
        shared = b.get(f"/v1/tasks/{tid}", params={"grid_encoding": "float64"})
        assert shared.status_code == 200 and shared.headers["x-cache"] == "hit"
        assert shared.json()["levels"] == first.json()["levels"]
        again = b.post("/v1/mrr", json=_grid(1))
        assert again.headers["x-cache"] == "hit" and again.json() == first.json()

        # The entry carries ZW_CACHE_TTL_SECONDS.
        rc = redis_server.client()
        ttl = rc.ttl(f"zw:task:{tid}")
        assert TTL - 30 <= ttl <= TTL, ttl
        rc.close()

        # Redis dies: requests still succeed, computed without the cache.
        redis_server.kill()
        for app in (a, b):
            start = time.monotonic()
            r = app.post("/v1/mrr", json=_grid(2))
            assert r.status_code == 200, r.text
            assert r.headers["x-cache"] == "miss"
            assert time.monotonic() - start < 5  # no long hang on the dead store
            ready = app.get("/readyz")
            assert ready.status_code == 200
            assert ready.json()["cache"] == "degraded" and ready.json()["status"] == "degraded"
        # A task only Redis held is gone, as a clean 404 problem, not a 5xx.
        lost = b.get(f"/v1/tasks/{tid}")
        assert lost.status_code == 404
        assert lost.headers["content-type"] == "application/problem+json"
        # The same request twice is recomputed: nothing is cached while Redis is down.
        assert a.post("/v1/mrr", json=_grid(2)).headers["x-cache"] == "miss"

        # Redis comes back on the same port: after the retry window, caching resumes.
        redis_server.start()
        time.sleep(RETRY_WINDOW + 0.2)
        r = a.post("/v1/mrr", json=_grid(3))
        assert r.status_code == 200 and r.headers["x-cache"] == "miss"
        tid3 = r.json()["task_id"]
        assert b.get(f"/v1/tasks/{tid3}").headers["x-cache"] == "hit"
        assert b.post("/v1/mrr", json=_grid(3)).headers["x-cache"] == "hit"
        for app in (a, b):
            ready = app.get("/readyz").json()
            assert ready["cache"] == "ok" and ready["status"] == "ok"
        rc = redis_server.client()
        assert TTL - 30 <= rc.ttl(f"zw:task:{tid3}") <= TTL
        rc.close()
