"""POST /v1/arcs with a G-code program or a DXF drawing as the body."""

from __future__ import annotations

import io

import ezdxf
import pytest
from fastapi.testclient import TestClient

from service.schemas.cadfiles import DxfArcsResult, GcodeArcsResult
from tests.conftest import make_client
from tests.nc_reader import read_moves, two_sided
from tests.test_dxf import TOL, by_layer, drawing
from tests.test_gcode_program import known_program
from tests.test_service_errors import assert_problem

PLAIN = {"content-type": "text/plain"}


@pytest.fixture
def client(tmp_path):  # type: ignore[no-untyped-def]
    # fits in the threads: worker processes start once, in the one test that needs them
    with make_client(tmp_path, process_workers=0) as c:
        yield c


@pytest.fixture
def process_client(tmp_path):  # type: ignore[no-untyped-def]
    with make_client(tmp_path) as c:
        yield c
DXF = {"content-type": "application/dxf"}


def test_program_is_rewritten_with_a_summary(process_client: TestClient) -> None:
    # in a worker process: the program, the result and any error cross the process boundary
    client = process_client
    text, runs = known_program()
    r = client.post("/v1/arcs?tolerance=0.01", content=text, headers=PLAIN)
    assert r.status_code == 200, r.text
    res = GcodeArcsResult.model_validate(r.json())
    moves_in, moves_out = read_moves(text), read_moves(res.program)
    assert res.summary.moves_before == len(moves_in)
    assert res.summary.moves_after == len(moves_out) < len(moves_in) / 20
    assert res.summary.bytes_before == len(text.encode())
    assert res.summary.bytes_after == len(res.program.encode())
    assert res.summary.runs == res.summary.runs_rewritten == len(runs)
    assert 0 < res.summary.max_deviation <= 0.01
    assert res.summary.unparsable_lines == 0
    # the program alone, and the same again from the cache
    again = client.post("/v1/arcs?tolerance=0.01", content=text,
                        headers={**PLAIN, "accept": "text/plain"})
    assert again.status_code == 200 and again.headers["x-cache"] == "hit"
    assert again.headers["content-type"].startswith("text/plain")
    assert again.text == res.program
    assert client.get(f"/v1/tasks/{res.task_id}").json()["program"] == res.program


SMALL_PROGRAM = "G90 G17\nG00 X0 Y0 Z0\n#1 = [2 * 3]\nG01 X1 Y0 F100\nX2 Y0\nX3 Y0.001\nM30\n"


def test_unparsable_lines_are_counted(client: TestClient) -> None:
    text = SMALL_PROGRAM
    r = client.post("/v1/arcs", content=text, headers=PLAIN)
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["summary"]["unparsable_lines"] == 1
    assert body["summary"]["unparsable_line_numbers"] == [3]
    assert "#1 = [2 * 3]" in body["program"].splitlines()
    assert body["notes"]


def test_dxf_round_trip_over_http(client: TestClient) -> None:
    data = drawing()
    r = client.post(f"/v1/arcs?tolerance={TOL}", content=data, headers=DXF)
    assert r.status_code == 200, r.text
    res = DxfArcsResult.model_validate(r.json())
    assert res.summary.entities["SPLINE"] == 1 and res.summary.n_arcs > 0
    want, got = by_layer(data), by_layer(res.dxf)
    for layer in want:
        d_in, d_out = two_sided(want[layer], got[layer])
        assert max(d_in, d_out) <= TOL + 0.002, layer
    file = client.post(f"/v1/arcs?tolerance={TOL}", content=data,
                       headers={**DXF, "accept": "application/dxf"})
    assert file.status_code == 200 and file.headers["content-type"].startswith("application/dxf")
    assert {e.dxftype() for e in ezdxf.read(io.StringIO(file.text)).modelspace()} <= {
        "LINE", "ARC", "CIRCLE"}


def _only_lines() -> bytes:
    doc = ezdxf.new("R2010")
    doc.modelspace().add_line((0, 0), (1, 1))
    out = io.StringIO()
    doc.write(out)
    return out.getvalue().encode()


def test_bad_files_are_problems(client: TestClient) -> None:
    assert_problem(client.post("/v1/arcs", content=b"\x00\xff garbage", headers=PLAIN),
                   422, "body", "parses as G-code")
    assert_problem(client.post("/v1/arcs", content=b"", headers=PLAIN), 422, "body")
    assert_problem(client.post("/v1/arcs", content=_only_lines(), headers=DXF),
                   422, "body", "no LWPOLYLINE")
    assert_problem(client.post("/v1/arcs", content=b"garbage", headers=DXF),
                   422, "body", "not a readable DXF")
    assert_problem(client.post("/v1/arcs?tolerance=0", content=b"G01 X1", headers=PLAIN),
                   422, "query.tolerance")
    assert_problem(client.post("/v1/arcs?tolerance=1e-9", content=known_program()[0],
                               headers=PLAIN), 413, "tolerance")
    assert_problem(client.post("/v1/arcs", content=b"x", headers={"content-type": "image/png"}),
                   415, "content-type")
    assert_problem(client.post("/v1/arcs?tolerance=1", json={"points": [[0, 0], [1, 1]]}),
                   422, "query")


def test_octet_stream_is_told_apart(client: TestClient) -> None:
    octet = {"content-type": "application/octet-stream"}
    r = client.post("/v1/arcs", content=drawing(), headers=octet)
    assert r.status_code == 200 and r.json()["operation"] == "arcs_dxf"
    r = client.post("/v1/arcs", content=SMALL_PROGRAM, headers=octet)
    assert r.status_code == 200 and r.json()["operation"] == "arcs_gcode"
