"""Dependencies as ``Annotated`` aliases (FastAPI full-stack template style)."""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Header, Request

from service.compute import ComputePool
from service.settings import Settings
from service.store import TaskStore


def get_settings_dep(request: Request) -> Settings:
    settings: Settings = request.app.state.settings
    return settings


def get_store(request: Request) -> TaskStore:
    store: TaskStore = request.app.state.store
    return store


def get_pool(request: Request) -> ComputePool:
    pool: ComputePool = request.app.state.pool
    return pool


SettingsDep = Annotated[Settings, Depends(get_settings_dep)]
StoreDep = Annotated[TaskStore, Depends(get_store)]
PoolDep = Annotated[ComputePool, Depends(get_pool)]


def prefers_async(
    prefer: Annotated[str | None, Header(
        description="`respond-async`: answer 202 with a Location at once and compute in "
        "the background (RFC 7240); a stored result is answered 200 all the same")] = None,
) -> bool:
    return prefer is not None and any(
        p.split(";")[0].strip().lower() == "respond-async" for p in prefer.split(","))


PreferAsyncDep = Annotated[bool, Depends(prefers_async)]
