"""GET /v1/tasks/{task_id}/preview.png: pictures of stored results."""

from __future__ import annotations

import io

import numpy as np
import pytest
from fastapi.testclient import TestClient
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from PIL import Image

from service.previews import display_grid
from tests.conftest import make_client
from tests.test_gcode_program import arc_points, g01
from tests.test_service_errors import assert_problem
from tests.test_service_zmaps import steps_stl
from tests.test_sim_service import BALL, bowl


@pytest.fixture
def client(tmp_path):  # type: ignore[no-untyped-def]
    # arcs fitted in the threads: no worker processes to start for a few small curves
    with make_client(tmp_path, process_workers=0) as c:
        yield c


def bump(n: int = 48) -> list[list[float]]:
    y, x = np.mgrid[0:n, 0:n]
    return (8 * np.exp(-((x - n / 2) ** 2 + (y - n / 2) ** 2) / (n * 3.0)) + 0.02 * x).tolist()


def png(r) -> Image.Image:  # type: ignore[no-untyped-def]
    assert r.status_code == 200, r.text
    assert r.headers["content-type"] == "image/png"
    img = Image.open(io.BytesIO(r.content))
    img.load()
    assert img.format == "PNG"
    assert 300 <= img.width <= 3000 and 300 <= img.height <= 3000
    # something was drawn: many distinct colours, not a blank canvas
    assert len(img.convert("RGB").getcolors(maxcolors=1 << 20) or []) > 50
    return img


@pytest.fixture
def plan(client: TestClient) -> dict:  # type: ignore[type-arg]
    r = client.post("/v1/plans/contour", json={"grid": {"dx": 1.0, "dy": 1.0, "z": bump()},
                                               "include_models": True})
    assert r.status_code == 200, r.text
    return r.json()  # type: ignore[no-any-return]


def test_plan_overview_and_one_stage(client: TestClient, plan: dict) -> None:  # type: ignore[type-arg]
    tid = plan["task_id"]
    overview = png(client.get(f"/v1/tasks/{tid}/preview.png"))
    one = png(client.get(f"/v1/tasks/{tid}/preview.png?stage=0&kind=model"))
    if len(plan["stages"]) > 1:  # side by side: wider than one stage alone
        assert overview.width > one.width
    r = client.get(f"/v1/tasks/{tid}/preview.png?stage=0")
    assert client.get(f"/v1/tasks/{tid}/preview.png?stage=0",
                      headers={"if-none-match": r.headers["etag"]}).status_code == 304


def test_mrr_levels_and_arc_chains(client: TestClient) -> None:
    r = client.post("/v1/mrr", json={"grid": {"dx": 0.5, "dy": 0.5, "z": bump(32)},
                                      "wavelet": "haar", "levels": 2, "include_models": True})
    png(client.get(f"/v1/tasks/{r.json()['task_id']}/preview.png"))
    png(client.get(f"/v1/tasks/{r.json()['task_id']}/preview.png?stage=1"))
    t = np.linspace(0, np.pi, 100)
    r = client.post("/v1/arcs", json={"points": np.c_[30 * np.cos(t), 10 * np.sin(t)].tolist()})
    png(client.get(f"/v1/tasks/{r.json()['task_id']}/preview.png"))
    program = "\n".join(["G90 G17", "G00 X30 Y0 Z1", "G01 Z0 F100",
                          *g01(arc_points((0, 0), 30, 0, np.pi, 40)), "M30"])
    r = client.post("/v1/arcs?tolerance=0.05", content=program,
                    headers={"content-type": "text/plain"})
    png(client.get(f"/v1/tasks/{r.json()['task_id']}/preview.png?kind=chain&stage=0"))


def test_unknown_task_stage_and_kind(client: TestClient, plan: dict) -> None:  # type: ignore[type-arg]
    tid = plan["task_id"]
    assert_problem(client.get(f"/v1/tasks/{'0' * 64}/preview.png"), 404, "task_id")
    assert_problem(client.get(f"/v1/tasks/{tid}/preview.png?stage=99"), 404, "stage")
    assert_problem(client.get(f"/v1/tasks/{tid}/preview.png?stage=-1"), 422, "query.stage")
    assert_problem(client.get(f"/v1/tasks/{tid}/preview.png?kind=toolpaths"), 422,
                   "query.kind")  # comes with the tool paths
    assert_problem(client.get(f"/v1/tasks/{tid}/preview.png?kind=chain"), 404, "kind",
                   "no chain picture")
    assert_problem(client.get(f"/v1/tasks/{tid}/preview.png?kind=bogus"), 422, "query.kind")
    r = client.post("/v1/plans/scanline", json={"grid": {"dx": 1.0, "dy": 1.0, "z": bump(16)}})
    assert_problem(client.get(f"/v1/tasks/{r.json()['task_id']}/preview.png"), 409,
                   "include_models")


@settings(max_examples=30)
@given(z=hnp.arrays(np.float64, st.tuples(st.integers(1, 40), st.integers(1, 40)),
                    elements=st.floats(-100, 100)), side=st.integers(1, 12))
def test_display_grid_is_the_block_maximum(z: np.ndarray, side: int) -> None:
    shown, s = display_grid(z, side)
    assert max(shown.shape) <= side
    for i in range(shown.shape[0]):
        for k in range(shown.shape[1]):
            block = z[i * s:(i + 1) * s, k * s:(k + 1) * s]
            assert shown[i, k] == block.max()  # never lower than what it stands for


def test_zmap_and_simulated_stock(client: TestClient) -> None:
    r = client.post("/v1/zmaps?dx=0.25", content=steps_stl(),
                    headers={"content-type": "model/stl"})
    assert r.status_code == 200, r.text
    png(client.get(f"/v1/tasks/{r.json()['task_id']}/preview.png"))
    r = client.post("/v1/simulate", json={"grid": {"dx": 0.1, "dy": 0.1, "z": bowl().tolist()},
                                          "tool": BALL, "stock_top": 6.0})
    assert r.status_code == 200, r.text
    png(client.get(f"/v1/tasks/{r.json()['task_id']}/preview.png?kind=stock"))
    assert_problem(client.get(f"/v1/tasks/{r.json()['task_id']}/preview.png?kind=model"), 404,
                   "kind", "it has: ['stock']")
