"""The plan operations over HTTP: bodies, the safety property on returned models, errors."""

from __future__ import annotations

import numpy as np
import pytest
from fastapi.testclient import TestClient

from service.schemas.plans import ContourPlanResult, ScanlinePlanResult
from tests.test_service_errors import assert_problem
from tests.test_service_mrr import grid_array, rows_grid
from zwcore import at_fine_nodes


def pocket_part(n: int = 33) -> np.ndarray:
    y, x = np.mgrid[0:n, 0:n] / (n - 1)
    pocket = (x - .5) ** 2 + (y - .5) ** 2 < .05
    return 6.0 * np.sin(2 * np.pi * x) * np.cos(np.pi * y) - 10.0 * pocket


def on_input(model: dict, part: np.ndarray, dx: float) -> np.ndarray:
    z = grid_array(model)
    scale = round(model["dx"] / dx)
    return at_fine_nodes(z, scale, part.shape, model["interpolation"])


def test_scanline_plan_models_never_cut_into_the_part(client: TestClient) -> None:
    part = pocket_part()
    r = client.post("/v1/plans/scanline", json={"grid": rows_grid(part), "include_models": True,
                                                "tolerance": 0.02})
    assert r.status_code == 200, r.text
    plan = ScanlinePlanResult.model_validate(r.json())
    assert plan.checks.ok and plan.stock_top_source == "default"
    assert plan.tool_sequence and plan.tool_sequence[-1] == plan.stages[-1].tool.id
    previous = np.full(part.shape, plan.stock_top)
    radii = [s.tool.diameter for s in plan.stages]
    assert radii == sorted(radii, reverse=True)
    for stage in plan.stages:
        assert stage.model is not None and stage.model.interpolation == "bilinear"
        here = on_input(stage.model.model_dump(), part, 0.5)
        assert (here - part).min() >= 0, "stage model below the part"
        depth = previous - here
        # Models nest except where the flute rule on the simulated stock lifted a stage;
        # the flute rule is on the simulated stock (the balls do not follow a model's
        # every node): tests/test_scanline_stock.py re-simulates it independently.
        assert depth.min() >= -1e-12 or stage.sim_lifted_nodes > 0
        assert stage.sim_max_depth_of_cut <= stage.tool.flute_length
        assert stage.sim_gouge == 0.0 and stage.sim_positions > 0
        previous = here
    np.testing.assert_allclose(previous, part, atol=1e-9)
    assert plan.stages[-1].scallop_height <= 0.02 + 1e-12


def test_scanline_path_length_counts_the_lines(client: TestClient) -> None:
    # A flat plate: no extra lines, so each stage's path is its grid lines run
    # whole, in the shorter direction: 17 lines of 4 mm (along y) against 9 of
    # 8 mm (along x). A steep boss then adds lines only near itself.
    plate = np.zeros((9, 17))
    ball = [{"id": "B1", "diameter": 1.0, "flute_length": 5.0}]
    r = client.post("/v1/plans/scanline", json={"grid": rows_grid(plate), "tools": ball,
                                                "tolerance": 0.1, "stock_top": 1.0})
    assert r.status_code == 200, r.text
    last = r.json()["stages"][-1]
    assert last["scan_direction"] == "y" and last["scan_lines"] == 17
    assert last["path_length"] == pytest.approx(17 * 4.0)
    assert last["path_length_whole_strips"] == last["path_length"]
    assert last["extra_segments"] == 0
    boss = np.zeros((65, 65))
    boss[28:37, 28:37] = 4.0  # 4 mm square, its walls one cell wide
    r = client.post("/v1/plans/scanline", json={"grid": rows_grid(boss), "tools": ball,
                                                "tolerance": 0.1, "stock_top": 5.0})
    assert r.status_code == 200, r.text
    plan = ScanlinePlanResult.model_validate(r.json())
    last = plan.stages[-1]
    assert last.pick_feed_reduced and last.extra_segments > 0
    nominal = 65 * 32.0  # the grid lines, 32 mm each
    assert nominal < last.path_length < last.path_length_whole_strips
    # The extra lines cross the 4 mm boss plus a radius either side, not 32 mm.
    assert last.path_length - nominal < 0.25 * (last.path_length_whole_strips - nominal)


