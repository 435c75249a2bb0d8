"""POST /v1/arcs over HTTP."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from fastapi.testclient import TestClient

from service.schemas.arcs import ArcsResult
from tests.test_service_errors import assert_problem, post_raw


def ellipse(n: int = 400) -> list[list[float]]:
    t = np.linspace(0, np.pi, n)
    return np.c_[100 * np.cos(t), 50 * np.sin(t)].tolist()


def test_arc_chain_is_continuous_and_within_tolerance(client: TestClient) -> None:
    pts = ellipse()
    r = client.post("/v1/arcs", json={"points": pts, "tolerance": 0.1, "gcode": True})
    assert r.status_code == 200, r.text
    res = ArcsResult.model_validate(r.json())
    segs = res.segments
    assert segs[0].start == pytest.approx(tuple(pts[0]), abs=1e-9)
    assert segs[-1].end == pytest.approx(tuple(pts[-1]), abs=1e-9)
    for a, b in itertools.pairwise(segs):
        assert a.end == pytest.approx(b.start, abs=1e-9)
    assert res.summary.max_deviation_points <= 0.1 + 1e-9
    assert res.summary.max_deviation_chain <= 0.1 + 1e-9
    assert res.summary.max_kink_smooth_deg < 1e-6
    assert res.summary.n_segments == len(segs) < 40
    assert res.gcode is not None and "G17" in res.gcode
    assert "G02" in res.gcode or "G03" in res.gcode


def test_rows_of_a_line_give_one_line(client: TestClient) -> None:
    x = np.linspace(0, 100, 201)
    noise = 0.02 * np.sin(np.arange(201) * 1.7)
    r = client.post("/v1/arcs", json={"points": np.c_[x, noise].tolist()}).json()
    assert [s["kind"] for s in r["segments"]] == ["line"]


def test_offset_and_cache(client: TestClient) -> None:
    body = {"points": ellipse(200), "offset": 2.0}
    first = client.post("/v1/arcs", json=body)
    assert first.status_code == 200
    assert first.json()["offset"]["distance"] == 2.0
    again = client.post("/v1/arcs", json=body)
    assert again.headers["x-cache"] == "hit" and again.json() == first.json()


@pytest.mark.parametrize(("body", "field", "reason"), [
    ('{"points": [[0, 0]]}', "points", "at least 2"),
    ('{"points": [[0, 0], [0, 0], [0, 0]]}', "points", "distinct"),
    ('{"points": [[0, 0], [1, NaN]]}', "points[1][1]", "finite"),
    ('{"points": [[0, 0, 1], [1, 1, 1]]}', "points[0]", ""),
    ('{"points": [[0, 0], [1, 1]], "tolerance": 0}', "tolerance", "greater than 0"),
    ('{"points": [[0, 0], [1, 1]], "corner_angle_deg": 200}', "corner_angle_deg", ""),
    ('{"points": "abc"}', "points", ""),
])
def test_bad_arc_requests(client: TestClient, body: str, field: str, reason: str) -> None:
    assert_problem(post_raw(client, "/v1/arcs", body), 422, field, reason)


def test_unbounded_work_is_refused(client: TestClient) -> None:
    # 2e4 mm of curve at a micron tolerance would mean ~1e10 verification samples.
    body = {"points": [[0, 0], [1e4, 0], [1e4, 1e4]], "tolerance": 1e-6}
    assert_problem(client.post("/v1/arcs", json=body), 413, "tolerance", "larger tolerance")
    far = {"points": [[0, 0], [2e6, 0]]}
    assert_problem(client.post("/v1/arcs", json=far), 422, "points[1][0]", "")


def test_offset_reports_reversed_segments(client: TestClient) -> None:
    """An L of two 10 mm lines offset 100 mm into its inner corner: both offset lines
    would run backwards, and the response says so (nothing vanished)."""
    body = {"points": [[0, 0], [10, 0], [10, 10]], "offset": 100.0}
    off = client.post("/v1/arcs", json=body).json()["offset"]
    assert off["vanished_arcs"] == []
    assert off["reversed_segments"] == [0, 1]
    small = client.post("/v1/arcs", json={**body, "offset": 5.0}).json()["offset"]
    assert small["reversed_segments"] == []


def test_readme_arc_example_has_lines_on_its_straight_runs(client: TestClient) -> None:
    body = {"points": [[0, 0], [10, 0], [20, 0], [27.07, 2.93], [30, 10]],
            "tolerance": 0.05, "gcode": True}
    r = client.post("/v1/arcs", json=body).json()
    kinds = [s["kind"] for s in r["segments"]]
    assert kinds == ["line", "arc", "line", "line"]
    assert all(s["radius"] < 10 for s in r["segments"] if s["kind"] == "arc")
