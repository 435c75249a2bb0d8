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


#: Where a validation error's location starts: the body, or a parameter's place.
_LOCATIONS = ("body", "path", "query", "header", "cookie")


def field_path(loc: Sequence[str | int]) -> str:
    """The one field-path convention of every problem's ``errors[].field``.

    A body field is its path inside the body (``("body", "grid", "z", 3, 5)`` ->
    ``"grid.z[3][5]"``), a parameter is its name as the document spells it
    (``("path", "task_id")`` -> ``"task_id"``, ``("header", "If-None-Match")``),
    and the body as a whole is ``"body"``.
    """
    out = ""
    parts = list(loc)
    if parts and parts[0] in _LOCATIONS:
        head = parts.pop(0)
        if not parts:
            return str(head)
    for part in parts:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out or "body"


def _unparsable_reason(exc: BaseException | None) -> str:
    """Why FastAPI could not parse a body that is not a JSON syntax error."""
    if isinstance(exc, UnicodeDecodeError):
        return f"the body is not valid UTF-8 (byte {exc.start})"
    if isinstance(exc, RecursionError):
        return "the JSON is nested too deeply"
    return "the body could not be parsed as JSON"


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


#: How each core error is reported, most specific class first.
_CORE_ERRORS: dict[type[ZwError], tuple[int, str, str]] = {
    LimitExceededError: (413, "Request too large", "too-large"),
    InvalidInputError: (422, "Invalid request", "validation"),
    PlanningError: (422, "No plan possible", "no-plan"),
    ZwError: (422, "Invalid request", "validation"),
}


def install(app: FastAPI) -> None:
    """Register the handlers that turn every error into a problem document."""

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
        if exc.status_code == 400:
            # FastAPI's "error parsing the body" (invalid UTF-8, deep nesting): its cause
            # says which, and it gets the same type and errors[] as malformed JSON.
            reason = _unparsable_reason(exc.__cause__)
            return problem_response(400, "Malformed request body", reason,
                                    kind="malformed-body", instance=request.url.path,
                                    errors=[{"field": "body", "reason": reason}])
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
