"""Request ids, structured access logs, Prometheus metrics, load shedding, opaque 5xx."""

from __future__ import annotations

import json
import re
import threading
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import httpx
import pytest
from fastapi.testclient import TestClient
from prometheus_client.parser import text_string_to_metric_families

from service.routers import mrr as mrr_router
from tests.conftest import make_client
from tests.live_server import LiveServer, live_server

PROBLEM = "application/problem+json"
MARKER = 987.654321  # a height no log line may contain


def grid(seed: float = 0.0, n: int = 6) -> dict[str, Any]:
    z = [[seed + float((i * 5 + k * 3) % 7) for k in range(n)] for i in range(n)]
    return {"grid": {"dx": 1.0, "dy": 1.0, "z": z}}


def samples(text: str) -> dict[tuple[str, tuple[tuple[str, str], ...]], float]:
    """Every sample of a Prometheus exposition, keyed by name and sorted labels."""
    out = {}
    for family in text_string_to_metric_families(text):
        for s in family.samples:
            out[(s.name, tuple(sorted(s.labels.items())))] = s.value
    return out


def access_lines(log: str) -> list[dict[str, Any]]:
    entries = [json.loads(line) for line in log.splitlines() if line.startswith("{")]
    return [e for e in entries if e.get("logger") == "zwplan.access" and e["msg"] == "request"]


@pytest.fixture(scope="module")
def server() -> Iterator[LiveServer]:
    with live_server({"ZW_MAX_GRID_CELLS": "4096", "ZW_WORKERS": "2",
                      "ZW_PROCESS_WORKERS": "1", "ZW_MAX_PENDING": "3"}) as s:
        yield s


def test_request_id_given_or_generated(server: LiveServer) -> None:
    with httpx.Client(base_url=server.url) as http:
        for path in ("/healthz", "/v1/tools", "/v1/tasks/" + "0" * 64, "/nowhere"):
            r = http.get(path, headers={"X-Request-ID": "trace-42.abc"})
            assert r.headers["x-request-id"] == "trace-42.abc", path
        generated = {http.get("/healthz").headers["x-request-id"] for _ in range(3)}
        assert len(generated) == 3
        assert all(re.fullmatch(r"[0-9a-f]{32}", g) for g in generated)
        # An over-long id is cut, so a client cannot blow up log lines.
        long_id = "x" * 500
        assert http.get("/healthz", headers={"X-Request-ID": long_id}).headers[
            "x-request-id"] == "x" * 128
        # Errors made by the middleware itself carry it too.
        r = http.post("/v1/mrr", content=b"{", headers={"X-Request-ID": "bad-json-1",
                                                        "content-type": "application/json"})
        assert r.status_code == 400 and r.headers["x-request-id"] == "bad-json-1"


def test_access_log_is_json_with_ids_outcomes_and_timings(server: LiveServer) -> None:
    body = grid(MARKER)
    with httpx.Client(base_url=server.url, timeout=30) as http:
        first = http.post("/v1/mrr", json=body, headers={"X-Request-ID": "log-miss"})
        second = http.post("/v1/mrr", json=body, headers={"X-Request-ID": "log-hit"})
        tid = first.json()["task_id"]
        got = http.get(f"/v1/tasks/{tid}", headers={"X-Request-ID": "log-task"})
        bad = http.post("/v1/mrr", json={"grid": {"dx": 1, "dy": 1, "z": [[MARKER, 1], [2]]}},
                        headers={"X-Request-ID": "log-bad"})
    assert (first.status_code, second.status_code, got.status_code, bad.status_code) == (
        200, 200, 200, 422)
    # the access line is written once the response has gone out: the client can read the
    # answer before the server's logging thread has flushed its line
    wanted = {"log-miss", "log-hit", "log-task", "log-bad"}
    deadline = time.monotonic() + 10.0
    while True:
        log = server.log_text()
        by_id = {e["request_id"]: e for e in access_lines(log)}
        if wanted <= by_id.keys() or time.monotonic() > deadline:
            break
        time.sleep(0.05)
    miss, hit, task, invalid = (by_id[k] for k in ("log-miss", "log-hit", "log-task", "log-bad"))
    assert miss["operation"] == "compute_mrr" and miss["task_id"] == tid
    assert miss["cache"] == "miss" and miss["status"] == 200
    assert miss["ms"] > 0 and miss["compute_ms"] is not None
    assert 0 <= miss["compute_ms"] <= miss["ms"]
    assert hit["cache"] == "hit" and hit["task_id"] == tid and hit["compute_ms"] is None
    assert task["operation"] == "get_task" and task["cache"] == "hit" and task["task_id"] == tid
    assert invalid["status"] == 422 and invalid["path"] == "/v1/mrr"
    for entry in (miss, hit, task, invalid):
        assert entry["level"] == "info" and isinstance(entry["ts"], float)
        assert entry["method"] in ("GET", "POST")
    # No body content, request or response, in any log line.
    assert str(MARKER) not in log and "987.65" not in log
    assert '"z"' not in log and "levels" not in log


