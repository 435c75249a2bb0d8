"""RFC 9457 problem details for every error the service returns."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import orjson
from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.responses import Response

from zwcore.errors import InvalidInputError, LimitExceededError, PlanningError, ZwError

PROBLEM_JSON = "application/problem+json"
PROBLEM_BASE = "https://zwplan.dev/problems/"


class Problem(Exception):
    """An error the service reports as a problem document."""

    def __init__(self, status: int, title: str, detail: str, *, kind: str = "about:blank",
                 errors: Sequence[dict[str, str]] = (), headers: dict[str, str] | None = None):
        super().__init__(detail)
        self.status = status
        self.title = title
        self.detail = detail
        self.kind = kind
        self.errors = list(errors)
        self.headers = headers or {}


def problem_response(status: int, title: str, detail: str, *, kind: str = "about:blank",
                     instance: str | None = None, errors: Sequence[dict[str, str]] = (),
                     headers: dict[str, str] | None = None) -> Response:
    body: dict[str, Any] = {
        "type": kind if kind == "about:blank" else PROBLEM_BASE + kind,
        "title": title,
        "status": status,
        "detail": detail,
    }
    if instance:
        body["instance"] = instance
    if errors:
        body["errors"] = list(errors)
    return Response(orjson.dumps(body), status_code=status, media_type=PROBLEM_JSON,
                    headers=headers)


def field_path(loc: Sequence[str | int]) -> str:
    """``("body", "grid", "z", 3, 5)`` -> ``"grid.z[3][5]"``."""
    out = ""
    for part in loc:
        if part == "body" and not out:
            continue
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out or "body"


def _validation_problem(request: Request, exc: RequestValidationError) -> Response:
    errors = []
    malformed = False
    for err in exc.errors():
        if err.get("type") == "json_invalid":
            malformed = True
            ctx = err.get("ctx") or {}
            errors.append({"field": "body",
                           "reason": f"malformed JSON: {ctx.get('error', err.get('msg'))}"})
            continue
        loc = err.get("loc", ())
        if err.get("type") == "missing" and loc == ("body",):
            errors.append({"field": "body", "reason": "a JSON request body is required"})
            continue
        errors.append({"field": field_path(loc), "reason": str(err.get("msg", "invalid"))})
    if malformed:
        return problem_response(400, "Malformed request body", errors[0]["reason"],
                                kind="malformed-body", instance=request.url.path, errors=errors)
    detail = "; ".join(f"{e['field']}: {e['reason']}" for e in errors[:5])
    return problem_response(422, "Invalid request", detail, kind="validation",
                            instance=request.url.path, errors=errors)


def _link_results_to_tasks(schema: dict[str, Any]) -> None:
    """An OpenAPI link from every operation's result to ``get_task`` with its ``task_id``.

    Clients (and schemathesis' stateful tests) learn from the document that a
    result can be fetched again by its task id.
    """
    ops = [op for item in schema.get("paths", {}).values() for op in item.values()]
    if not any(op.get("operationId") == "get_task" for op in ops):
        return
    component_schemas = schema.get("components", {}).get("schemas", {})
    for op in ops:
        ok = op.get("responses", {}).get("200", {})
        ref = ok.get("content", {}).get("application/json", {}).get("schema", {}).get("$ref", "")
        result = component_schemas.get(ref.rsplit("/", 1)[-1], {})
        if op.get("operationId") != "get_task" and "task_id" in result.get("required", []):
            ok.setdefault("links", {})["GetTask"] = {
                "operationId": "get_task",
                "parameters": {"task_id": "$response.body#/task_id"},
                "description": "The stored result, by the task id this call returned."}


def _problem_media_type_in_openapi(app: FastAPI) -> None:
    """Declare the ProblemDetails schema under ``application/problem+json``, the type sent.

    FastAPI files an error response's ``model`` under ``application/json``;
    left so, the document promised a JSON body and an untyped problem+json one,
    and generated clients parsed every error as nothing.
    """
    build = app.openapi

    def openapi() -> dict[str, Any]:
        cached = app.openapi_schema is not None
        schema = build()
        if not cached:
            for item in schema.get("paths", {}).values():
                for op in item.values():
                    for response in op.get("responses", {}).values():
                        content = response.get("content", {})
                        if PROBLEM_JSON in content and "application/json" in content:
                            content[PROBLEM_JSON] = content.pop("application/json")
            _link_results_to_tasks(schema)
        return schema

    app.openapi = openapi  # type: ignore[method-assign]


#: How each core error is reported, most specific class first.
_CORE_ERRORS: dict[type[ZwError], tuple[int, str, str]] = {
    LimitExceededError: (413, "Request too large", "too-large"),
    InvalidInputError: (422, "Invalid request", "validation"),
    PlanningError: (422, "No plan possible", "no-plan"),
    ZwError: (422, "Invalid request", "validation"),
}


def install(app: FastAPI) -> None:
    """Register the handlers that turn every error into a problem document."""

    _problem_media_type_in_openapi(app)

    @app.exception_handler(RequestValidationError)
    async def _on_validation(request: Request, exc: RequestValidationError) -> Response:
        return _validation_problem(request, exc)

    @app.exception_handler(ZwError)
    async def _on_core_error(request: Request, exc: ZwError) -> Response:
        # The most specific class wins (LimitExceededError is an InvalidInputError).
        status, title, kind = next(v for k, v in _CORE_ERRORS.items() if isinstance(exc, k))
        return problem_response(status, title, str(exc), kind=kind, instance=request.url.path,
                                errors=[{"field": exc.field, "reason": exc.reason}])

    @app.exception_handler(Problem)
    async def _on_problem(request: Request, exc: Problem) -> Response:
        return problem_response(exc.status, exc.title, exc.detail, kind=exc.kind,
                                instance=request.url.path, errors=exc.errors,
                                headers=exc.headers)

    @app.exception_handler(StarletteHTTPException)
    async def _on_http(request: Request, exc: StarletteHTTPException) -> Response:
        title = {404: "Not found", 405: "Method not allowed"}.get(exc.status_code, "HTTP error")
        return problem_response(exc.status_code, title, str(exc.detail),
                                instance=request.url.path,
                                headers=getattr(exc, "headers", None))

    @app.exception_handler(Exception)
    async def _on_bug(request: Request, exc: Exception) -> Response:
        # A 5xx is a bug: log it with the trace, tell the client nothing internal.
        import logging

        logging.getLogger("zwplan").exception("unhandled error on %s", request.url.path)
        return problem_response(500, "Internal error",
                                "The service failed on this request; it has been logged.",
                                instance=request.url.path)
