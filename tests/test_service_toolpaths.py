"""Plans with ``toolpaths: true`` over HTTP: the program is fetched, parsed back and
simulated here (independently of the response's own verification figures)."""

from __future__ import annotations

import base64

import numpy as np
import pytest
from fastapi.testclient import TestClient

from service.schemas.plans import ContourPlanResult, ScanlinePlanResult
from tests.conftest import make_client
from tests.test_service_errors import assert_problem
from tests.test_service_mrr import rows_grid
from zwcore import ZMap
from zwcore.grid.tools import Tool
from zwcore.toolpath import parse_program, simulate_program


def pocket(n: int = 33) -> np.ndarray:
    y, x = np.mgrid[0:n, 0:n] * 0.5
    r2 = (x - 8) ** 2 + (y - 8) ** 2
    return np.where(r2 < 25, -np.sqrt(np.maximum(25 - r2, 0)), 0.0)


TOOLS = [{"id": "B6", "diameter": 6, "flute_length": 12, "tool_number": 12, "feed": 900,
          "spindle_rpm": 8000},
         {"id": "B2", "diameter": 2, "flute_length": 4}]


def _program(client: TestClient, task_id: str) -> str:
    r = client.get(f"/v1/tasks/{task_id}/program")
    assert r.status_code == 200, r.text
    assert r.headers["content-type"].startswith("text/plain")
    assert "attachment" in r.headers["content-disposition"] and ".nc" in \
        r.headers["content-disposition"]
    return r.text


def test_scanline_plan_with_toolpaths_program_simulates_gouge_free(client: TestClient) -> None:
    part = pocket()
    r = client.post("/v1/plans/scanline", json={
        "grid": rows_grid(part), "tools": TOOLS, "tolerance": 0.05, "toolpaths": True})
    assert r.status_code == 200, r.text
    plan = ScanlinePlanResult.model_validate(r.json())
    tp = plan.toolpaths
    assert tp is not None and tp.verification is not None
    assert tp.clearance > plan.stock_top and tp.time_min > 0 and tp.length > 0
    text = _program(client, plan.task_id)
    assert len(text.encode()) == tp.program_bytes
    assert "T12 M6" in text and "G43 H12" in text and "S8000 M3" in text
    assert text.rstrip().endswith("%") and "M30" in text
    prog = parse_program(text)
    tools = {12: Tool("B6", "ball", 6.0, 12.0), 2: Tool("B2", "ball", 2.0, 4.0)}
    assert set(np.unique(prog.tool)) <= set(tools)
    chk = simulate_program(prog, tools, ZMap(part, 0.0, 0.0, 0.5, 0.5), plan.stock_top,
                           tolerance=0.05)
    assert chk.gouge <= 1e-9 and chk.rapid_in_material == 0.0
    ver = tp.verification
    assert ver.gouge <= 1e-9
    # the response's figures are those of the program simulated here; the tolerance is held
    # where the plan says it finishes: everywhere but the area its reach summary leaves
    assert ver.final_over_part_max == pytest.approx(chk.final_over_part_max, abs=1e-9)
    assert ver.finished_over_part_max <= ver.final_over_part_max
    assert ver.within_tolerance == (ver.finished_over_part_max <= 0.05)
    assert plan.reach is not None
    area = part.size * 0.5 * 0.5
    assert (1.0 - ver.finished_area_fraction) * area == pytest.approx(
        plan.reach.unreachable_area, abs=1e-9)
    # per-stage points in JSON are the program's end points
    first = tp.stages[0]
    pts = np.frombuffer(base64.b64decode(first.points_b64), "<f4").reshape(-1, 3)
    kinds = np.frombuffer(base64.b64decode(first.move_kinds_b64), "u1")
    assert len(pts) == len(kinds) == first.moves
    assert first.tool_number == 12 and first.feed == 900


def test_contour_plan_with_toolpaths_has_arcs_and_no_gouge(client: TestClient) -> None:
    n = 49
    y, x = np.mgrid[0:n, 0:n] * 0.5
    part = np.where((abs(x - 12) < 7) & (abs(y - 12) < 5), -5.0, 0.0)
    tools = [{"id": "F6", "diameter": 6, "flute_length": 13, "ramp_angle_deg": 5}]
    r = client.post("/v1/plans/contour", json={"grid": rows_grid(part), "tools": tools,
                                               "toolpaths": True, "tolerance": 0.02})
    assert r.status_code == 200, r.text
    plan = ContourPlanResult.model_validate(r.json())
    assert plan.toolpaths is not None and plan.toolpaths.verification is not None
    text = _program(client, plan.task_id)
    prog = parse_program(text)
    assert (prog.motion >= 2).any()
    chk = simulate_program(prog, {1: Tool("F6", "flat", 6.0, 13.0)},
                           ZMap(part, 0.0, 0.0, 0.5, 0.5), plan.stock_top, tolerance=0.02)
    assert chk.gouge <= 1e-9 and chk.rapid_in_material == 0.0


def test_program_of_a_plan_without_toolpaths_is_404(client: TestClient) -> None:
    r = client.post("/v1/plans/scanline", json={"grid": rows_grid(pocket(9))})
    assert r.status_code == 200
    r = client.get(f"/v1/tasks/{r.json()['task_id']}/program")
    assert_problem(r, 404, "task_id", "without tool paths")
    r = client.get(f"/v1/tasks/{'0' * 64}/program")
    assert_problem(r, 404, "task_id", "no stored result")


@pytest.mark.parametrize(("tool_field", "value"), [
    ("feed", 0), ("feed", -5), ("plunge_feed", 0), ("spindle_rpm", 0), ("ramp_angle_deg", 0),
    ("ramp_angle_deg", 90), ("ramp_angle_deg", 120), ("tool_number", 0)])
def test_tool_cutting_fields_out_of_range(client: TestClient, tool_field: str,
                                          value: float) -> None:
    tools = [{"id": "B6", "diameter": 6, "flute_length": 12, tool_field: value}]
    r = client.post("/v1/plans/scanline", json={"grid": rows_grid(pocket(9)), "tools": tools,
                                                "toolpaths": True})
    assert_problem(r, 422, f"tools[0].{tool_field}")


def test_clearance_below_stock_top(client: TestClient) -> None:
    r = client.post("/v1/plans/scanline", json={"grid": rows_grid(pocket(9)), "stock_top": 10,
                                                "clearance": 5, "toolpaths": True})
    assert_problem(r, 422, "clearance", "above the stock top")


def test_program_too_large_is_413(tmp_path) -> None:  # type: ignore[no-untyped-def]
    with make_client(tmp_path, max_program_bytes=2000) as c:
        r = c.post("/v1/plans/scanline", json={"grid": rows_grid(pocket(17)), "toolpaths": True})
        assert_problem(r, 413, "program", "2000 bytes")
