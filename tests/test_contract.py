"""The OpenAPI document says what the service does (issue 14).

Each declaration is checked twice: in the document, and against what a real
request gets back (status, headers, problem body).
"""

from __future__ import annotations

import json
import re
import time
from collections.abc import Iterator
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import httpx
import pytest
from fastapi.testclient import TestClient

from tests.conftest import make_client
from tests.live_server import live_server

PROBLEM = "application/problem+json"
GRID = {"dx": 1.0, "dy": 1.0, "z": [[0.0, 1.0, 2.0], [1.0, 2.0, 3.0], [0.0, 1.0, 2.0]]}
BODIES: dict[str, tuple[str, dict[str, Any]]] = {
    "compute_mrr": ("/v1/mrr", {"grid": GRID}),
    "plan_scanline": ("/v1/plans/scanline", {"grid": GRID, "tolerance": 0.1}),
    "plan_contour": ("/v1/plans/contour", {"grid": GRID}),
    "fit_arcs": ("/v1/arcs", {"points": [[0.0, 0.0], [4.0, 0.0], [8.0, 2.0]]}),
    "simulate": ("/v1/simulate", {"grid": GRID, "tool": {"kind": "ball", "diameter": 2.0,
                                                         "flute_length": 4.0}}),
}
STL = (b"solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 1\n"
       b"endloop\nendfacet\nendsolid t\n")
TASK_ID = re.compile(r"[0-9a-f]{64}")


def operations(spec: dict[str, Any]) -> dict[str, tuple[str, str, dict[str, Any]]]:
    return {op["operationId"]: (method, path, op) for path, item in spec["paths"].items()
            for method, op in item.items() if isinstance(op, dict) and "operationId" in op}


@pytest.fixture
def keyed(tmp_path: Path) -> Iterator[TestClient]:
    with make_client(tmp_path, api_keys="k1,k2") as c:
        yield c


# -- security ------------------------------------------------------------------------------


def test_security_is_required_only_when_keys_are_set(client: TestClient,
                                                     keyed: TestClient) -> None:
    open_ops = operations(client.app.openapi())  # type: ignore[attr-defined]
    keyed_ops = operations(keyed.app.openapi())  # type: ignore[attr-defined]
    assert open_ops.keys() == keyed_ops.keys()
    for operation_id, (_m, path, op) in open_ops.items():
        assert "security" not in op, operation_id
        if path.startswith("/v1/"):
            assert keyed_ops[operation_id][2]["security"] == [{"bearer": []}], operation_id
        else:
            assert "security" not in keyed_ops[operation_id][2], operation_id
    # what the documents say is what the servers do
    assert client.get("/v1/tools").status_code == 200
    assert keyed.get("/v1/tools").status_code == 401
    assert keyed.get("/v1/tools", headers={"Authorization": "Bearer k2"}).status_code == 200
    scheme = client.app.openapi()["components"]["securitySchemes"]  # type: ignore[attr-defined]
    assert scheme == {"bearer": {"type": "http", "scheme": "bearer",
                                 "description": scheme["bearer"]["description"]}}


# -- conditional requests and headers ------------------------------------------------------


def test_conditional_operations_declare_if_none_match_304_and_headers(
        client: TestClient) -> None:
    ops = operations(client.app.openapi())  # type: ignore[attr-defined]
    for operation_id in (*BODIES, "create_zmap", "get_task", "get_task_model"):
        _m, _p, op = ops[operation_id]
        params = {(p["in"], p["name"]): p for p in op.get("parameters", [])}
        assert params[("header", "If-None-Match")]["schema"]["type"] == "string"
        assert not params[("header", "If-None-Match")]["required"]
        responses = op["responses"]
        assert set(responses["304"]["headers"]) == {"ETag", "X-Request-ID"}
        assert "content" not in responses["304"]
        assert {"ETag", "X-Request-ID"} <= set(responses["200"]["headers"])
        assert ("X-Cache" in responses["200"]["headers"]) == (operation_id != "get_task_model")
        assert responses["503"]["headers"]["Retry-After"]["schema"]["type"] == "integer"
    for operation_id, (_m, _p, op) in ops.items():
        for status, response in op["responses"].items():
            assert response["headers"]["X-Request-ID"]["required"], (operation_id, status)


