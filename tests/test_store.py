"""The embedded task store: size bound with least-recently-used eviction, TTL, restarts."""

from __future__ import annotations

import signal
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

from hypothesis import given, settings
from hypothesis import strategies as st

from service.store import DiskStore, directory_bytes

VALUE = 64 * 1024  # large enough that diskcache keeps values as files: exact accounting


def test_size_bound_evicts_least_recently_used(tmp_path: Path) -> None:
    limit = 2 << 20
    store = DiskStore(tmp_path, max_bytes=limit, ttl_seconds=3600)
    try:
        store.put("keep", b"k" * VALUE)
        for i in range(96):  # three times the bound
            store.put(f"t{i}", bytes([i]) * VALUE)
            assert store.get("keep") is not None  # used all along: never the one evicted
        volume = store._cache.volume()
        # over the bound by at most one value and the index database
        assert volume <= limit + VALUE + 256 * 1024, volume
        kept = [i for i in range(96) if store.get(f"t{i}") is not None]
        assert 0 < len(kept) < 96
        assert kept == list(range(96 - len(kept), 96)), "evicted other than the oldest"
        assert store.get("t95") == bytes([95]) * VALUE
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


def _sizes_bound(tmp_path: Path, limit: int, sizes: list[int]) -> None:
    """Write entries of these sizes; after every write, and sampled during the writes,
    the store's directory (measured by walking it, not by the store's own accounting)
    stays within the limit plus the largest entry written so far."""
    store = DiskStore(tmp_path, max_bytes=limit, ttl_seconds=3600)
    worst: list[tuple[int, int]] = []
    done = threading.Event()
    largest = [0]

    def sample() -> None:
        while not done.is_set():
            worst.append((directory_bytes(tmp_path / "tasks"), largest[0]))

    sampler = threading.Thread(target=sample)
    sampler.start()
    try:
        for i, size in enumerate(sizes):
            largest[0] = max(largest[0], size)
            value = bytes([i % 251]) * size
            store.put(f"k{i}", value)
            on_disk = directory_bytes(tmp_path / "tasks")
            assert on_disk <= limit + size, (i, size, on_disk)
            assert store.get(f"k{i}") == value  # the newest entry is always kept
    finally:
        done.set()
        sampler.join()
        store.close()
    for measured, big in worst:
        assert measured <= limit + big, (measured, big)


def test_small_then_large_results_stay_within_the_bound(tmp_path: Path) -> None:
    # Many small results (inline in SQLite and small files), then large ones: diskcache
    # alone evicted ten entries per write and ended at several times its limit.
    limit = 4 << 20
    _sizes_bound(tmp_path, limit, [3000] * 300 + [40_000] * 60 + [1_500_000] * 8
                 + [6 << 20] + [100] * 20)


@settings(max_examples=12, deadline=None)
@given(st.lists(st.sampled_from([50, 5_000, 40_000, 300_000, 1_200_000, 3_000_000]),
                min_size=1, max_size=25))
def test_any_sequence_of_sizes_stays_within_the_bound(sizes: list[int]) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        _sizes_bound(Path(tmp), 2 << 20, sizes)


_PARTIAL_WRITER = """
import os, sys, time
sys.path.insert(0, sys.argv[2])
from pathlib import Path
from service.store import DiskStore
store = DiskStore(Path(sys.argv[1]), max_bytes=64 << 20, ttl_seconds=3600)
store.put("whole", b"w" * 100_000)
class Stalling:
    # a value that arrives slowly: the file is half written when the parent kills us
    def __init__(self):
        self.sent = 0
    def read(self, n):
        if self.sent < 3:
            self.sent += 1
            return b"p" * 1_000_000
        print("stalled", flush=True)
        time.sleep(600)
        return b""
store._cache.set("partial", Stalling(), read=True)
"""


def test_leftovers_of_a_killed_write_are_removed_and_never_served(tmp_path: Path) -> None:
    root = Path(__file__).resolve().parents[1]
    child = subprocess.Popen([sys.executable, "-c", _PARTIAL_WRITER, str(tmp_path), str(root)],
                             stdout=subprocess.PIPE)
    try:
        assert child.stdout is not None
        assert child.stdout.readline().strip() == b"stalled"
    finally:
        child.send_signal(signal.SIGKILL)
        child.wait(timeout=10)
    vals = sorted(p.stat().st_size for p in (tmp_path / "tasks").rglob("*.val"))
    assert vals == [100_000, 3_000_000]  # the complete entry and the torn one
    store = DiskStore(tmp_path, max_bytes=64 << 20, ttl_seconds=3600)
    try:
        assert store.get("partial") is None
        assert store.get("whole") == b"w" * 100_000
        left = [p.stat().st_size for p in (tmp_path / "tasks").rglob("*.val")]
        assert left == [100_000]
    finally:
        store.close()
