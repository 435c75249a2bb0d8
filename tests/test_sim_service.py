"""``POST /v1/simulate`` over HTTP: status codes and bodies, judged by independent sums."""

from __future__ import annotations

import numpy as np
from fastapi.testclient import TestClient

from service.schemas.simulate import SimulateResult
from tests.conftest import make_client
from tests.test_service_errors import assert_problem
from tests.test_service_mrr import b64_grid, grid_array, rows_grid


def bowl(n: int = 61, dx: float = 0.1) -> np.ndarray:
    y, x = (np.mgrid[0:n, 0:n] - (n - 1) / 2) * dx
    return (x * x + y * y) / 8.0 - 4.0  # paraboloid bowl, radius of curvature 4 at the bottom


BALL = {"kind": "ball", "diameter": 4.0, "flute_length": 8.0}


def test_closing_of_a_bowl_keeps_the_part_and_reports_the_figures(client: TestClient) -> None:
    part = bowl()
    r = client.post("/v1/simulate", json={"grid": rows_grid(part, dx=0.1, dy=0.1),
                                          "tool": BALL, "stock_top": 6.0})
    assert r.status_code == 200, r.text
    res = SimulateResult.model_validate(r.json())
    machined = grid_array(r.json()["machined"])
    assert res.cl_source == "drop_cutter" and res.stock_top == 6.0
    assert res.machined.interpolation == "bilinear" and machined.shape == part.shape
    assert (machined - part).min() >= 0.0 and res.gouge == 0.0
    rest = machined - part
    assert res.rest.max == rest.max() and abs(res.rest.p95 - np.percentile(rest, 95)) < 1e-12
    # the R 2 ball fits the R 4 bowl: nothing left inside, away from the grid's rim
    assert rest[20:41, 20:41].max() <= 0.005
    # the deepest engagement: from the stock top to the bowl's floor, over 8 mm flutes
    assert abs(res.depth_of_cut.max - 10.0) < 5e-3 and not res.depth_of_cut.flute_length_ok
    assert res.notes


def test_given_cl_grid_and_stock_grid_in_base64(client: TestClient) -> None:
    part = np.zeros((16, 16))
    stock = np.full((16, 16), 2.0)
    cl = np.full((16, 16), 0.5)  # a flat end mill 0.5 above the part everywhere
    body = {"grid": b64_grid(part, "float32"), "stock": b64_grid(stock),
            "cl": rows_grid(cl), "tool": {"kind": "flat", "diameter": 2.0, "flute_length": 3}}
    r = client.post("/v1/simulate", json=body)
    assert r.status_code == 200, r.text
    out = r.json()
    assert out["cl_source"] == "request" and out["stock_top"] is None
    machined = grid_array(out["machined"])
    assert out["machined"]["dtype"] == "float32"
    np.testing.assert_allclose(machined, 0.5, atol=1e-4)
    assert abs(out["depth_of_cut"]["max"] - 1.5) < 1e-4 and out["gouge"] == 0.0
    # the same request again is the same task, from the cache
    again = client.post("/v1/simulate", json=body)
    assert again.headers["x-cache"] == "hit" and again.json()["task_id"] == out["task_id"]
    deeper = dict(body, cl=rows_grid(np.full((16, 16), -0.25)))
    r = client.post("/v1/simulate", json=deeper)
    assert r.status_code == 200 and abs(r.json()["gouge"] - 0.25) < 1e-4
    assert r.json()["task_id"] != out["task_id"] and r.json()["notes"]


def test_bad_input_names_the_field(client: TestClient) -> None:
    part = bowl(9, 0.5)
    grid = rows_grid(part)
    cases = [
        ({"grid": grid, "cl": rows_grid(part)}, "tool"),
        ({"grid": grid, "tool": BALL, "stock": rows_grid(np.zeros((8, 9)))}, "stock.shape"),
        ({"grid": grid, "tool": BALL, "stock": rows_grid(part - 1.0)}, "stock"),
        ({"grid": grid, "tool": BALL, "stock": rows_grid(part + 1, dx=0.25)}, "stock.dx"),
        ({"grid": grid, "tool": BALL, "stock_top": -10.0}, "stock_top"),
        ({"grid": grid, "tool": BALL, "stock_top": 5.0, "stock": rows_grid(part + 1)}, "stock"),
        ({"grid": grid, "tool": BALL, "cl": rows_grid(np.zeros((9, 3)))}, "cl.shape"),
        ({"grid": grid, "tool": {"kind": "bull", "diameter": 4, "flute_length": 8}}, "tool.kind"),
    ]
    for body, field in cases:
        assert_problem(client.post("/v1/simulate", json=body), 422, field)


def test_too_large_a_simulation_is_413(tmp_path) -> None:  # type: ignore[no-untyped-def]
    with make_client(tmp_path, max_simulation_work=10000) as c:
        r = c.post("/v1/simulate", json={"grid": rows_grid(bowl(9, 0.5)),
                                         "tool": {**BALL, "diameter": 20.0}})
        assert_problem(r, 413, "tool.diameter")
