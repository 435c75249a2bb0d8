"""ASGI middleware: request ids, the body-size limit, metrics and structured access logs."""

from __future__ import annotations

import json
import logging
import time
import uuid
from typing import Any

import orjson
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from service import metrics
from service.problems import PROBLEM_JSON, problem_response
from service.security import api_key_problem

log = logging.getLogger("zwplan.access")

_BINARY_MEDIA = (b"application/x-npy", b"model/stl", b"application/sla",
                 b"application/vnd.ms-pki.stl", b"model/x.stl-binary", b"model/x.stl-ascii",
                 b"application/octet-stream")


class JsonFormatter(logging.Formatter):
    """One JSON object per log line; extra fields passed as ``extra={"fields": {...}}``."""

    def format(self, record: logging.LogRecord) -> str:
        entry: dict[str, Any] = {
            "ts": round(record.created, 3),
            "level": record.levelname.lower(),
            "logger": record.name,
            "msg": record.getMessage(),
        }
        entry.update(getattr(record, "fields", {}))
        if record.exc_info:
            entry["exc"] = self.formatException(record.exc_info)
        return json.dumps(entry, default=str)


def _problem(status: int, title: str, detail: str) -> bytes:
    return orjson.dumps({"type": "about:blank", "title": title, "status": status,
                         "detail": detail, "errors": [{"field": "body", "reason": detail}]})


class ServiceMiddleware:
    """Outermost layer of the app.

    - echoes ``X-Request-ID`` (or makes one) on every response;
    - refuses a ``/v1`` call without a valid API key (when keys are set) before
      reading its body;
    - bounds the number of JSON values a body may hold (``max_json_values``),
      since parsing multiplies their memory;
    - enforces ``max_body_bytes`` on every request, whether it declares a
      Content-Length or arrives chunked: the body is read here, so the limit
      holds before any parsing starts;
    - records per-operation counts and latencies and writes one JSON log line
      per request (never the body, never the Authorization header).
    """

    def __init__(self, app: ASGIApp, max_body_bytes: int, max_json_values: int,
                 api_keys: list[str] | None = None) -> None:
        self.app = app
        self.max_body_bytes = max_body_bytes
        self.max_json_values = max_json_values
        self.api_keys = api_keys or []

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        start = time.perf_counter()
        headers = dict(scope.get("headers") or [])
        request_id = headers.get(b"x-request-id", b"").decode("latin-1")[:128]
        if not request_id or not request_id.isprintable():
            request_id = uuid.uuid4().hex
        scope.setdefault("state", {})["request_id"] = request_id
        status = 500
        response_started = False

        async def send_wrapper(message: Message) -> None:
            nonlocal status, response_started
            if message["type"] == "http.response.start":
                response_started = True
                status = message["status"]
                message["headers"] = [*message.get("headers", []),
                                      (b"x-request-id", request_id.encode("latin-1"))]
            await send(message)

        async def reject(code: int, title: str, detail: str) -> None:
            await send_wrapper({"type": "http.response.start", "status": code,
                                "headers": [(b"content-type", PROBLEM_JSON.encode())]})
            await send_wrapper({"type": "http.response.body",
                                "body": _problem(code, title, detail)})

        try:
            if self.api_keys and scope["path"].startswith("/v1"):
                auth = headers.get(b"authorization")
                denied = api_key_problem(auth.decode("latin-1") if auth else None, self.api_keys)
                if denied is not None:
                    await problem_response(denied.status, denied.title, denied.detail,
                                           kind=denied.kind, instance=scope["path"],
                                           headers=denied.headers)(scope, receive, send_wrapper)
                    return
            declared = headers.get(b"content-length")
            if declared is not None:
                try:
                    too_big = int(declared) > self.max_body_bytes
                except ValueError:
                    await reject(400, "Bad request", "Content-Length is not a number")
                    return
                if too_big:
                    await reject(413, "Request too large",
                                 f"body exceeds the limit of {self.max_body_bytes} bytes")
                    return
            body = b""
            if scope["method"] in ("POST", "PUT", "PATCH"):
                chunks: list[bytes] = []
                size = 0
                more = True
                while more:
                    message = await receive()
                    if message["type"] == "http.disconnect":
                        status = 499  # client closed the request: no response, not a 5xx
                        return
                    chunk = message.get("body", b"")
                    size += len(chunk)
                    if size > self.max_body_bytes:
                        await reject(413, "Request too large",
                                     f"body exceeds the limit of {self.max_body_bytes} bytes")
                        return
                    chunks.append(chunk)
                    more = message.get("more_body", False)
                body = b"".join(chunks)
                # Parsed JSON numbers cost ~10x their text in Python objects: bound their
                # count before any parsing (a comma count is a cheap upper bound).
                # (binary bodies, .npy or STL, hold commas by chance: not counted)
                media = headers.get(b"content-type", b"").split(b";")[0].strip().lower()
                binary = media in _BINARY_MEDIA or media.startswith(b"multipart/")
                if not binary and body.count(b",") >= self.max_json_values:
                    await reject(413, "Request too large",
                                 f"body holds more than {self.max_json_values} JSON values; "
                                 "send large grids as z_b64")
                    return
            replayed = False

            async def replay() -> Message:
                nonlocal replayed
                if not replayed:
                    replayed = True
                    return {"type": "http.request", "body": body, "more_body": False}
                return await receive()

            await self.app(scope, replay, send_wrapper)
        except Exception:
            log.exception("unhandled error", extra={"fields": {"request_id": request_id}})
            if not response_started:
                await reject(500, "Internal error", "The service failed on this request.")
        finally:
            elapsed = time.perf_counter() - start
            route = scope.get("route")
            # the OpenAPI operation id: the name clients, dashboards and logs share
            operation = (getattr(route, "operation_id", None) or getattr(route, "name", None)
                         or "unmatched")
            metrics.REQUESTS.labels(operation, str(status)).inc()
            metrics.REQUEST_SECONDS.labels(operation).observe(elapsed)
            state = scope.get("state", {})
            log.info("request", extra={"fields": {
                "request_id": request_id, "method": scope["method"], "path": scope["path"],
                "operation": operation, "status": status, "ms": round(elapsed * 1000, 2),
                "task_id": state.get("task_id"), "cache": state.get("cache"),
                "compute_ms": state.get("compute_ms")}})
