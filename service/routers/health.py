"""Liveness, readiness and metrics: open even when API keys are configured."""

from __future__ import annotations

from typing import Literal

import anyio
from fastapi import APIRouter, Response
from prometheus_client import CONTENT_TYPE_LATEST, generate_latest
from pydantic import BaseModel

from service.deps import PoolDep, StoreDep
from service.metrics import REGISTRY

router = APIRouter(tags=["health"])


class Health(BaseModel):
    status: Literal["ok"]


class Readiness(BaseModel):
    status: Literal["ok", "degraded", "down"]
    cache: Literal["ok", "degraded", "down"]
    cache_kind: str
    detail: str
    pool_busy: int
    pool_capacity: int


@router.get("/healthz", response_model=Health, operation_id="get_health",
            summary="Liveness")
async def get_health() -> Health:
    return Health(status="ok")


@router.get("/readyz", response_model=Readiness, operation_id="get_readiness",
            summary="Readiness: the task store works",
            responses={503: {"model": Readiness, "description": "The store is down"}})
async def get_readiness(store: StoreDep, pool: PoolDep, response: Response) -> Readiness:
    state, detail = await anyio.to_thread.run_sync(store.health)
    # A degraded shared cache still serves (computing without it); a broken
    # embedded store means this replica cannot keep its contract.
    if state == "down":
        response.status_code = 503
    return Readiness(status=state, cache=state, cache_kind=store.kind, detail=detail,  # type: ignore[arg-type]
                     pool_busy=pool.busy, pool_capacity=pool.capacity)


@router.get("/metrics", operation_id="get_metrics", summary="Prometheus metrics",
            response_class=Response,
            responses={200: {"content": {"text/plain": {"schema": {"type": "string"}}},
                            "description": "Prometheus text"}})
async def get_metrics() -> Response:
    return Response(generate_latest(REGISTRY), media_type=CONTENT_TYPE_LATEST)
