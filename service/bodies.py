"""Request bodies parsed and validated off the event loop.

FastAPI parses a JSON body and validates it against the route's model on the
event loop: for a 2048² grid sent as rows (millions of numbers) that held every
other request, ``/healthz`` included, for seconds. :class:`OffLoopRoute` does
both in a worker thread first (orjson, then the route's own body field, so
errors are exactly FastAPI's), and hands FastAPI the validated model, which it
accepts without validating again.
"""

from __future__ import annotations

import email.message
import json
from collections.abc import Callable, Coroutine
from typing import Any

import anyio
import orjson
from fastapi.exceptions import RequestValidationError
from fastapi.routing import APIRoute
from starlette.requests import Request
from starlette.responses import Response

_UNPARSED = object()


def _is_json(content_type: str | None) -> bool:
    if not content_type:
        return True  # FastAPI reads a body without a content type as JSON
    message = email.message.Message()
    message["content-type"] = content_type
    subtype = message.get_content_subtype()
    return message.get_content_maintype() == "application" and (
        subtype == "json" or subtype.endswith("+json"))


def _parse_and_validate(field: Any, body: bytes) -> tuple[Any, list[Any]]:
    """The validated body or FastAPI's own error list (runs in a worker thread)."""
    try:
        value = orjson.loads(body)
    except orjson.JSONDecodeError:
        # orjson is strict JSON; FastAPI's parser (the standard library's) also takes
        # NaN and Infinity, which then fail validation with a precise message, and
        # words its errors its own way: on anything orjson refuses, ask it.
        try:
            value = json.loads(body)
        except json.JSONDecodeError as exc:
            return None, [{"type": "json_invalid", "loc": ("body", exc.pos),
                           "msg": "JSON decode error", "input": {},
                           "ctx": {"error": exc.msg}}]
        except (ValueError, RecursionError):
            # not UTF-8, or nested too deeply: FastAPI's own path, whose failure the
            # problem handlers type as a malformed body (on the loop, but fast)
            return _UNPARSED, []
    validated, errors = field.validate(value, {}, loc=("body",))
    return validated, list(errors or [])


class OffLoopRoute(APIRoute):
    """An API route whose JSON body is parsed and validated in a worker thread."""

    def get_route_handler(self) -> Callable[[Request], Coroutine[Any, Any, Response]]:
        handler = super().get_route_handler()
        field = self.body_field

        async def route(request: Request) -> Response:
            if field is not None and _is_json(request.headers.get("content-type")):
                body = await request.body()
                if body:
                    value, errors = await anyio.to_thread.run_sync(
                        _parse_and_validate, field, body)
                    if errors:
                        raise RequestValidationError(errors, body=None)
                    if value is not _UNPARSED:
                        # Starlette's Request.json() returns this cached value; FastAPI
                        # then takes the model instance as it is.
                        request._json = value
            return await handler(request)

        return route