def test_declared_headers_are_sent(client: TestClient) -> None:
    for operation_id, (path, body) in BODIES.items():
        first = client.post(path, json=body, headers={"X-Request-ID": f"req-{operation_id}"})
        assert first.status_code == 200, first.text
        tid = first.json()["task_id"]
        etag = f'"{tid}"'
        assert first.headers["etag"] == etag and first.headers["x-cache"] == "miss"
        assert first.headers["x-request-id"] == f"req-{operation_id}"
        assert first.json()["operation"] == operation_id
        again = client.post(path, json=body)
        assert again.headers["x-cache"] == "hit" and again.json() == first.json()
        cond = client.post(path, json=body, headers={"If-None-Match": f'"{"0" * 64}", {etag}'})
        assert cond.status_code == 304 and cond.content == b"" and cond.headers["etag"] == etag
        assert cond.headers["x-request-id"]
        stored = client.get(f"/v1/tasks/{tid}")
        assert stored.status_code == 200 and stored.headers["x-cache"] == "hit"
        assert stored.json()["operation"] == operation_id
        cond = client.get(f"/v1/tasks/{tid}", headers={"If-None-Match": f"W/{etag}"})
        assert cond.status_code == 304 and cond.headers["etag"] == etag


def test_zmap_uploads_and_models_send_their_declared_headers(client: TestClient) -> None:
    r = client.post("/v1/zmaps?dx=0.5", content=STL, headers={"content-type": "model/stl"})
    assert r.status_code == 200, r.text
    tid = r.json()["task_id"]
    assert r.json()["operation"] == "create_zmap"
    assert r.headers["etag"] == f'"{tid}"' and r.headers["x-cache"] == "miss"
    npy = client.post("/v1/zmaps?dx=0.5", content=STL,
                      headers={"content-type": "model/stl", "accept": "application/x-npy"})
    assert npy.status_code == 200 and npy.headers["etag"] == f'"{tid}"'
    cond = client.post("/v1/zmaps?dx=0.5", content=STL,
                       headers={"content-type": "model/stl", "If-None-Match": f'"{tid}"'})
    assert cond.status_code == 304
    model = client.get(f"/v1/tasks/{tid}/models/0")
    assert model.status_code == 200
    assert re.fullmatch(r'"[0-9a-f]{64}-[0-9]+-[a-z0-9-]+"', model.headers["etag"])
    again = client.get(f"/v1/tasks/{tid}/models/0",
                       headers={"If-None-Match": model.headers["etag"]})
    assert again.status_code == 304 and again.headers["etag"] == model.headers["etag"]
    # a z-map task feeds a plan by its id: the stored operation name is the one checked
    plan = client.post("/v1/mrr", json={"grid_task": tid})
    assert plan.status_code == 200, plan.text
    mrr = client.post("/v1/mrr", json={"grid": GRID, "include_models": True}).json()
    level = client.get(f"/v1/tasks/{mrr['task_id']}/models/0")
    assert level.status_code == 200 and level.json()["nx"] == mrr["levels"][0]["nx"]


def test_discriminator_names_every_result_by_its_operation_id(client: TestClient) -> None:
    spec = client.app.openapi()  # type: ignore[attr-defined]
    ops = operations(spec)
    union = ops["get_task"][2]["responses"]["200"]["content"]["application/json"]["schema"]
    mapping = union["discriminator"]["mapping"]
    assert union["discriminator"]["propertyName"] == "operation"
    # fit_arcs answers three kinds of result (a point curve, a G-code program, a DXF): the
    # curve's is named fit_arcs, the files' arcs_gcode and arcs_dxf
    kinds = {"arcs_gcode": "fit_arcs", "arcs_dxf": "fit_arcs"}
    assert set(mapping) == {*BODIES, "create_zmap", *kinds}
    for name_in_result, ref in mapping.items():
        _m, _p, op = ops[kinds.get(name_in_result, name_in_result)]
        answer = op["responses"]["200"]["content"]["application/json"]["schema"]
        assert answer.get("$ref") == ref or ref in [s["$ref"] for s in answer["oneOf"]]
        name = ref.rsplit("/", 1)[1]
        assert spec["components"]["schemas"][name]["properties"]["operation"]["const"] == (
            name_in_result)


# -- errors: one field-path convention, every 400 typed ------------------------------------


def problem(r: httpx.Response, status: int) -> dict[str, Any]:
    assert r.status_code == status, r.text
    assert r.headers["content-type"] == PROBLEM
    body: dict[str, Any] = r.json()
    assert body["status"] == status and body["title"] and body["detail"]
    assert body["type"].startswith("https://zwplan.dev/problems/"), body
    assert body["errors"] and all(e["field"] and e["reason"] for e in body["errors"])
    return body


def fields(body: dict[str, Any]) -> list[str]:
    return [e["field"] for e in body["errors"]]


