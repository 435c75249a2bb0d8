"""Task stores: where results live under their task id.

The embedded store (diskcache, a size-bounded SQLite-backed cache under
``ZW_DATA_DIR``) survives restarts; the Redis store lets replicas share work.
A store that fails never fails the request: the result is computed anyway and
the store reports itself degraded until it answers again.
"""

from __future__ import annotations

import logging
import threading
import time
from pathlib import Path
from typing import Protocol

log = logging.getLogger("zwplan.store")


class TaskStore(Protocol):
    kind: str

    def get(self, key: str) -> bytes | None: ...
    def put(self, key: str, value: bytes) -> None: ...
    def health(self) -> tuple[str, str]: ...  # ("ok" | "degraded" | "down", detail)
    def close(self) -> None: ...


class DiskStore:
    """Embedded store: diskcache with a size bound and least-recently-used eviction."""

    kind = "embedded"

    def __init__(self, directory: Path, max_bytes: int, ttl_seconds: int) -> None:
        import diskcache

        directory.mkdir(parents=True, exist_ok=True)
        self._ttl = ttl_seconds
        self._cache = diskcache.Cache(str(directory / "tasks"), size_limit=max_bytes,
                                      eviction_policy="least-recently-used")

    def get(self, key: str) -> bytes | None:
        # A failing store (disk full, database locked past its timeout, a corrupt
        # file) must not fail the request: it is a miss, and /readyz reports it.
        try:
            value = self._cache.get(key)
        except Exception as exc:
            log.warning("embedded store read failed: %s", type(exc).__name__)
            return None
        return value if isinstance(value, bytes) else None

    def put(self, key: str, value: bytes) -> None:
        try:
            self._cache.set(key, value, expire=self._ttl)
        except Exception as exc:
            log.warning("embedded store write failed: %s", type(exc).__name__)

    def health(self) -> tuple[str, str]:
        try:
            self._cache.set("__readyz__", b"1", expire=60)
            ok = self._cache.get("__readyz__") == b"1"
        except Exception as exc:  # the store is broken: report, do not raise
            return "down", f"embedded store failed: {type(exc).__name__}"
        return ("ok", "embedded store") if ok else ("down", "embedded store lost a write")

    def close(self) -> None:
        self._cache.close()


class RedisStore:
    """Redis store with a circuit breaker: while Redis is unreachable, calls skip
    it for ``retry_seconds`` instead of waiting on a timeout every request."""

    kind = "redis"

    def __init__(self, url: str, ttl_seconds: int, retry_seconds: float = 2.0) -> None:
        import redis

        self._redis = redis.Redis.from_url(url, socket_timeout=0.5, socket_connect_timeout=0.5,
                                           health_check_interval=0)
        self._ttl = ttl_seconds
        self._retry = retry_seconds
        self._down_until = 0.0
        self._last_error = ""
        self._lock = threading.Lock()

    def _available(self) -> bool:
        return time.monotonic() >= self._down_until

    def _failed(self, exc: Exception) -> None:
        with self._lock:
            if self._available():
                log.warning("redis unavailable: %s", type(exc).__name__)
            self._down_until = time.monotonic() + self._retry
            self._last_error = type(exc).__name__

    def get(self, key: str) -> bytes | None:
        if not self._available():
            return None
        try:
            value = self._redis.get("zw:task:" + key)
        except Exception as exc:
            self._failed(exc)
            return None
        return value if isinstance(value, bytes) else None

    #: Results larger than this are not shared through Redis: one such write can
    #: outlast the socket timeout and would trip the breaker for every request.
    max_item_bytes = 32 << 20

    def put(self, key: str, value: bytes) -> None:
        if not self._available() or len(value) > self.max_item_bytes:
            return
        try:
            self._redis.set("zw:task:" + key, value, ex=self._ttl)
        except Exception as exc:
            self._failed(exc)

    def health(self) -> tuple[str, str]:
        try:
            self._redis.ping()
        except Exception as exc:
            self._failed(exc)
            return "degraded", f"redis unreachable ({self._last_error}); computing without cache"
        self._down_until = 0.0
        return "ok", "redis"

    def close(self) -> None:
        self._redis.close()


def open_store(cache_url: str | None, data_dir: Path, max_bytes: int, ttl: int) -> TaskStore:
    if cache_url:
        return RedisStore(cache_url, ttl)
    return DiskStore(data_dir, max_bytes, ttl)