def test_contour_plan_terraces_contain_the_part(client: TestClient) -> None:
    part = pocket_part(32)
    tools = [{"id": "F8", "diameter": 8, "flute_length": 6},
             {"id": "F3", "diameter": 3, "flute_length": 4}]
    r = client.post("/v1/plans/contour", json={"grid": rows_grid(part), "tools": tools,
                                               "include_models": True, "stock_top": 8.0})
    assert r.status_code == 200, r.text
    plan = ContourPlanResult.model_validate(r.json())
    assert plan.checks.ok and plan.stock_top == 8.0 and plan.stock_top_source == "request"
    assert plan.contour_spacings == [s for st in plan.stages for s in st.spacings]
    previous = np.full(part.shape, 8.0)
    for stage in plan.stages:
        assert stage.z_levels == sorted(stage.z_levels, reverse=True)
        assert all(0 < s <= stage.tool.flute_length + 1e-9 for s in stage.spacings)
        assert len(stage.slab_volumes) == len(stage.spacings)
        here = on_input(stage.model.model_dump(), part, 0.5)  # type: ignore[union-attr]
        assert (here - part).min() >= 0 and (previous - here).min() >= 0
        previous = here


def test_plans_are_cached_and_default_tools_are_the_library(client: TestClient) -> None:
    part = pocket_part(17)
    body = {"grid": rows_grid(part)}
    first = client.post("/v1/plans/contour", json=body)
    library = [t for t in client.get("/v1/tools").json()["tools"] if t["kind"] == "flat"]
    # the library's entries go back as they are (kind included) and hash like the default
    explicit = client.post("/v1/plans/contour", json={**body, "tools": library})
    assert explicit.status_code == 200, explicit.text
    assert explicit.json()["task_id"] == first.json()["task_id"]
    bare = [{k: t[k] for k in ("id", "diameter", "flute_length")} for t in library]
    again = client.post("/v1/plans/contour", json={**body, "tools": bare})
    assert again.json()["task_id"] == first.json()["task_id"]
    assert explicit.headers["x-cache"] == "hit"
    stored = client.get(f"/v1/tasks/{first.json()['task_id']}")
    assert stored.json() == first.json()


def test_default_library_has_the_catalogue_range(client: TestClient) -> None:
    tools = client.get("/v1/tools").json()["tools"]
    balls = sorted(t["diameter"] for t in tools if t["kind"] == "ball")
    flats = sorted(t["diameter"] for t in tools if t["kind"] == "flat")
    assert balls[0] == 1 and balls[-1] == 20 and flats[0] == 3 and flats[-1] == 20
    assert len({t["id"] for t in tools}) == len(tools)
    assert all(t["flute_length"] > t["diameter"] for t in tools)


GRID = {"dx": 1, "dy": 1, "z": [[0, 1, 0], [1, 2, 1], [0, 1, 0]]}


@pytest.mark.parametrize("path", ["/v1/plans/scanline", "/v1/plans/contour"])
@pytest.mark.parametrize(("extra", "field", "reason"), [
    ({"tools": []}, "tools", "empty"),
    ({"tools": [{"id": "a", "diameter": 2, "flute_length": 4},
                {"id": "a", "diameter": 1, "flute_length": 2}]}, "tools[1].id", "duplicate"),
    ({"tools": [{"id": "a", "diameter": -2, "flute_length": 4}]}, "tools[0].diameter", ""),
    ({"tools": [{"id": "a", "diameter": 2}]}, "tools[0].flute_length", "required"),
    ({"tools": [{"id": "a", "diameter": 1e-300, "flute_length": 4}]}, "tools[0].diameter",
     "greater than or equal to 0.01"),
    ({"tools": [{"id": "a", "kind": "drill", "diameter": 2, "flute_length": 4}]},
     "tools[0].kind", ""),
    ({"stock_top": 1.0}, "stock_top", ""),
])
def test_bad_plan_requests(client: TestClient, path: str, extra: dict, field: str,
                           reason: str) -> None:
    assert_problem(client.post(path, json={"grid": GRID, **extra}), 422, field, reason)


@pytest.mark.parametrize(("path", "wrong"), [("/v1/plans/scanline", "flat"),
                                             ("/v1/plans/contour", "ball")])
def test_a_tool_of_the_other_kind_is_refused(client: TestClient, path: str, wrong: str) -> None:
    tools = [{"id": "a", "kind": wrong, "diameter": 2, "flute_length": 4}]
    r = client.post(path, json={"grid": GRID, "tools": tools})
    assert_problem(r, 422, "tools[0].kind", f"a {wrong} end mill")


@pytest.mark.parametrize("tolerance", [0, -0.01])
def test_scanline_tolerance_must_be_positive(client: TestClient, tolerance: float) -> None:
    r = client.post("/v1/plans/scanline", json={"grid": GRID, "tolerance": tolerance})
    assert_problem(r, 422, "tolerance", "greater than or equal to")


def test_contour_unknown_strategy_lists_the_valid_ones(client: TestClient) -> None:
    r = client.post("/v1/plans/contour", json={"grid": GRID, "strategy": "fastest"})
    assert_problem(r, 422, "strategy", "uniform_load")
