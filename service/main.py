"""The zwplan ASGI app: ``service.main:app``."""

from __future__ import annotations

import logging
import sys
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

from fastapi import Depends, FastAPI

import zwcore
from service import problems
from service.compute import ComputePool
from service.middleware import JsonFormatter, ServiceMiddleware
from service.routers import arcs, health, mrr, plans, simulate, tasks, tools, zmaps
from service.security import require_api_key
from service.settings import Settings, get_settings
from service.store import open_store

DESCRIPTION = """Machining process planning: lifted wavelet stage models from a z-map,
ball-end-mill tool sequences, contour heights for flat end mills, and tangent-continuous
arc chains from point curves. Every result is cached under its task id (SHA-256 of the
canonical request); errors are RFC 9457 problem documents."""


def _configure_logging(level: str) -> None:
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(JsonFormatter())
    root = logging.getLogger("zwplan")
    root.handlers[:] = [handler]
    root.setLevel(level.upper())
    root.propagate = False


def create_app(settings: Settings | None = None) -> FastAPI:
    settings = settings or get_settings()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        _configure_logging(settings.log_level)
        app.state.store = open_store(settings.cache_url, settings.data_dir,
                                     settings.cache_max_bytes, settings.cache_ttl_seconds)
        app.state.pool = ComputePool(settings.workers, settings.max_pending,
                                     settings.process_workers)
        try:
            yield
        finally:
            app.state.pool.shutdown()
            app.state.store.close()

    app = FastAPI(title="zwplan", version=zwcore.__version__, description=DESCRIPTION,
                  lifespan=lifespan)
    app.state.settings = settings
    problems.install(app)
    secured = [Depends(require_api_key)]
    app.include_router(mrr.router, dependencies=secured)
    app.include_router(plans.router, dependencies=secured)
    app.include_router(arcs.router, dependencies=secured)
    app.include_router(simulate.router, dependencies=secured)
    app.include_router(tasks.router, dependencies=secured)
    app.include_router(zmaps.router, dependencies=secured)
    app.include_router(tools.router, dependencies=secured)
    app.include_router(health.router)
    app.add_middleware(ServiceMiddleware, max_body_bytes=settings.max_body_bytes,
                       max_json_values=settings.max_json_values,
                       api_keys=settings.api_key_list)
    return app


app = create_app()