def test_metrics_exposition(server: LiveServer) -> None:
    with httpx.Client(base_url=server.url, timeout=30) as http:
        body = grid(3.0)
        assert http.post("/v1/mrr", json=body).headers["x-cache"] == "miss"
        assert http.post("/v1/mrr", json=body).headers["x-cache"] == "hit"
        assert http.get("/v1/tools").status_code == 200
        arcs = http.post("/v1/arcs", json={"points": [[0, 0], [10, 0], [20, 5]]})
        assert arcs.status_code == 200, arcs.text
        r = http.get("/metrics")
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/plain")
    m = samples(r.text)
    assert m[("zw_requests_total", (("operation", "compute_mrr"), ("status", "200")))] >= 2
    assert m[("zw_requests_total", (("operation", "list_tools"), ("status", "200")))] >= 1
    assert m[("zw_request_seconds_count", (("operation", "compute_mrr"),))] >= 2
    assert m[("zw_request_seconds_sum", (("operation", "compute_mrr"),))] > 0
    assert m[("zw_compute_seconds_count", (("operation", "compute_mrr"),))] >= 1
    assert m[("zw_cache_total", (("operation", "compute_mrr"), ("outcome", "hit")))] >= 1
    assert m[("zw_cache_total", (("operation", "compute_mrr"), ("outcome", "miss")))] >= 1
    # every family names an operation by its OpenAPI operation id
    assert m[("zw_requests_total", (("operation", "fit_arcs"), ("status", "200")))] == 1
    assert m[("zw_compute_seconds_count", (("operation", "fit_arcs"),))] == 1
    assert m[("zw_cache_total", (("operation", "fit_arcs"), ("outcome", "miss")))] == 1
    assert m[("zw_pool_busy", ())] == 0
    # grid work: ZW_WORKERS + ZW_MAX_PENDING; arc fits: ZW_PROCESS_WORKERS + ZW_MAX_PENDING
    assert m[("zw_pool_capacity", ())] == (2 + 3) + (1 + 3)
    assert ("zw_pool_shed_total", ()) in m


@pytest.fixture
def gated(monkeypatch: pytest.MonkeyPatch) -> Iterator[tuple[threading.Event, threading.Event]]:
    """Make /v1/mrr's computation wait for ``release`` after signalling ``entered``."""
    entered, release = threading.Event(), threading.Event()
    real = mrr_router.mrr_result

    def slow(*args: Any, **kwargs: Any) -> dict[str, Any]:
        entered.set()
        assert release.wait(30), "test never released the computation"
        return real(*args, **kwargs)

    monkeypatch.setattr(mrr_router, "mrr_result", slow)
    yield entered, release
    release.set()


def test_full_pool_sheds_with_503_and_retry_after(
        tmp_path: Path, gated: tuple[threading.Event, threading.Event]) -> None:
    entered, release = gated
    with make_client(tmp_path, workers=1, process_workers=1, max_pending=0) as client, \
            ThreadPoolExecutor(2) as threads:
        before = samples(client.get("/metrics").text).get(("zw_pool_shed_total", ()), 0.0)
        first = threads.submit(client.post, "/v1/mrr", json=grid(1.0))
        assert entered.wait(10)
        ready = client.get("/readyz").json()
        # one grid thread (taken) and one arc worker process (free)
        assert (ready["pool_busy"], ready["pool_capacity"]) == (1, 2)

        shed = client.post("/v1/mrr", json=grid(2.0), headers={"X-Request-ID": "shed-1"})
        assert shed.status_code == 503
        assert shed.headers["content-type"] == PROBLEM
        assert shed.headers["retry-after"] == "1"
        assert shed.headers["x-request-id"] == "shed-1"
        problem = shed.json()
        assert problem["status"] == 503 and problem["type"].endswith("/busy")

        # The same request as the one in flight is not shed: it joins that computation.
        twin = threads.submit(client.post, "/v1/mrr", json=grid(1.0))
        time.sleep(0.5)  # let it reach the pool while the first still holds it
        release.set()
        r1, r2 = first.result(30), twin.result(30)
        assert r1.status_code == r2.status_code == 200
        assert r1.headers["x-cache"] == "miss"
        # "shared" when it arrived in time (nearly always); "hit" if it came after.
        assert r2.headers["x-cache"] in ("shared", "hit")
        assert r1.json() == r2.json()

        after = samples(client.get("/metrics").text)
        assert after[("zw_pool_shed_total", ())] == before + 1
        assert after[("zw_pool_busy", ())] == 0
        # With the pool free again the shed request goes through.
        assert client.post("/v1/mrr", json=grid(2.0)).status_code == 200


INTERNALS = re.compile(r"Traceback|File \"|\.py\b|/work/|site-packages|RuntimeError|line \d+")


def test_errors_carry_no_trace_or_internal_path(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    def explode(*args: Any, **kwargs: Any) -> dict[str, Any]:
        raise RuntimeError(f"secret state in {mrr_router.__file__}")

    monkeypatch.setattr(mrr_router, "mrr_result", explode)
    with TestClient(make_client(tmp_path, max_body_bytes=4096).app,
                    raise_server_exceptions=False) as client:
        crash = client.post("/v1/mrr", json=grid(5.0), headers={"X-Request-ID": "crash-1"})
        assert crash.status_code == 500
        assert crash.headers["content-type"] == PROBLEM
        assert crash.headers["x-request-id"] == "crash-1"
        assert crash.json()["status"] == 500 and crash.json()["title"] == "Internal error"
        others = [
            client.post("/v1/mrr", content=b"{oops", headers={"content-type": "application/json"}),
            client.post("/v1/mrr", json={"grid": {"dx": 1, "dy": 1, "z": [[0, 1], [0]]}}),
            client.post("/v1/mrr", content=b"x" * 5000),
            client.get("/v1/tasks/not-a-task-id"),
            client.get("/v1/tasks/" + "f" * 64),
            client.delete("/v1/mrr"),
            client.get("/nowhere"),
        ]
        assert [r.status_code for r in others] == [400, 422, 413, 422, 404, 405, 404]
        for r in [crash, *others]:
            assert r.headers["content-type"] == PROBLEM, r.request.url
            assert not INTERNALS.search(r.text), r.text
            assert "secret state" not in r.text
    # ... while the log keeps the trace for whoever debugs it.
    err = capsys.readouterr().err
    assert "secret state" in err and "Traceback" in err
