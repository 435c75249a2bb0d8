"""Bad input gets a 4xx problem document naming the field and the reason."""

from __future__ import annotations

import base64

import numpy as np
import pytest
from fastapi.testclient import TestClient

from tests.conftest import make_client

PROBLEM = "application/problem+json"


def post_raw(client: TestClient, path: str, text: str):  # type: ignore[no-untyped-def]
    return client.post(path, content=text.encode(), headers={"content-type": "application/json"})


def assert_problem(r, status: int, field: str, reason: str = "") -> None:  # type: ignore[no-untyped-def]
    assert r.status_code == status, r.text
    assert r.headers["content-type"] == PROBLEM
    body = r.json()
    assert body["status"] == status and body["title"] and body["detail"]
    fields = [e["field"] for e in body.get("errors", [])]
    assert any(f.startswith(field) for f in fields), fields
    if reason:
        assert reason in body["detail"] or any(reason in e["reason"] for e in body["errors"])


B64_2x2 = base64.b64encode(np.zeros(4, "<f8").tobytes()).decode()


@pytest.mark.parametrize(("body", "field", "reason"), [
    ('{"grid": {"dx": 1, "dy": 1, "z": [[0, NaN], [0, 0]]}}', "grid.z", "finite"),
    ('{"grid": {"dx": 1, "dy": 1, "z": [[0, Infinity], [0, 0]]}}', "grid.z", "finite"),
    ('{"grid": {"dx": 1, "dy": 1, "z": [[0, 1, 2], [0, 0]]}}', "grid.z[1]", "ragged"),
    ('{"grid": {"dx": 1, "dy": 1, "z": [[0, "a"], [0, 0]]}}', "grid.z[0][1]", "number"),
    ('{"grid": {"dx": 0, "dy": 1, "z": [[0, 1], [0, 0]]}}', "grid.dx", "greater than or equal to"),
    ('{"grid": {"dx": 1, "dy": -1, "z": [[0, 1], [0, 0]]}}', "grid.dy", ""),
    ('{"grid": {"dx": 1, "dy": 1, "z": [[0, 1]]}}', "grid.z", "at least 2"),
    ('{"grid": {"dx": 1, "dy": 1, "z": []}}', "grid.z", "at least 2"),
    ('{"grid": {"dx": 1, "dy": 1, "z": [[0], [1]]}}', "grid.z[0]", "at least 2"),
    ('{"grid": {"dx": 1, "dy": 1, "shape": [1, 4], "dtype": "float64", "z_b64": "B64"}}',
     "grid.shape[0]", "greater than or equal to 2"),
    ('{"grid": {"dx": 1, "dy": 1}}', "grid", "exactly one"),
    ('{"grid": {"dx": 1, "dy": 1, "shape": [2, 2], "dtype": "float64", "z_b64": "@@@"}}',
     "grid.z_b64", "base64"),
    ('{"grid": {"dx": 1, "dy": 1, "shape": [3, 2], "dtype": "float64", "z_b64": "B64"}}',
     "grid.z_b64", "needs 48"),
    ('{"grid": {"dx": 1, "dy": 1, "shape": [2, 2], "dtype": "int8", "z_b64": "B64"}}',
     "grid.dtype", "float32"),
    ('{"grid": {"dx": 1, "dy": 1, "shape": [2, 2], "z_b64": "B64"}}',
     "grid.dtype", "required"),
    ('{"grid": {"dx": 1, "dy": 1, "z": [[0, 1], [0, 0]]}, "wavelet": "db4"}', "wavelet",
     "haar"),
    ('{"grid": {"dx": 1, "dy": 1, "z": [[0, 1], [0, 0]]}, "levels": -1}', "levels", ""),
    ('{"grid": {"dx": 1, "dy": 1, "z": [[0, 1], [0, 0]]}, "levels": 5}', "levels", "between"),
    ('{"grid": {"dx": 1, "dy": 1, "z": [[0, 1], [0, 0]]}, "colour": 5}', "colour", ""),
    ('[1, 2]', "body", ""),
])
def test_bad_mrr_requests(client: TestClient, body: str, field: str, reason: str) -> None:
    body = body.replace('"B64"', f'"{B64_2x2}"')
    assert_problem(post_raw(client, "/v1/mrr", body), 422, field, reason)


