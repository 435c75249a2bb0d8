"""API keys: every /v1 operation needs one, health and metrics stay open, keys never leak.

The operations are read from the app's own OpenAPI document, so each one
that lands is covered here without touching this file.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from fastapi.testclient import TestClient

from tests.conftest import make_client
from tests.live_server import live_server

PROBLEM = "application/problem+json"
KEYS = ("alpha-key-1d5c8e", "beta-key-77f0aa")
WRONG = "gamma-key-0000ff"
GRID = {"dx": 1.0, "dy": 1.0, "z": [[0.0, 1.0, 2.0, 1.0], [1.0, 2.0, 3.0, 2.0],
                                    [0.0, 1.0, 2.0, 1.0], [0.0, 0.0, 1.0, 0.0]]}
ARC_POINTS = [[10 * math.cos(t / 20 * math.pi), 10 * math.sin(t / 20 * math.pi)]
              for t in range(21)]
# A valid body for each operation that takes one (by operationId).
BODIES: dict[str, dict[str, Any]] = {
    "compute_mrr": {"grid": GRID, "include_models": True},  # models: GET .../models/0
    "plan_scanline": {"grid": GRID, "tolerance": 0.1},
    "plan_contour": {"grid": GRID},
    "fit_arcs": {"points": ARC_POINTS, "tolerance": 0.05},
    "simulate": {"grid": GRID, "tool": {"kind": "ball", "diameter": 2.0, "flute_length": 4.0}},
}
# Operations whose body is not JSON: (query, media type, body).
RAW_BODIES: dict[str, tuple[str, str, bytes]] = {
    "create_zmap": ("?dx=0.5", "model/stl", b"solid t\nfacet normal 0 0 1\nouter loop\n"
                    b"vertex 0 0 0\nvertex 1 0 0\nvertex 0 1 1\nendloop\nendfacet\nendsolid t\n"),
}
OPEN_PATHS = ("/healthz", "/readyz", "/metrics")


def v1_operations(client: TestClient) -> list[tuple[str, str, dict[str, Any]]]:
    spec = client.app.openapi()  # type: ignore[attr-defined]
    ops = [(method.upper(), path, op) for path, item in spec["paths"].items()
           for method, op in item.items() if path.startswith("/v1/")]
    assert ops
    return ops


def call(client: TestClient, method: str, path: str, op: dict[str, Any],
         headers: dict[str, str], task_id: str) -> httpx.Response:
    url = path.replace("{task_id}", task_id).replace("{index}", "0")
    if op["operationId"] in RAW_BODIES:
        query, media, raw = RAW_BODIES[op["operationId"]]
        return client.request(method, url + query, content=raw,
                              headers={**headers, "content-type": media})
    if "requestBody" in op:
        assert op["operationId"] in BODIES, f"add a valid body for {op['operationId']}"
        return client.request(method, url, json=BODIES[op["operationId"]], headers=headers)
    return client.request(method, url, headers=headers)


def assert_problem(r: httpx.Response, status: int) -> dict[str, Any]:
    assert r.status_code == status, r.text
    assert r.headers["content-type"] == PROBLEM
    body: dict[str, Any] = r.json()
    assert body["status"] == status and body["title"] and body["detail"]
    return body


@pytest.fixture
def keyed(tmp_path: Path) -> Iterator[TestClient]:
    # Spaces around the keys are trimmed; both keys are valid.
    with make_client(tmp_path, api_keys=f" {KEYS[0]} , {KEYS[1]} ") as c:
        yield c


@pytest.fixture
def task_id(keyed: TestClient) -> str:
    # with its models, so that every operation on a task (previews too) has data to serve
    r = keyed.post("/v1/mrr", json={**BODIES["compute_mrr"], "include_models": True},
                   headers={"Authorization": f"Bearer {KEYS[0]}"})
    assert r.status_code == 200
    tid: str = r.json()["task_id"]
    return tid


def test_every_v1_operation_needs_a_key(keyed: TestClient, task_id: str) -> None:
    program = keyed.post("/v1/plans/scanline", json={"grid": GRID, "toolpaths": True},
                         headers={"Authorization": f"Bearer {KEYS[0]}"}).json()["task_id"]
    for method, path, op in v1_operations(keyed):
        # the program of a plan computed with tool paths; every other task: the fixture's
        tid = program if op["operationId"] == "get_program" else task_id
        for headers in ({}, {"Authorization": "Basic " + KEYS[0]},
                        {"Authorization": f"Token {KEYS[0]}"}, {"Authorization": "Bearer"}):
            r = call(keyed, method, path, op, headers, tid)
            body = assert_problem(r, 401)
            assert r.headers["www-authenticate"] == "Bearer", (path, headers)
            assert body["instance"] == path.replace("{task_id}", tid).replace("{index}", "0")
        for wrong in (WRONG, KEYS[0] + "x", KEYS[0][:-1], KEYS[0].upper(), f"{KEYS[0]},{KEYS[1]}"):
            r = call(keyed, method, path, op, {"Authorization": f"Bearer {wrong}"}, tid)
            assert_problem(r, 403)
            assert wrong not in r.text
        for key in KEYS:
            r = call(keyed, method, path, op, {"Authorization": f"Bearer {key}"}, tid)
            assert r.status_code == 200, (method, path, r.text)
            types = list(op["responses"]["200"].get("content", {"application/json": {}}))
            expected = "application/json" if "application/json" in types else types[0]
            assert r.headers["content-type"].startswith(expected)
            # The scheme is case-insensitive (RFC 7235).
            r = call(keyed, method, path, op, {"Authorization": f"bearer {key}"}, tid)
            assert r.status_code == 200, (method, path, r.text)


def test_auth_comes_before_body_parsing(keyed: TestClient) -> None:
    for method, path, op in v1_operations(keyed):
        if "requestBody" not in op:
            continue
        for body in (b"{not json", b"", b"[1, 2]", b'{"grid": 5}'):
            r = keyed.request(method, path, content=body,
                              headers={"content-type": "application/json"})
            assert_problem(r, 401)
            r = keyed.request(method, path, content=body,
                              headers={"content-type": "application/json",
                                       "Authorization": f"Bearer {WRONG}"})
            assert_problem(r, 403)
        # With the key, the same malformed body is the client's 400 (415 where the
        # operation takes no JSON at all).
        r = keyed.request(method, path, content=b"{not json",
                          headers={"content-type": "application/json",
                                   "Authorization": f"Bearer {KEYS[1]}"})
        json_body = "application/json" in op["requestBody"]["content"]
        assert_problem(r, 400 if json_body else 415)


@pytest.mark.parametrize(("authorization", "status"), [(None, 401), (f"Bearer {WRONG}", 403)])
def test_a_refused_call_is_answered_before_its_body_is_read(
        tmp_path: Path, authorization: str | None, status: int) -> None:
    """An unauthenticated client cannot make the server buffer a large body."""
    import asyncio

    from service.main import create_app
    from service.settings import Settings

    app = create_app(Settings(data_dir=tmp_path, api_keys=",".join(KEYS)))
    headers = [(b"content-type", b"application/json"), (b"content-length", b"200000000")]
    if authorization:
        headers.append((b"authorization", authorization.encode()))
    scope = {"type": "http", "asgi": {"version": "3.0"}, "http_version": "1.1",
             "method": "POST", "scheme": "http", "path": "/v1/mrr", "raw_path": b"/v1/mrr",
             "query_string": b"", "root_path": "", "headers": headers,
             "client": ("127.0.0.1", 1), "server": ("127.0.0.1", 80)}
    reads = 0
    sent: list[dict[str, Any]] = []

    async def receive() -> dict[str, Any]:
        nonlocal reads
        reads += 1
        return {"type": "http.request", "body": b"0" * 65536, "more_body": True}

    async def send(message: dict[str, Any]) -> None:
        sent.append(message)

    asyncio.run(app(scope, receive, send))  # type: ignore[arg-type]
    assert reads == 0
    assert sent[0]["status"] == status
    assert dict(sent[0]["headers"])[b"content-type"] == PROBLEM.encode()
    assert json.loads(sent[1]["body"])["status"] == status


def test_health_and_metrics_stay_open(keyed: TestClient) -> None:
    for path in OPEN_PATHS:
        for headers in ({}, {"Authorization": f"Bearer {WRONG}"}):
            r = keyed.get(path, headers=headers)
            assert r.status_code == 200, (path, r.text)
    assert keyed.get("/healthz").json() == {"status": "ok"}
    assert "zw_requests_total" in keyed.get("/metrics").text


def test_no_keys_configured_means_open(tmp_path: Path) -> None:
    with make_client(tmp_path) as c:
        r = c.post("/v1/mrr", json=BODIES["compute_mrr"])
        assert r.status_code == 200
        assert c.get("/v1/tools").status_code == 200
        # A stray header is harmless when auth is off.
        assert c.get("/v1/tools", headers={"Authorization": f"Bearer {WRONG}"}).status_code == 200


def test_keys_never_reach_the_logs_or_responses() -> None:
    env = {"ZW_API_KEYS": ",".join(KEYS), "ZW_MAX_GRID_CELLS": "4096"}
    with live_server(env) as server, httpx.Client(base_url=server.url, timeout=30) as http:
        bodies = []
        for key in (*KEYS, WRONG):
            auth = {"Authorization": f"Bearer {key}"}
            bodies.append(http.post("/v1/mrr", json=BODIES["compute_mrr"], headers=auth).text)
            bodies.append(http.get("/v1/tools", headers=auth).text)
            bodies.append(http.get("/v1/tasks/" + "a" * 64, headers=auth).text)
            bodies.append(http.post("/v1/mrr", content=b"{bad", headers=auth).text)
        bodies.append(http.get("/metrics").text)
        log = server.log_text()
    lines = [json.loads(line) for line in log.splitlines() if line.startswith("{")]
    assert len([e for e in lines if e.get("msg") == "request"]) >= 12
    for secret in (*KEYS, WRONG):
        assert secret not in log
        assert not [b for b in bodies if secret in b]
    assert not re.search(r"(?i)authorization|bearer", log)