def test_parameters_are_named_as_the_document_names_them(client: TestClient) -> None:
    assert fields(problem(client.get("/v1/tasks/not-a-task"), 422)) == ["task_id"]
    assert fields(problem(client.get("/v1/tasks/" + "0" * 64), 404)) == ["task_id"]
    bad_query = client.get("/v1/tasks/" + "0" * 64, params={"grid_encoding": "png"})
    assert fields(problem(bad_query, 422)) == ["grid_encoding"]
    names = {p["name"] for p in operations(client.app.openapi())["get_task"][2]["parameters"]}  # type: ignore[attr-defined]
    assert {"task_id", "grid_encoding"} <= names


@pytest.mark.parametrize("tolerance", [1e12, 1e15])
def test_a_huge_tolerance_is_reported_against_tolerance(client: TestClient,
                                                        tolerance: float) -> None:
    r = client.post("/v1/arcs", json={"points": [[0, 0], [1, 0], [2, 1]],
                                      "tolerance": tolerance})
    assert fields(problem(r, 422)) == ["tolerance"]
    # points that really coincide are still the points' fault
    r = client.post("/v1/arcs", json={"points": [[3, 4], [3, 4]], "tolerance": 0.1})
    assert fields(problem(r, 422)) == ["points"]


@pytest.mark.parametrize(("content", "reason"), [
    (b"{not json", "malformed JSON"),
    (b'{"grid": "\xff\xfe"}', "utf-8"),
    (b'{"grid": ' + b"[" * 100_000 + b"]" * 100_000 + b"}", "nested too deeply|recursion"),
])
def test_every_400_is_typed_with_errors(client: TestClient, content: bytes,
                                        reason: str) -> None:
    for path, _body in BODIES.values():
        r = client.post(path, content=content, headers={"content-type": "application/json"})
        body = problem(r, 400)
        assert body["type"].endswith("/malformed-body")
        assert fields(body) == ["body"]
        assert re.search(reason, body["errors"][0]["reason"], re.I), body


def test_a_bad_content_length_is_a_typed_400(client: TestClient) -> None:
    r = client.post("/v1/mrr", content=b"{}", headers={"content-length": "ten"})
    body = problem(r, 400)
    assert fields(body) == ["Content-Length"] and body["type"].endswith("/malformed-header")


# -- offline docs --------------------------------------------------------------------------


class _Assets(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.urls: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.urls += [v for k, v in attrs if k in ("src", "href") and v]


@pytest.mark.parametrize("page", ["/docs", "/redoc"])
def test_docs_use_only_assets_the_service_serves(client: TestClient, page: str) -> None:
    r = client.get(page)
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/html")
    parser = _Assets()
    parser.feed(r.text)
    scripts = [u for u in parser.urls if u.endswith(".js")]
    assert scripts and parser.urls
    for url in parser.urls:
        assert url.startswith("/") and not url.startswith("//"), url
        asset = client.get(url)
        assert asset.status_code == 200 and len(asset.content) > 1000, url
    # no absolute URL anywhere in the page (fonts, CDNs), only the document it loads
    assert not re.findall(r"https?://", r.text), re.findall(r"https?://\S+", r.text)
    assert "/openapi.json" in r.text
    assert client.get("/openapi.json").json()["info"]["title"] == "zwplan"


# -- one log line per request --------------------------------------------------------------


def test_one_log_line_per_request_with_uvicorn_defaults() -> None:
    """Started as the image starts it (uvicorn's access log on, level info), each request
    writes exactly one line, the JSON one."""
    with live_server({"ZW_MAX_GRID_CELLS": "4096"}, uvicorn_args=()) as server, \
            httpx.Client(base_url=server.url, timeout=30) as http:
        ids = [f"one-line-{i}" for i in range(4)]
        http.get("/v1/tools", headers={"X-Request-ID": ids[0]})
        http.post("/v1/mrr", json={"grid": GRID}, headers={"X-Request-ID": ids[1]})
        http.post("/v1/mrr", content=b"{bad", headers={"X-Request-ID": ids[2],
                                                       "content-type": "application/json"})
        http.get("/v1/tasks/" + "0" * 64, headers={"X-Request-ID": ids[3]})
        # the line is written once the response is sent: wait for the last one
        deadline = time.monotonic() + 10
        while ids[-1] not in server.log_text() and time.monotonic() < deadline:
            time.sleep(0.05)
        log = server.log_text()
    lines = log.splitlines()
    for rid in ids:
        mine = [line for line in lines if rid in line]
        assert len(mine) == 1, mine
        entry = json.loads(mine[0])
        assert entry["msg"] == "request" and entry["request_id"] == rid
    for path in ("/v1/tools", "/v1/mrr", "/v1/tasks/"):
        # uvicorn's access line names the path without the request id; none may appear
        assert not [line for line in lines if path in line and not line.startswith("{")]
    assert TASK_ID.search(log)
