"""Property-based tests of every operation in openapi/openapi.json against a live server.

Schemathesis reads the committed document, so each operation that lands in
it (plans, arcs, ...) is fuzzed here without touching this file. All checks
run against a default server (no API keys); the exclusions are listed below, each
with its reason.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.live_server import ROOT, LiveServer, live_server

pytest.importorskip("schemathesis")

SPEC = ROOT / "openapi" / "openapi.json"
# A default server (no ZW_API_KEYS: the committed document declares no security), with
# small limits so every generated request is cheap: the 1 MB body limit bounds what the
# fuzzer can send, the cell and point limits bound the compute.
SERVER_ENV = {
    "ZW_MAX_GRID_CELLS": "4096",
    "ZW_MAX_POINTS": "2000",
    "ZW_MAX_TOOLS": "16",
    "ZW_MAX_BODY_BYTES": str(1 << 20),
    "ZW_WORKERS": "2",
    "ZW_MAX_PENDING": "16",
}
MAX_EXAMPLES = 40  # per operation and phase: ~30 s for twelve operations on two cores

_GRID_RULES = (
    "a grid's rows have equal length, it has at most ZW_MAX_GRID_CELLS nodes (a product "
    "of two sizes), and z_b64 decodes to shape x dtype bytes of finite heights; one more "
    "rule could be said but is not: exactly one of z (rows) or z_b64 with shape and dtype "
    "(an object-level oneOf, which openapi-python-client cannot parse: the generated client "
    "would lose the operation; the Grid description says it)")
#: Operations whose schema-valid requests the service may rightly refuse (4xx problem
#: naming the field), because the rule cannot be said in JSON Schema. The
#: ``positive_data_acceptance`` check is off for exactly these; every other check, and
#: every check on every other operation, stays on.
POSITIVE_DATA_EXCLUSIONS: dict[str, str] = {
    "compute_mrr": _GRID_RULES + ".",
    "plan_scanline": _GRID_RULES + "; stock_top lies at or above the part's top (a "
    "property of the heights sent).",
    "plan_contour": _GRID_RULES + "; stock depth over the smallest tool step stays within "
    "ZW_MAX_CONTOUR_SLABS (a ratio of the heights and the tools sent).",
    "simulate": _GRID_RULES + "; stock and cl grids have the part's shape, origin and "
    "spacing, the stock lies at or above the part, stock_top at or above the part's top "
    "(relations between arrays sent).",
    "create_zmap": "the body is an STL file holding triangles (a binary or text file format, "
    "not JSON), and the grid it asks for has at most ZW_MAX_GRID_CELLS nodes (nx x ny, or "
    "the mesh's extent over dx x dy).",
    "fit_arcs": "the curve has two points that differ by more than 1e-9 tolerances, and its "
    "length over the tolerance stays within ZW_MAX_ARC_RESOLUTION (a sum over the points "
    "divided by another field).",
}


def _operations() -> list[tuple[str, str, dict[str, object]]]:
    spec = json.loads(SPEC.read_text())
    return [(method.upper(), path, op) for path, item in spec["paths"].items()
            for method, op in item.items() if isinstance(op, dict) and "operationId" in op]


def _config(tmp_path: Path) -> Path:
    """schemathesis.toml: every check on, with the exclusions listed above.

    ``[checks] enabled = true`` is ``--checks all``; on the command line that flag
    would override the per-operation exclusions, so it lives here.
    """
    lines = ["[checks]", "enabled = true", "", "[warnings]", "fail-on = []", ""]
    for operation_id in POSITIVE_DATA_EXCLUSIONS:
        lines += ["[[operations]]", f'include-operation-id = "{operation_id}"',
                  "checks.positive_data_acceptance.enabled = false", ""]
    path = tmp_path / "schemathesis.toml"
    path.write_text("\n".join(lines))
    return path


def test_exclusions_are_exactly_the_operations_with_unexpressible_rules() -> None:
    """A new operation gets every check, positive data included, until someone adds it
    here with its reason; a removed one leaves no stale exclusion behind."""
    ids = {str(op["operationId"]) for _m, _p, op in _operations()}
    assert set(POSITIVE_DATA_EXCLUSIONS) <= ids
    # the operations without a body (get_task, list_tools, health) keep the check
    assert not {"get_task", "list_tools", "get_health"} & set(POSITIVE_DATA_EXCLUSIONS)
    assert all(reason.strip() for reason in POSITIVE_DATA_EXCLUSIONS.values())


def test_default_document_requires_no_key() -> None:
    """The committed document is the default server's: no security requirement, so
    schemathesis (and generated clients) call it without credentials."""
    assert not [op["operationId"] for _m, _p, op in _operations() if op.get("security")]


API_KEY = "st-test-key"


def test_spec_lists_the_core_operations() -> None:
    ids = {op["operationId"] for _m, _p, op in _operations()}
    assert {"compute_mrr", "get_task", "list_tools", "get_health", "get_readiness",
            "get_metrics"} <= ids


def _run(server: LiveServer, tmp_path: Path, location: str, max_examples: int,
         extra: tuple[str, ...] = ()) -> str:
    config = _config(tmp_path)
    cmd = [sys.executable, "-m", "schemathesis.cli", "--config-file", str(config), "--no-color",
           "run", location, "--url", server.url, *extra,
           "--max-examples", str(max_examples), "--seed", "20240611",
           # A request this slow on these small limits is a failure (unbounded work per
           # request is a denial of service), reported as such instead of a hung run.
           "--max-response-time", "10", "--request-timeout", "30",
           # Shrinking replays failing cases many times; with a slow case that alone
           # would blow the time budget. The report still prints a curl reproduction.
           "--no-shrink", "--continue-on-failure", "--max-failures", "20",
           # One worker: schemathesis workers are threads, and concurrent ast.parse in
           # hypothesis (function descriptions) trips CPython 3.11's "AST constructor
           # recursion depth mismatch" SystemError (a thread-safety bug in CPython).
           "--workers", "1"]
    proc = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, timeout=170)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out[-20000:]
    # Every operation of the document was exercised, none was skipped as unreachable.
    n_ops = len(_operations())
    assert f"Tested: {n_ops}" in out, out[-3000:]
    assert "Errors:" not in out, out[-6000:]
    # Nothing the fuzzer sent reached a 5xx, which the server log would show.
    log_lines = [json.loads(line) for line in server.log_text().splitlines()
                 if line.startswith("{")]
    statuses = [e["status"] for e in log_lines if e.get("msg") == "request"]
    assert len(statuses) > 5 * n_ops
    assert not [s for s in statuses if s >= 500 and s != 503], "server errors in the log"
    return out


@pytest.mark.timeout(180)
def test_every_operation_passes_all_checks(tmp_path: Path) -> None:
    """The committed document against a default server, without credentials."""
    with live_server(SERVER_ENV) as server:
        _run(server, tmp_path, str(SPEC), MAX_EXAMPLES)


@pytest.mark.timeout(180)
def test_a_keyed_server_passes_all_checks_on_its_served_document(tmp_path: Path) -> None:
    """With ZW_API_KEYS set, the served /openapi.json requires the bearer scheme, and the
    auth checks (a call without or with a wrong key must be refused) hold. Fewer
    examples: the operations' bodies are fuzzed in full above."""
    with live_server({**SERVER_ENV, "ZW_API_KEYS": f"{API_KEY},second-key"}) as server:
        _run(server, tmp_path, server.url + "/openapi.json", MAX_EXAMPLES // 8,
             ("--header", f"Authorization: Bearer {API_KEY}"))
