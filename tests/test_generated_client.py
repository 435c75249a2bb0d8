"""A client generated from openapi/openapi.json by openapi-python-client works against the service.

The generator must run without a single warning (every schema named, every
response typed), produce a module for every operation of the document, and
the generated calls must round-trip real requests on a live server, errors
included (problem documents parse as ``ProblemDetails``).
"""

from __future__ import annotations

import importlib
import json
import math
import os
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

from tests.live_server import ROOT, LiveServer, live_server

pytest.importorskip("openapi_python_client")

SPEC_PATH = ROOT / "openapi" / "openapi.json"
SPEC: dict[str, Any] = json.loads(SPEC_PATH.read_text())
PACKAGE = "zwplan_generated_client"
API_KEY = "client-test-key"


def _snake(name: str) -> str:
    return re.sub(r"[^0-9a-zA-Z]+", "_", re.sub(r"(?<=[a-z0-9])(?=[A-Z])", "_", name)).lower()


def _operations() -> dict[str, tuple[str, str, dict[str, Any]]]:
    """operationId -> (method, path, operation)."""
    return {op["operationId"]: (method, path, op) for path, item in SPEC["paths"].items()
            for method, op in item.items() if isinstance(op, dict) and "operationId" in op}


@pytest.fixture(scope="module")
def generated(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[ModuleType, str]]:
    """Generate the client into a temp dir and import it; yields the package and the log."""
    out_dir = tmp_path_factory.mktemp("client")
    env = dict(os.environ)
    # The generator formats its output with ruff (a test dependency) if it is on PATH;
    # without it, it warns, and this test accepts no warnings.
    env["PATH"] = str(Path(sys.executable).parent) + os.pathsep + env.get("PATH", "")
    # Binary bodies (.npy grids, STL, PNG previews) are bytes to a client: the generator's
    # documented override maps their media types onto the one it knows.
    config = out_dir / "config.json"
    config.write_text(json.dumps({"content_type_overrides": {
        "application/x-npy": "application/octet-stream",
        "model/stl": "application/octet-stream",
        "image/png": "application/octet-stream"}}))  # previews
    proc = subprocess.run(
        [sys.executable, "-m", "openapi_python_client", "generate", "--path", str(SPEC_PATH),
         "--output-path", str(out_dir / PACKAGE), "--meta", "none", "--fail-on-warning",
         "--config", str(config)],
        capture_output=True, text=True, cwd=out_dir, env=env, timeout=120)
    log = proc.stdout + proc.stderr
    assert proc.returncode == 0, log
    sys.path.insert(0, str(out_dir))
    try:
        yield importlib.import_module(PACKAGE), log
    finally:
        sys.path.remove(str(out_dir))
        for name in [m for m in sys.modules if m == PACKAGE or m.startswith(PACKAGE + ".")]:
            del sys.modules[name]


@pytest.fixture(scope="module")
def server() -> Iterator[LiveServer]:
    with live_server({"ZW_API_KEYS": API_KEY, "ZW_MAX_GRID_CELLS": "4096",
                      "ZW_MAX_POINTS": "2000"}) as s:
        yield s


def op_module(operation_id: str) -> ModuleType:
    _method, _path, op = _operations()[operation_id]
    tag = _snake(op["tags"][0]) if op.get("tags") else "default"
    return importlib.import_module(f"{PACKAGE}.api.{tag}.{_snake(operation_id)}")


def model(name: str) -> Any:
    return getattr(importlib.import_module(f"{PACKAGE}.models"), name)


def request_model(operation_id: str) -> Any:
    """The generated class of an operation's JSON body, by its schema's name."""
    _m, _p, op = _operations()[operation_id]
    ref = op["requestBody"]["content"]["application/json"]["schema"]["$ref"]
    return model(ref.rsplit("/", 1)[1])


def needs(operation_id: str) -> None:
    if operation_id not in _operations():
        pytest.skip(f"{operation_id} is not in openapi/openapi.json yet")


@pytest.fixture
def client(generated: tuple[ModuleType, str], server: LiveServer) -> Any:
    pkg, _log = generated
    return pkg.AuthenticatedClient(base_url=server.url, token=API_KEY, timeout=30.0)


def test_generation_is_clean_and_covers_every_operation(
        generated: tuple[ModuleType, str]) -> None:
    _pkg, log = generated
    assert "warning" not in log.lower(), log
    for operation_id in _operations():
        module = op_module(operation_id)
        assert callable(module.sync_detailed), operation_id
    # Problem responses are typed, not Any: the document puts ProblemDetails under
    # the media type the service actually sends.
    assert "ProblemDetails" in Path(op_module("compute_mrr").__file__ or "").read_text()


def test_health_readiness_metrics(client: Any) -> None:
    health = op_module("get_health").sync_detailed(client=client)
    assert health.status_code == 200 and health.parsed.status == "ok"
    ready = op_module("get_readiness").sync_detailed(client=client)
    assert ready.status_code == 200
    assert ready.parsed.status == "ok" and ready.parsed.cache_kind == "embedded"
    assert ready.parsed.pool_capacity >= 1
    metrics = op_module("get_metrics").sync_detailed(client=client)
    assert metrics.status_code == 200
    assert isinstance(metrics.parsed, str) and "zw_requests_total" in metrics.parsed


