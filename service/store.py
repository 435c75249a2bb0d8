"""Task stores: where results live under their task id.

The embedded store (diskcache, a size-bounded SQLite-backed cache under
``ZW_DATA_DIR``) survives restarts; the Redis store lets replicas share work.
A store that fails never fails the request: the result is computed anyway and
the store reports itself degraded until it answers again.
"""

from __future__ import annotations

import contextlib
import fcntl
import logging
import os
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Protocol

log = logging.getLogger("zwplan.store")


class TaskStore(Protocol):
    kind: str

    def get(self, key: str) -> bytes | None: ...
    def put(self, key: str, value: bytes) -> None: ...
    # Task state documents (asynchronous tasks): small JSON, shared like results.
    def get_state(self, key: str) -> bytes | None: ...
    def put_state(self, key: str, value: bytes, ttl_seconds: int) -> None: ...
    def health(self) -> tuple[str, str]: ...  # ("ok" | "degraded" | "down", detail)
    def close(self) -> None: ...


#: SQLite's write-ahead log is checkpointed every this many pages and cut back to
#: at most WAL_BYTES after each checkpoint; reads write too (access times).
WAL_PAGES = 256
WAL_BYTES = WAL_PAGES * 4096
#: Room kept for SQLite's own files beyond its database pages (the log at its
#: largest, the shared-memory index, one transaction's growth), so the bound
#: holds for the whole directory whatever reads happen between writes.
SQLITE_RESERVE_BYTES = WAL_BYTES + (32 << 10) + (256 << 10)


def directory_bytes(directory: Path) -> int:
    """Apparent size of every file under ``directory`` (what the bound is about)."""
    total = 0
    for root, _dirs, files in os.walk(directory):
        for name in files:
            with contextlib.suppress(FileNotFoundError):
                total += os.stat(os.path.join(root, name)).st_size
    return total


class DiskStore:
    """Embedded store: diskcache with least-recently-used eviction and a hard size bound.

    diskcache evicts at most ``cull_limit`` entries after a write, so large results
    after many small ones outgrew its limit several times over. Here eviction runs
    before each write, until the directory (SQLite database, its log and the value
    files) leaves room for the new entry: the store stays within ``max_bytes`` at
    every moment, or within one entry of it when that entry alone is larger. Writes
    are serialised by an ``flock`` on the directory, so several server processes
    sharing it (uvicorn ``--workers``) keep the bound too.

    diskcache writes a value's file before committing its row: a process killed in
    between leaves a file no row names. Such a file is never served (reads go
    through the rows) and is removed when a store opens.
    """

    kind = "embedded"

    def __init__(self, directory: Path, max_bytes: int, ttl_seconds: int) -> None:
        import diskcache

        self._dir = directory / "tasks"
        self._dir.mkdir(parents=True, exist_ok=True)
        self._ttl = ttl_seconds
        self._max = max_bytes
        self._lock = threading.Lock()
        self._lock_file = directory / "tasks.lock"
        # cull_limit=0: no eviction inside set(); put() evicts first, completely
        # A bounded write-ahead log, cut back at each checkpoint: it counts in the bound.
        self._cache = diskcache.Cache(str(self._dir), size_limit=max_bytes, cull_limit=0,
                                      eviction_policy="least-recently-used",
                                      sqlite_wal_autocheckpoint=WAL_PAGES,
                                      sqlite_journal_size_limit=WAL_BYTES)
        with self._exclusive():
            removed = self._remove_orphans()
        if removed:
            log.warning("embedded store: removed %d leftover files of interrupted writes",
                        removed)

    @contextlib.contextmanager
    def _exclusive(self) -> Iterator[None]:
        with self._lock, open(self._lock_file, "a+b") as fh:
            fcntl.flock(fh, fcntl.LOCK_EX)
            try:
                yield
            finally:
                fcntl.flock(fh, fcntl.LOCK_UN)

    def _remove_orphans(self) -> int:
        """Delete value files that no row names (leftovers of a killed write)."""
        named = {row[0] for row in self._cache._sql(
            "SELECT filename FROM Cache WHERE filename IS NOT NULL").fetchall()}
        removed = 0
        for root, _dirs, files in os.walk(self._dir):
            for name in files:
                path = Path(root, name)
                if path.suffix != ".val":
                    continue  # the database and its log
                if path.relative_to(self._dir).as_posix() not in named:
                    with contextlib.suppress(FileNotFoundError):
                        path.unlink()
                        removed += 1
        return removed

    def _db_lag(self) -> int:
        """Bytes of the database file beyond its live pages: freed pages stay in the
        file until a checkpoint cuts it back, and volume() does not see them."""
        try:
            on_disk = (self._dir / "cache.db").stat().st_size
        except FileNotFoundError:
            return 0
        ((pages,),) = self._cache._sql("PRAGMA page_count").fetchall()
        return max(0, on_disk - pages * self._cache._page_size)

    def _make_room(self, size: int) -> None:
        # volume() counts the database pages and the value files; the log and the
        # shared-memory index are reserved at their largest, the file's lag measured.
        target = self._max - size - SQLITE_RESERVE_BYTES - self._db_lag()
        # cull() evicts down to the size_limit attribute; set here, not persisted
        # (reset() would write it to the database on every put)
        self._cache.size_limit = max(0, target)
        self._cache.cull(retry=True)

    def get(self, key: str) -> bytes | None:
        # A failing store (disk full, database locked past its timeout, a corrupt
        # file) must not fail the request: it is a miss, and /readyz reports it.
        try:
            value = self._cache.get(key)
        except Exception as exc:
            log.warning("embedded store read failed: %s", type(exc).__name__)
            return None
        return value if isinstance(value, bytes) else None

    def _put(self, key: str, value: bytes, ttl: int) -> None:
        try:
            with self._exclusive():
                self._make_room(len(value))
                self._cache.set(key, value, expire=ttl)
        except Exception as exc:
            log.warning("embedded store write failed: %s", type(exc).__name__)

    def put(self, key: str, value: bytes) -> None:
        self._put(key, value, self._ttl)

    def get_state(self, key: str) -> bytes | None:
        return self.get("state:" + key)

    def put_state(self, key: str, value: bytes, ttl_seconds: int) -> None:
        self._put("state:" + key, value, ttl_seconds)

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

    def get_state(self, key: str) -> bytes | None:
        if not self._available():
            return None
        try:
            value = self._redis.get("zw:state:" + key)
        except Exception as exc:
            self._failed(exc)
            return None
        return value if isinstance(value, bytes) else None

    def put_state(self, key: str, value: bytes, ttl_seconds: int) -> None:
        if not self._available():
            return
        try:
            self._redis.set("zw:state:" + key, value, ex=ttl_seconds)
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