def test_nan_in_base64_is_rejected(client: TestClient) -> None:
    z = np.zeros((3, 3), "<f4")
    z[2, 1] = np.nan
    grid = {"dx": 1, "dy": 1, "shape": [3, 3], "dtype": "float32",
            "z_b64": base64.b64encode(z.tobytes()).decode()}
    assert_problem(client.post("/v1/mrr", json={"grid": grid}), 422, "grid.z_b64", "row 2")


def test_malformed_json_is_400(client: TestClient) -> None:
    assert_problem(post_raw(client, "/v1/mrr", '{"grid": '), 400, "body", "malformed")


def test_body_over_the_limit_is_413(tmp_path) -> None:  # type: ignore[no-untyped-def]
    with make_client(tmp_path, max_body_bytes=1000) as c:
        rows = ",".join(["[0, 0]"] * 400)
        big = f'{{"grid": {{"dx": 1, "dy": 1, "z": [{rows}]}}}}'
        assert_problem(post_raw(c, "/v1/mrr", big), 413, "body", "limit")

        def chunks():  # type: ignore[no-untyped-def]
            for _ in range(10):
                yield b" " * 200  # no Content-Length: the stream is counted
        r = c.post("/v1/mrr", content=chunks(), headers={"content-type": "application/json"})
        assert_problem(r, 413, "body", "limit")


def test_grid_over_the_cell_limit_is_413(tmp_path) -> None:  # type: ignore[no-untyped-def]
    with make_client(tmp_path, max_grid_cells=16) as c:
        r = c.post("/v1/mrr", json={"grid": {"dx": 1, "dy": 1, "z": np.zeros((5, 5)).tolist()}})
        assert_problem(r, 413, "grid.z", "exceeds")
        grid = {"dx": 1, "dy": 1, "shape": [100000, 100000], "dtype": "float64", "z_b64": ""}
        assert_problem(c.post("/v1/mrr", json={"grid": grid}), 413, "grid.shape", "exceeds")


def test_unknown_route_is_a_problem(client: TestClient) -> None:
    r = client.get("/v1/nothing")
    assert r.status_code == 404 and r.headers["content-type"] == PROBLEM
    assert client.get("/v1/mrr").status_code == 405


# Review regressions: inputs that produced a 5xx, an endless computation or a null figure.

@pytest.mark.parametrize("shape", [[2**63, 0], [10**30, 0], [0, 5], [1, 2], [-2, -2]])
def test_degenerate_base64_shape_is_422(client: TestClient, shape: list[int]) -> None:
    # [2**63, 0] has no cells, so it passed the cell limit and numpy's reshape raised (500).
    grid = {"dx": 1, "dy": 1, "shape": shape, "dtype": "float64", "z_b64": ""}
    assert_problem(client.post("/v1/mrr", json={"grid": grid}), 422, "grid.shape")


@pytest.mark.parametrize(("path", "grid_extra", "field"), [
    ("/v1/plans/scanline", {"dx": 1e300, "dy": 1e300}, "grid.dx"),  # OverflowError, 500
    ("/v1/plans/scanline", {"dx": 1e-300, "dy": 1e-300}, "grid.dx"),  # ZeroDivisionError, 500
    ("/v1/mrr", {"dx": 1e308, "dy": 1.0}, "grid.dx"),  # coarse dx came back null
    ("/v1/mrr", {"x0": 1.7e308, "dx": 1.0, "dy": 1.0}, "grid.x0"),
])
def test_extreme_spacing_or_origin_is_422(client: TestClient, path: str,
                                           grid_extra: dict[str, float], field: str) -> None:
    grid = {"z": np.zeros((4, 4)).tolist(), **grid_extra}
    assert_problem(client.post(path, json={"grid": grid}), 422, field)


def test_unreachable_scanline_tolerance_is_422(client: TestClient) -> None:
    # 1e-300 gave an infinite predicted scallop, sent as null in a float field.
    grid = {"dx": 1, "dy": 1, "z": [[0, 5, 0], [5, 0, 5], [0, 5, 0]]}
    r = client.post("/v1/plans/scanline", json={"grid": grid, "tolerance": 1e-300})
    assert_problem(r, 422, "tolerance")


