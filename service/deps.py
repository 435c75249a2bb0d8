"""Dependencies as ``Annotated`` aliases (FastAPI full-stack template style)."""

from __future__ import annotations

import hmac
from typing import Annotated

from fastapi import Depends, Request
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer

from service.compute import ComputePool
from service.problems import Problem
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

_bearer = HTTPBearer(auto_error=False, description="Required when ZW_API_KEYS is set.")


def require_api_key(
    settings: SettingsDep,
    credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)],
) -> None:
    """Every ``/v1`` call needs ``Authorization: Bearer <key>`` when keys are configured."""
    keys = settings.api_key_list
    if not keys:
        return
    if credentials is None or credentials.scheme.lower() != "bearer":
        raise Problem(401, "Unauthorized", "this call needs Authorization: Bearer <key>",
                      kind="unauthorized", headers={"WWW-Authenticate": "Bearer"})
    given = credentials.credentials.encode()
    # Compare against every key in constant time so timing reveals neither key nor index.
    matched = False
    for key in keys:
        matched |= hmac.compare_digest(given, key.encode())
    if not matched:
        raise Problem(403, "Forbidden", "the API key is not valid", kind="forbidden")