def test_tools(client: Any) -> None:
    r = op_module("list_tools").sync_detailed(client=client)
    assert r.status_code == 200
    kinds = {t.kind.value for t in r.parsed.tools}
    assert kinds == {"ball", "flat"}
    assert all(t.diameter > 0 and t.flute_length > 0 for t in r.parsed.tools)


def test_mrr_then_task(client: Any) -> None:
    z = [[float((i - 3) ** 2 + (k - 4) ** 2) / 10 for k in range(9)] for i in range(7)]
    body = request_model("compute_mrr").from_dict(
        {"grid": {"dx": 0.5, "dy": 0.5, "z": z}, "wavelet": "single_knot",
         "include_models": True})
    r = op_module("compute_mrr").sync_detailed(client=client, body=body)
    assert r.status_code == 200, r.content
    result = r.parsed
    assert re.fullmatch(r"[0-9a-f]{64}", result.task_id)
    assert result.operation == "mrr" and result.wavelet.value == "single_knot"
    finest = result.levels[-1]
    assert (finest.ny, finest.nx) == (7, 9)
    assert finest.grid.z == z  # the input comes back exactly, in the rows encoding sent
    assert all(level.containment_margin >= 0 for level in result.levels)

    got = op_module("get_task").sync_detailed(result.task_id, client=client)
    assert got.status_code == 200
    assert got.parsed.task_id == result.task_id
    assert got.headers["x-cache"] == "hit"
    assert [lv.nx for lv in got.parsed.levels] == [lv.nx for lv in result.levels]


def test_errors_parse_as_problems(generated: tuple[ModuleType, str], client: Any,
                                  server: LiveServer) -> None:
    pkg, _log = generated
    problem_cls = model("ProblemDetails")
    missing = op_module("get_task").sync_detailed("0" * 64, client=client)
    assert missing.status_code == 404
    assert isinstance(missing.parsed, problem_cls) and missing.parsed.status == 404

    ragged = request_model("compute_mrr").from_dict(
        {"grid": {"dx": 1, "dy": 1, "z": [[0, 1, 2], [0, 1]]}})
    bad = op_module("compute_mrr").sync_detailed(client=client, body=ragged)
    assert bad.status_code == 422
    assert isinstance(bad.parsed, problem_cls)
    assert any(e.field == "grid.z[1]" for e in bad.parsed.errors)

    wrong = pkg.AuthenticatedClient(base_url=server.url, token="not-the-key")
    denied = op_module("list_tools").sync_detailed(client=wrong)
    assert denied.status_code == 403 and isinstance(denied.parsed, problem_cls)
    # The token goes into a header the service ignores: no Authorization at all.
    anonymous = pkg.AuthenticatedClient(base_url=server.url, token="x",
                                        auth_header_name="X-Not-Authorization")
    unauth = op_module("list_tools").sync_detailed(client=anonymous)
    assert unauth.status_code == 401 and unauth.parsed.status == 401


def _bowl(n: int = 24) -> list[list[float]]:
    c = (n - 1) / 2
    return [[round(0.05 * ((i - c) ** 2 + (k - c) ** 2), 6) for k in range(n)] for i in range(n)]


def test_plan_scanline(client: Any) -> None:
    needs("plan_scanline")
    body = request_model("plan_scanline").from_dict(
        {"grid": {"dx": 1.0, "dy": 1.0, "z": _bowl()}, "tolerance": 0.05,
         "include_models": True})
    r = op_module("plan_scanline").sync_detailed(client=client, body=body)
    assert r.status_code == 200, r.content
    plan = r.parsed
    assert plan.operation == "plan_scanline" and re.fullmatch(r"[0-9a-f]{64}", plan.task_id)
    assert plan.stages and plan.tool_sequence
    assert plan.checks.containment is True
    # The sequence is the stages' tools in machining order, each once.
    assert list(dict.fromkeys(s.tool.id for s in plan.stages)) == plan.tool_sequence


def test_plan_contour(client: Any) -> None:
    needs("plan_contour")
    body = request_model("plan_contour").from_dict(
        {"grid": {"dx": 1.0, "dy": 1.0, "z": _bowl()}, "include_models": False})
    r = op_module("plan_contour").sync_detailed(client=client, body=body)
    assert r.status_code == 200, r.content
    plan = r.parsed
    assert plan.operation == "plan_contour" and plan.stages
    assert plan.checks.containment is True
    for stage in plan.stages:
        assert stage.z_levels == sorted(stage.z_levels, reverse=True)


def test_fit_arcs(client: Any) -> None:
    needs("fit_arcs")
    points = [[round(20 * math.cos(t / 40 * math.pi), 6), round(20 * math.sin(t / 40 * math.pi), 6)]
              for t in range(41)]
    body = request_model("fit_arcs").from_dict(
        {"points": points, "tolerance": 0.01, "gcode": True})
    r = op_module("fit_arcs").sync_detailed(client=client, body=body)
    assert r.status_code == 200, r.content
    result = r.parsed
    assert result.operation == "arcs" and result.segments
    assert {s.kind.value for s in result.segments} <= {"arc", "line"}
    assert result.summary.max_deviation_points <= 0.01 + 1e-9
    assert isinstance(result.gcode, str) and result.gcode.strip()
