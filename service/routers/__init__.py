"""One router per OpenAPI tag."""

from __future__ import annotations

from typing import Any

from service.schemas.common import ProblemDetails

_TEXT = {
    304: "Not modified: If-None-Match named this task",
    400: "Malformed JSON body",
    401: "Missing API key",
    403: "Invalid API key",
    404: "Not found",
    409: "The stored result lacks what the request needs",
    413: "Body or grid over the configured limits",
    415: "Unsupported media type: the problem names the types this call takes",
    422: "Invalid request: the problem names each field and why",
    503: "Compute pool saturated; retry after Retry-After seconds",
}


def responses(*extra: int) -> dict[int | str, dict[str, Any]]:
    """OpenAPI response entries: problem+json for every error a /v1 call may return."""
    codes = sorted({400, 401, 403, 422, 503, *extra})
    out: dict[int | str, dict[str, Any]] = {}
    for code in codes:
        if code == 304:
            out[code] = {"description": _TEXT[code]}
            continue
        out[code] = {"description": _TEXT.get(code, "Error"), "model": ProblemDetails,
                     "content": {"application/problem+json": {}}}
    return out
