"""One router per OpenAPI tag; the response and header declarations they share."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import Header

from service.schemas.common import ProblemDetails
from service.schemas.tasks import TaskStatus

_TEXT = {
    202: "Accepted (Prefer: respond-async): computing in the background; poll Location",
    304: "Not modified: If-None-Match named this task (no body)",
    400: "Malformed body: not JSON, not UTF-8, nested too deeply, or a bad Content-Length",
    401: "Missing API key (only when the deployment sets ZW_API_KEYS)",
    403: "Invalid API key (only when the deployment sets ZW_API_KEYS)",
    404: "Not found",
    409: "The stored result lacks what the request needs",
    413: "Body or grid over the configured limits",
    415: "Unsupported media type: the problem names the types this call takes",
    422: "Invalid request: the problem names each field and why",
    503: "Compute pool saturated; retry after Retry-After seconds",
}

#: Response headers, as OpenAPI header objects.
ETAG: dict[str, Any] = {
    "description": "The task id in quotes; send it back as If-None-Match to get a 304.",
    "required": True, "schema": {"type": "string", "pattern": '^"[0-9a-f]{64}"$'}}
MODEL_ETAG: dict[str, Any] = {
    "description": "The grid's representation in quotes (task id, index, encoding); send it "
    "back as If-None-Match to get a 304.",
    "required": True, "schema": {"type": "string", "pattern": '^"[0-9a-f]{64}-[0-9]+-[a-z0-9-]+"$'}}
X_CACHE: dict[str, Any] = {
    "description": "Where the result came from: hit (the store), miss (computed for this "
    "request) or shared (computed once for identical concurrent requests).",
    "required": True, "schema": {"type": "string"}}
RETRY_AFTER: dict[str, Any] = {
    "description": "Seconds to wait before retrying.", "required": True,
    "schema": {"type": "integer", "minimum": 0}}


def responses(*extra: int, conditional: bool = False, etag: dict[str, Any] = ETAG,
              cache: bool = True) -> dict[int | str, dict[str, Any]]:
    """OpenAPI response entries: problem+json for every error a /v1 call may return.

    ``conditional``: the operation honours ``If-None-Match`` (304 with the ``etag``
    header, which the 200 carries too) and, with ``cache``, says in ``X-Cache``
    whether it answered a task from the store.
    """
    codes = sorted({400, 401, 403, 422, 503, *extra} | ({304} if conditional else set()))
    out: dict[int | str, dict[str, Any]] = {}
    if conditional:
        out[200] = {"headers": {"ETag": etag, **({"X-Cache": X_CACHE} if cache else {})}}
    for code in codes:
        if code == 304:
            out[code] = {"description": _TEXT[code], "headers": {"ETag": etag}}
            continue
        if code == 202:
            out[code] = {"description": _TEXT[code], "model": TaskStatus,
                         "headers": {"Location": {"description": "/v1/tasks/{task_id}",
                                                  "schema": {"type": "string"}}}}
            continue
        out[code] = {"description": _TEXT.get(code, "Error"), "model": ProblemDetails,
                     "content": {"application/problem+json": {}}}
        if code in (429, 503):
            out[code]["headers"] = {"Retry-After": RETRY_AFTER}
    return out


def if_none_match(
    if_none_match: Annotated[str | None, Header(
        alias="If-None-Match",
        description="ETags (task ids in quotes) the client holds, or *: a matching task is "
        "answered 304 without a body")] = None,
) -> None:
    """Declares ``If-None-Match`` in the document; :func:`service.tasks.not_modified`
    reads it off the request (the route answers 304 before any work)."""
