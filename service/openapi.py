"""The OpenAPI document says what the service does.

FastAPI builds the document from the routes; this module adds what routes
cannot say and what depends on the deployment:

- security: the ``bearer`` scheme is required on ``/v1`` only when
  ``ZW_API_KEYS`` is set. Without keys (the default, and the committed
  ``openapi/openapi.json``) operations carry no security requirement, so a
  generated client works with a plain client; a server with keys serves a
  document that requires the scheme on every ``/v1`` operation.
- problem documents under ``application/problem+json``, the type sent;
- ``X-Request-ID`` on every response of every operation;
- links from each result to ``get_task``.
"""

from __future__ import annotations

from typing import Any

from fastapi import FastAPI

from service.problems import PROBLEM_JSON

BEARER = "bearer"

X_REQUEST_ID: dict[str, Any] = {
    "description": "The request's X-Request-ID, or one made for it: it names the request's "
    "log line.", "required": True, "schema": {"type": "string"}}


def _operations(schema: dict[str, Any]) -> list[dict[str, Any]]:
    return [op for item in schema.get("paths", {}).values() for op in item.values()
            if isinstance(op, dict) and "responses" in op]


def _problem_media_type(ops: list[dict[str, Any]]) -> None:
    """FastAPI files an error response's ``model`` under ``application/json``; left so,
    the document promised a JSON body and an untyped problem+json one, and generated
    clients parsed every error as nothing."""
    for op in ops:
        for response in op["responses"].values():
            content = response.get("content", {})
            if PROBLEM_JSON in content and "application/json" in content:
                content[PROBLEM_JSON] = content.pop("application/json")


def _link_results_to_tasks(schema: dict[str, Any], ops: list[dict[str, Any]]) -> None:
    """An OpenAPI link from every operation's result to ``get_task`` with its ``task_id``.

    Clients (and schemathesis' stateful tests) learn from the document that a
    result can be fetched again by its task id.
    """
    if not any(op.get("operationId") == "get_task" for op in ops):
        return
    component_schemas = schema.get("components", {}).get("schemas", {})
    for op in ops:
        ok = op["responses"].get("200", {})
        ref = ok.get("content", {}).get("application/json", {}).get("schema", {}).get("$ref", "")
        result = component_schemas.get(ref.rsplit("/", 1)[-1], {})
        if op.get("operationId") != "get_task" and "task_id" in result.get("required", []):
            ok.setdefault("links", {})["GetTask"] = {
                "operationId": "get_task",
                "parameters": {"task_id": "$response.body#/task_id"},
                "description": "The stored result, by the task id this call returned."}


def _security(schema: dict[str, Any], ops: list[dict[str, Any]], keys_required: bool) -> None:
    schemes = schema.get("components", {}).get("securitySchemes", {})
    if BEARER in schemes:
        schemes[BEARER]["description"] = (
            "Authorization: Bearer <key>. Required on every /v1 operation when the deployment "
            "sets ZW_API_KEYS (its served /openapi.json then says so); without keys it is "
            "not needed and is ignored.")
    if keys_required:
        return
    for op in ops:
        op.pop("security", None)


def _plain_optional_headers(ops: list[dict[str, Any]]) -> None:
    """An optional header is a string or absent: FastAPI's ``anyOf [string, null]`` for
    ``str | None`` would tell clients a header can be JSON null."""
    for op in ops:
        for param in op.get("parameters", []):
            schema = param.get("schema", {})
            kinds = [s for s in schema.get("anyOf", []) if s.get("type") != "null"]
            if param.get("in") == "header" and len(kinds) == 1 and "anyOf" in schema:
                del schema["anyOf"]
                schema.update(kinds[0])


def _request_ids(ops: list[dict[str, Any]]) -> None:
    for op in ops:
        for response in op["responses"].values():
            response.setdefault("headers", {})["X-Request-ID"] = X_REQUEST_ID


def install(app: FastAPI, keys_required: bool) -> None:
    """Shape ``app.openapi()`` once, on first build (FastAPI caches the result)."""
    build = app.openapi

    def openapi() -> dict[str, Any]:
        cached = app.openapi_schema is not None
        schema = build()
        if not cached:
            ops = _operations(schema)
            _problem_media_type(ops)
            _link_results_to_tasks(schema, ops)
            _security(schema, ops, keys_required)
            _plain_optional_headers(ops)
            _request_ids(ops)
        return schema

    app.openapi = openapi  # type: ignore[method-assign]
