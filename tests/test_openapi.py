"""The committed OpenAPI document is the app's, with readable names."""

from __future__ import annotations

import json
from pathlib import Path

from scripts.export_openapi import document
from service.main import app

COMMITTED = Path(__file__).resolve().parents[1] / "openapi" / "openapi.json"


def test_committed_document_matches_the_app() -> None:
    assert COMMITTED.exists(), "run: python scripts/export_openapi.py"
    assert json.loads(COMMITTED.read_text()) == json.loads(document()), (
        "openapi/openapi.json is stale: run python scripts/export_openapi.py")


def test_operation_ids_and_schemas_are_named() -> None:
    spec = app.openapi()
    ids = [op["operationId"] for path in spec["paths"].values() for op in path.values()]
    assert len(ids) == len(set(ids))
    for op_id in ids:
        assert "__" not in op_id and "_post" not in op_id and "_get" not in op_id, op_id
    schemas = spec["components"]["schemas"]
    for name in ("Grid", "GridOut", "MrrRequest", "MrrResult", "ProblemDetails"):
        assert name in schemas
