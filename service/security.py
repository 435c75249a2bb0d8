"""API keys: who may call ``/v1`` (``ZW_API_KEYS``)."""

from __future__ import annotations

import hmac
from typing import Annotated

from fastapi import Depends, Request
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer

from service.problems import Problem
from service.settings import Settings

_bearer = HTTPBearer(scheme_name="bearer", auto_error=False,
                     description="Required when ZW_API_KEYS is set.")


def api_key_problem(authorization: str | None, keys: list[str]) -> Problem | None:
    """Why a request with this ``Authorization`` header may not call ``/v1`` (None: it may).

    Used twice: by the middleware, before a body is read (an unauthenticated client must
    not make the server buffer up to ``ZW_MAX_BODY_BYTES``), and as the routes'
    dependency, which documents the scheme in the OpenAPI document.
    """
    if not keys:
        return None
    scheme, _, token = (authorization or "").partition(" ")
    if scheme.lower() != "bearer" or not token.strip():
        return Problem(401, "Unauthorized", "this call needs Authorization: Bearer <key>",
                       kind="unauthorized", headers={"WWW-Authenticate": "Bearer"},
                       errors=[{"field": "Authorization", "reason": "a bearer key is required"}])
    given = token.strip().encode()
    # Compare against every key in constant time so timing reveals neither key nor index.
    matched = False
    for key in keys:
        matched |= hmac.compare_digest(given, key.encode())
    if not matched:
        return Problem(403, "Forbidden", "the API key is not valid", kind="forbidden",
                       errors=[{"field": "Authorization", "reason": "not a valid key"}])
    return None


def require_api_key(
    request: Request,
    credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)],
) -> None:
    """Every ``/v1`` call needs ``Authorization: Bearer <key>`` when keys are configured."""
    settings: Settings = request.app.state.settings
    header = f"{credentials.scheme} {credentials.credentials}" if credentials else None
    problem = api_key_problem(header, settings.api_key_list)
    if problem is not None:
        raise problem
