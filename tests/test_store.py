"""The embedded task store: size bound with least-recently-used eviction, TTL, restarts."""

from __future__ import annotations

from pathlib import Path

from service.store import DiskStore

VALUE = 64 * 1024  # large enough that diskcache keeps values as files: exact accounting


def test_size_bound_evicts_least_recently_used(tmp_path: Path) -> None:
    limit = 1 << 20
    store = DiskStore(tmp_path, max_bytes=limit, ttl_seconds=3600)
    try:
        store.put("keep", b"k" * VALUE)
        for i in range(48):  # three times the bound
            store.put(f"t{i}", bytes([i]) * VALUE)
            assert store.get("keep") is not None  # used all along: never the one evicted
        volume = store._cache.volume()
        # over the bound by at most one value and the index database
        assert volume <= limit + VALUE + 256 * 1024, volume
        kept = [i for i in range(48) if store.get(f"t{i}") is not None]
        assert 0 < len(kept) < 48
        assert kept == list(range(48 - len(kept), 48)), "evicted other than the oldest"
        assert store.get("t47") == bytes([47]) * VALUE
    finally:
        store.close()


def test_entries_survive_a_restart_and_expire(tmp_path: Path) -> None:
    store = DiskStore(tmp_path, max_bytes=1 << 20, ttl_seconds=3600)
    store.put("a", b"result")
    store.close()
    again = DiskStore(tmp_path, max_bytes=1 << 20, ttl_seconds=3600)
    try:
        assert again.get("a") == b"result"
        assert again.get("missing") is None
        expire_time = again._cache.get("a", expire_time=True)[1]
        assert expire_time is not None  # entries carry ZW_CACHE_TTL_SECONDS
    finally:
        again.close()
