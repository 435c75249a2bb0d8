"""The zwplan ASGI app: ``service.main:app``."""

from __future__ import annotations

import asyncio
import concurrent.futures
import logging
import sys
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from typing import Any

from fastapi import Depends, FastAPI
from fastapi_offline import FastAPIOffline
from pydantic import BaseModel
from pydantic.json_schema import models_json_schema

import zwcore
from service import asynctasks, openapi, problems
from service.compute import ComputePool, trim_when_idle
from service.middleware import JsonFormatter, ServiceMiddleware
from service.routers import (
    arcs,
    health,
    mrr,
    plans,
    previews,
    simulate,
    tasks,
    tools,
    viewer,
    zmaps,
)
from service.security import require_api_key
from service.settings import Settings, get_settings
from service.store import open_store
from zwcore.scanline.warmup import warm_up as warm_up_scanline

#: How long the service waits at start for its worker processes (a cold start is seconds).
WORKER_START_SECONDS = 120.0

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
    # ezdxf logs every repair of a broken DXF upload as a warning: noise, not service events
    logging.getLogger("ezdxf").setLevel(logging.ERROR)
    # One line per request: the middleware's JSON line. uvicorn's own access line would
    # repeat it in another format (and is on unless started with --no-access-log).
    access = logging.getLogger("uvicorn.access")
    access.handlers[:] = []
    access.propagate = False
    access.disabled = True


def _list_models(app: FastAPI, models: tuple[type[BaseModel], ...]) -> None:
    """Put request models that no route parameter names (a route reading several media
    types parses its body itself) into the document's components."""
    build = app.openapi

    def openapi() -> dict[str, Any]:
        cached = app.openapi_schema is not None
        schema = build()
        if not cached:
            _, defs = models_json_schema([(m, "validation") for m in models],
                                         ref_template="#/components/schemas/{model}")
            components = schema.setdefault("components", {}).setdefault("schemas", {})
            for name, model_schema in defs.get("$defs", {}).items():
                components.setdefault(name, model_schema)
            schema["components"]["schemas"] = dict(sorted(components.items()))
        return schema

    app.openapi = openapi  # type: ignore[method-assign]


async def _started(jobs: list[concurrent.futures.Future[int]]) -> list[int]:
    """The pids of the started worker processes; a worker that fails to start within
    :data:`WORKER_START_SECONDS` is logged and left to start on first use."""
    if not jobs:
        return []
    done, _ = await asyncio.wait([asyncio.wrap_future(j) for j in jobs],
                                 timeout=WORKER_START_SECONDS)
    pids = [f.result() for f in done if f.exception() is None]
    if len(pids) < len(jobs):
        logging.getLogger("zwplan").warning("%d of %d worker processes not started in %s s",
                                            len(jobs) - len(pids), len(jobs),
                                            WORKER_START_SECONDS)
    return pids


def create_app(settings: Settings | None = None) -> FastAPI:
    settings = settings or get_settings()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        _configure_logging(settings.log_level)
        # compiled scan-line kernels loaded before serving: loading holds the GIL
        warm_up_scanline()
        app.state.store = open_store(settings.cache_url, settings.data_dir,
                                     settings.cache_max_bytes, settings.cache_ttl_seconds)
        app.state.pool = ComputePool(settings.workers, settings.max_pending,
                                     settings.process_workers,
                                     timeout=settings.compute_timeout_seconds,
                                     memory_budget=settings.memory_budget_bytes,
                                     memory_wait=settings.memory_wait_seconds)
        app.state.worker_pids = []
        if settings.prestart_workers:
            # serve only once the workers are up: a request arriving during their cold start
            # would wait seconds for it (the load benchmark's first arc fits did)
            app.state.worker_pids = await _started(app.state.pool.start_processes())
        trimmer = asyncio.ensure_future(trim_when_idle(app.state.pool))
        try:
            yield
        finally:
            trimmer.cancel()
            asynctasks.cancel_all()
            app.state.pool.shutdown()
            app.state.store.close()

    # Swagger UI and ReDoc from assets shipped in the package, not a CDN: shop networks
    # are often offline (/docs, /redoc; assets under /static-offline-docs).
    app = FastAPIOffline(title="zwplan", version=zwcore.__version__, description=DESCRIPTION,
                         lifespan=lifespan)
    app.state.settings = settings
    problems.install(app)
    openapi.install(app, keys_required=bool(settings.api_key_list))
    secured = [Depends(require_api_key)]
    app.include_router(mrr.router, dependencies=secured)
    app.include_router(plans.router, dependencies=secured)
    app.include_router(arcs.router, dependencies=secured)
    app.include_router(simulate.router, dependencies=secured)
    app.include_router(tasks.router, dependencies=secured)
    app.include_router(zmaps.router, dependencies=secured)
    app.include_router(previews.router, dependencies=secured)
    app.include_router(tools.router, dependencies=secured)
    app.include_router(health.router)
    app.include_router(viewer.router)
    _list_models(app, arcs.OPENAPI_MODELS)
    app.add_middleware(ServiceMiddleware, max_body_bytes=settings.max_body_bytes,
                       max_json_values=settings.max_json_values,
                       api_keys=settings.api_key_list)
    return app


app = create_app()
