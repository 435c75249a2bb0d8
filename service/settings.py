"""Service settings, read from the environment with the ``ZW_`` prefix."""

from __future__ import annotations

import os
from functools import lru_cache
from pathlib import Path

from pydantic import Field, field_validator
from pydantic_settings import BaseSettings, SettingsConfigDict


def _cpu_count() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


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
    max_points: int = Field(2_000_000, gt=0, description="Largest point curve for /v1/arcs.")
    max_tools: int = Field(64, gt=0, description="Largest tool library in a plan request.")
    max_arc_resolution: float = Field(
        2.0e5, gt=0, description="Largest curve length / tolerance for /v1/arcs (work bound).")
    max_contour_slabs: int = Field(
        10_000, gt=0, description="Most contour slabs one contour-plan stage may need (413).")
    workers: int = Field(default_factory=_cpu_count, gt=0, description="Compute pool threads.")
    process_workers: int = Field(
        default_factory=_cpu_count, ge=0, description="Worker processes for Python-bound work "
        "(arc fitting), started on first use; 0: it runs in the threads.")
    max_pending: int = Field(16, ge=0,
                             description="Computations queued beyond the pool before shedding.")
    log_level: str = Field("INFO", description="Python logging level.")

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