@pytest.mark.parametrize(("extra", "field"), [
    ({"stock_top": 1e6, "tools": [{"id": "a", "diameter": 1, "flute_length": 0.01}]},
     "tools[0].flute_length"),
    ({"stock_top": 500, "tools": [{"id": "big", "diameter": 10, "flute_length": 20},
                                  {"id": "tiny", "diameter": 0.01, "flute_length": 0.01}]},
     "tools[1]."),
    ({"stock_top": 1e6}, "stock_top"),
])
def test_contour_slab_count_is_bounded(client: TestClient, extra: dict[str, object],
                                       field: str) -> None:
    # Each of these asks the core for 10**4..10**8 slabs (once 10**300, which never returned).
    grid = {"dx": 1, "dy": 1, "z": [[0, 5, 0], [5, 0, 5], [0, 5, 0]]}
    r = client.post("/v1/plans/contour", json={"grid": grid, **extra})
    assert_problem(r, 413, field, "slabs")


def test_embedded_store_failure_does_not_fail_the_request(client: TestClient) -> None:
    store = client.app.state.store  # type: ignore[attr-defined]

    def broken(*args: object, **kwargs: object) -> None:
        raise OSError("disk full")

    store._cache.get = broken  # the diskcache object behind the store
    store._cache.set = broken
    r = client.post("/v1/mrr", json={"grid": {"dx": 1, "dy": 1, "z": [[0, 1], [2, 3]]}})
    assert r.status_code == 200, r.text
    assert r.json()["task_id"]


def test_cancelled_caller_neither_fails_the_shared_computation_nor_frees_its_slot() -> None:
    import asyncio
    import threading

    from service.compute import ComputePool

    async def scenario() -> None:
        pool = ComputePool(1, 0)
        release = threading.Event()
        leader = asyncio.ensure_future(pool.run_once("k", "op", lambda: release.wait(5)))
        await asyncio.sleep(0.05)
        follower = asyncio.ensure_future(pool.run_once("k", "op", lambda: False))
        await asyncio.sleep(0.05)
        leader.cancel()  # the first client went away
        await asyncio.sleep(0.05)
        # The thread still runs: its slot stays taken, so the next job is shed.
        assert pool.busy == 1
        with pytest.raises(Exception, match="busy"):
            await pool.run("op", lambda: None)
        release.set()
        assert await follower == (True, True)  # the follower still gets the result
        await asyncio.sleep(0.05)
        assert pool.busy == 0
        pool.shutdown()

    asyncio.run(scenario())


def test_too_many_json_values_is_413_before_parsing(tmp_path) -> None:  # type: ignore[no-untyped-def]
    with make_client(tmp_path, max_json_values=1000) as c:
        rows = [[0.0] * 40 for _ in range(40)]  # 1600 values
        r = c.post("/v1/mrr", json={"grid": {"dx": 1, "dy": 1, "z": rows}})
        assert_problem(r, 413, "body", "z_b64")
        small = c.post("/v1/mrr", json={"grid": {"dx": 1, "dy": 1, "z": [[0, 1], [2, 3]]}})
        assert small.status_code == 200


def test_a_ball_far_too_small_for_the_grid_is_refused_not_computed(client: TestClient) -> None:
    """A 0.01 mm ball over a 2 x 2 grid of 856 m cells needed extra scan lines over ~10**8
    grid cells: minutes of work and GBs (found by schemathesis). Refused with 422 naming
    tools; the same ball on a grid it fits still plans."""
    import time

    grid = {"x0": 31346.8, "y0": 192657.8, "dx": 1.000001, "dy": 856142.34,
            "z": [[0.01, -5.96e-08], [0.01, -5.96e-08]]}
    body = {"grid": grid, "tolerance": 9007199254740992.0,
            "tools": [{"id": "0", "flute_length": 0.01, "diameter": 0.01}]}
    start = time.perf_counter()
    r = client.post("/v1/plans/scanline", json=body)
    assert time.perf_counter() - start < 20
    assert_problem(r, 422, "tools", "too small")
    fits = client.post("/v1/plans/scanline", json={**body, "grid": {**grid, "dy": 1.0}})
    assert fits.status_code == 200, fits.text
