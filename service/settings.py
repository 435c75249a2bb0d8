"""Service settings, read from the environment with the ``ZW_`` prefix."""

from __future__ import annotations

import math
import os
from functools import lru_cache
from pathlib import Path

from pydantic import Field, field_validator
from pydantic_settings import BaseSettings, SettingsConfigDict


def _cgroup_cpu_limit(root: Path = Path("/sys/fs/cgroup")) -> float | None:
    """CPUs the container may use by its cgroup quota (``docker --cpus``, compose
    ``limits.cpus``), or None when unlimited or unknown. cgroup v2, then v1."""
    try:
        quota, period = (root / "cpu.max").read_text().split()[:2]
        return None if quota == "max" else int(quota) / int(period)
    except (OSError, ValueError):
        pass
    try:
        q = int((root / "cpu" / "cpu.cfs_quota_us").read_text())
        p = int((root / "cpu" / "cpu.cfs_period_us").read_text())
        return q / p if q > 0 and p > 0 else None
    except (OSError, ValueError):
        return None


def _cpu_count() -> int:
    """CPUs this process may really use: its affinity mask, capped by the cgroup quota
    (os.cpu_count() and the affinity mask both ignore a container's CPU limit)."""
    try:
        n = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        n = os.cpu_count() or 1
    limit = _cgroup_cpu_limit()
    if limit is not None:
        n = min(n, math.ceil(limit))
    return max(1, n)


def _cgroup_memory_limit(root: Path = Path("/sys/fs/cgroup")) -> int | None:
    """Bytes the container may use by its cgroup limit (``docker --memory``, compose
    ``limits.memory``), or None when unlimited or unknown. cgroup v2, then v1."""
    for name in ("memory.max", "memory/memory.limit_in_bytes"):
        try:
            text = (root / name).read_text().strip()
        except OSError:
            continue
        if text == "max":
            return None
        try:
            value = int(text)
        except ValueError:
            continue
        # cgroup v1 reports "unlimited" as a huge page-rounded number
        return value if value < 1 << 60 else None
    return None


def _machine_memory() -> int:
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):  # pragma: no cover - not POSIX
        return 8 << 30


#: Share of the container's (or machine's) memory that computations may plan to use;
#: the rest is for the interpreter, the request bodies being parsed and the responses.
MEMORY_SHARE = 0.75


def _memory_budget() -> int:
    """Default ``ZW_MEMORY_BUDGET_BYTES``: ``MEMORY_SHARE`` of the cgroup memory limit,
    or of the machine's memory when the container is not limited."""
    total = _machine_memory()
    limit = _cgroup_memory_limit()
    if limit is not None:
        total = min(total, limit)
    return int(total * MEMORY_SHARE)


class Settings(BaseSettings):
    """Every setting is an environment variable ``ZW_<NAME>`` (see the README)."""

    model_config = SettingsConfigDict(env_prefix="ZW_", extra="ignore")

    data_dir: Path = Field(Path("./data"), description="Where the embedded task store lives.")
    cache_url: str | None = Field(None, description="redis://host:port/db; unset: embedded store.")
    cache_max_bytes: int = Field(2 << 30, gt=0, description="Size bound of the embedded store.")
    cache_ttl_seconds: int = Field(7 * 24 * 3600, gt=0, description="Lifetime of a cached result.")
    api_keys: str = Field("", description="Comma-separated bearer keys; empty: no auth.")
    max_body_bytes: int = Field(256 << 20, gt=0, description="Largest request body accepted.")
    max_json_values: int = Field(
        4_500_000, gt=0, description="Most comma-separated JSON values in a body (parsing cost "
        "bound: larger grids go as z_b64).")
    max_grid_cells: int = Field(4096 * 4096, gt=0, description="Largest z-map (ny * nx).")
    max_points: int = Field(2_000_000, gt=0, description="Largest point curve for /v1/arcs; "
                            "also the most lines of a G-code program and the most vertices "
                            "and spline samples of a DXF drawing.")
    max_tools: int = Field(64, gt=0, description="Largest tool library in a plan request.")
    max_arc_resolution: float = Field(
        2.0e5, gt=0, description="Largest curve length / tolerance for /v1/arcs (work bound).")
    max_contour_slabs: int = Field(
        10_000, gt=0, description="Most contour slabs one contour-plan stage may need (413).")
    max_simulation_work: int = Field(
        20_000_000_000, gt=0, description="Largest cutting simulation, grid cells times the "
        "tool's footprint in nodes (413): a few seconds of one core.")
    max_program_bytes: int = Field(
        256 << 20, gt=0, description="Largest NC program a plan with tool paths may emit (413).")
    workers: int = Field(default_factory=_cpu_count, gt=0, description="Compute pool threads.")
    process_workers: int = Field(
        default_factory=_cpu_count, ge=0, description="Worker processes for Python-bound work "
        "(arc fitting); 0: it runs in the threads.")
    prestart_workers: bool = Field(
        True, description="Start the worker processes when the service starts (their cold "
        "start costs seconds of CPU); false: on first use.")
    max_pending: int = Field(16, ge=0,
                             description="Computations queued beyond the pool before shedding.")
    log_level: str = Field("INFO", description="Python logging level.")
    compute_timeout_seconds: float = Field(
        120.0, gt=0, description="Deadline of one computation, from when it starts: past it "
        "the work is stopped (a worker process is terminated and replaced, a thread gets an "
        "exception at its next Python step), its worker freed, and the request answered 503 "
        "(an asynchronous task: failed). 120 s: several times the largest grid plan the "
        "default limits allow, and within common HTTP client timeouts.")
    memory_budget_bytes: int = Field(
        default_factory=_memory_budget, gt=0, description="Estimated peak memory that the "
        "running computations may add up to (default: 75 % of the cgroup memory limit, or "
        "of the machine's memory). A request that would pass it waits (see "
        "memory_wait_seconds), then gets 503 with Retry-After; one that alone exceeds it "
        "gets 503 at once.")
    memory_wait_seconds: float = Field(
        10.0, ge=0, description="How long a request may wait for room in the memory budget.")
    task_state_ttl_seconds: int = Field(
        24 * 3600, gt=0, description="How long the state of an asynchronous task (pending, "
        "running, failed) is kept; a done task's result lives cache_ttl_seconds.")

    @field_validator("cache_url")
    @classmethod
    def _empty_is_unset(cls, v: str | None) -> str | None:
        return v or None

    @property
    def api_key_list(self) -> list[str]:
        return [k.strip() for k in self.api_keys.split(",") if k.strip()]


@lru_cache
def get_settings() -> Settings:
    return Settings()  # type: ignore[call-arg]  # every field has a default
