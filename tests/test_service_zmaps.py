"""STL to z-map over HTTP, binary (.npy) grids, grid_task and .npy results."""

from __future__ import annotations

import io
import pickle

import numpy as np
import pytest
from fastapi.testclient import TestClient
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from service.grids import decode_npy
from service.schemas.zmaps import ZMapResult
from tests.conftest import make_client
from tests.test_mesh_zmap import DATA, box, stl_bytes
from tests.test_service_mrr import grid_array, rows_grid
from zwcore import analyse

PROBLEM = "application/problem+json"
NPY = "application/x-npy"


def npy(a: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, a)
    return buf.getvalue()


def load_npy(data: bytes) -> np.ndarray:
    return np.load(io.BytesIO(data), allow_pickle=False)


def assert_problem(r, status: int, field: str, words: str) -> None:  # type: ignore[no-untyped-def]
    assert r.status_code == status, r.text
    assert r.headers["content-type"] == PROBLEM
    errors = r.json()["errors"]
    assert any(e["field"] == field and words in e["reason"] for e in errors), errors


def steps_stl() -> bytes:
    """A block 10 x 8 x 2 with a 3 mm high boss over [2, 5] x [2, 4]."""
    return stl_bytes(np.concatenate([box(0, 10, 0, 8, 0, 2), box(2, 5, 2, 4, 2, 5)]))


def expected_steps(dx: float, dy: float) -> np.ndarray:
    xs = dx * np.arange(round(10 / dx) + 1)
    ys = dy * np.arange(round(8 / dy) + 1)
    boss = (xs[None, :] >= 2) & (xs[None, :] <= 5) & (ys[:, None] >= 2) & (ys[:, None] <= 4)
    return np.where(boss, 5.0, 2.0)


def test_stl_body_gives_the_zbuffer_and_counts(client: TestClient) -> None:
    r = client.post("/v1/zmaps?dx=0.5&dy=0.25", content=steps_stl(),
                    headers={"content-type": "model/stl"})
    assert r.status_code == 200, r.text
    res = ZMapResult.model_validate(r.json())
    g = r.json()["grid"]
    assert (g["x0"], g["y0"], g["dx"], g["dy"], g["nx"], g["ny"]) == (0, 0, 0.5, 0.25, 21, 33)
    np.testing.assert_array_equal(grid_array(g), expected_steps(0.5, 0.25))
    assert res.background == 0.0 and res.background_source == "default"
    assert res.triangles == 24 and res.covered_nodes == 21 * 33
    assert res.bounds.max == (10, 8, 5)


def test_multipart_upload_is_the_same_task(client: TestClient) -> None:
    a = client.post("/v1/zmaps?dx=0.5", content=steps_stl(),
                    headers={"content-type": "model/stl"}).json()
    r = client.post("/v1/zmaps", files={"stl": ("part.stl", steps_stl(), "model/stl")},
                    data={"dx": "0.5"})
    assert r.status_code == 200, r.text
    assert r.json()["task_id"] == a["task_id"] and r.headers["x-cache"] == "hit"


def test_shape_and_background(client: TestClient) -> None:
    r = client.post("/v1/zmaps?nx=11&ny=9&background=-3", content=steps_stl(),
                    headers={"content-type": "model/stl"})
    body = r.json()
    assert body["grid"]["dx"] == 1.0 and body["grid"]["dy"] == 1.0
    assert body["background"] == -3 and body["background_source"] == "request"


def test_undercut_is_noted(client: TestClient) -> None:
    cap = stl_bytes(np.concatenate([box(0, 10, 0, 10, 0, 2), box(3, 6, 3, 6, 4, 5)]))
    body = client.post("/v1/zmaps?dx=1", content=cap,
                       headers={"content-type": "model/stl"}).json()
    assert body["undercut_nodes"] == 16 and body["undercut_area"] == 16.0
    assert any("undercut" in n for n in body["notes"])


@pytest.mark.skipif(not (DATA / "mount_rush.stl").exists(), reason="no shared data")
def test_mount_rushmore_over_http_and_as_npy(client: TestClient) -> None:
    stl = (DATA / "mount_rush.stl").read_bytes()
    ref = np.load(DATA / "mount_rush_zmap_0.1mm.npy", allow_pickle=False)
    r = client.post("/v1/zmaps?dx=0.1&background=-26.646141", content=stl,
                    headers={"content-type": "model/stl"})
    assert r.status_code == 200, r.text
    tid = r.json()["task_id"]
    got = client.get(f"/v1/tasks/{tid}/models/0", headers={"accept": NPY})
    assert got.headers["content-type"] == NPY
    z = load_npy(got.content)
    assert z.shape == ref.shape and np.abs(z - ref).max() <= 1e-4
    assert float(got.headers["x-grid-x0"]) == pytest.approx(-40.958, abs=1e-3)


def test_grid_task_plans_the_uploaded_zmap(client: TestClient) -> None:
    tid = client.post("/v1/zmaps?dx=0.5", content=steps_stl(),
                      headers={"content-type": "model/stl"}).json()["task_id"]
    z = expected_steps(0.5, 0.5)
    direct = client.post("/v1/mrr", json={"grid": rows_grid(z), "include_models": True}).json()
    via = client.post("/v1/mrr", json={"grid_task": tid, "include_models": True})
    assert via.status_code == 200, via.text
    assert via.json()["task_id"] == direct["task_id"]  # same heights, same task
    # the finest level is the z-map itself; the coarsest is the lifted Haar of it
    coarse = client.get(f"/v1/tasks/{direct['task_id']}/models/0", headers={"accept": NPY})
    np.testing.assert_allclose(load_npy(coarse.content), analyse(z, "haar").approximations[0])
    plan = client.post("/v1/plans/scanline", json={"grid_task": tid})
    assert plan.status_code == 200 and plan.json()["stages"]


def test_grid_task_unknown_or_not_a_zmap(client: TestClient) -> None:
    assert_problem(client.post("/v1/mrr", json={"grid_task": "0" * 64}), 422, "grid_task",
                   "no stored task")
    other = client.post("/v1/mrr", json={"grid": rows_grid(np.eye(3))}).json()["task_id"]
    assert_problem(client.post("/v1/plans/contour", json={"grid_task": other}), 422,
                   "grid_task", "not a z-map")
    assert_problem(client.post("/v1/mrr", json={}), 422, "grid", "exactly one")


@pytest.mark.parametrize("dtype", ["float32", "float64", "int16"])
def test_npy_body_is_the_same_task_as_json(client: TestClient, dtype: str) -> None:
    z = np.arange(35, dtype=dtype).reshape(5, 7) % 6
    js = client.post("/v1/mrr", json={"grid": rows_grid(z.astype(float)),
                                      "include_models": True}).json()
    r = client.post("/v1/mrr?dx=0.5&dy=0.5&include_models=true&wavelet=haar", content=npy(z),
                    headers={"content-type": NPY})
    assert r.status_code == 200, r.text
    assert r.json()["task_id"] == js["task_id"] and r.headers["x-cache"] == "hit"


def test_multipart_grid_with_tools_as_fields(client: TestClient) -> None:
    z = np.add.outer(np.linspace(0, 4, 9), np.linspace(0, 2, 9)) ** 1.5
    tools = '[{"id": "B4", "diameter": 4, "flute_length": 10}]'
    js = client.post("/v1/plans/scanline", json={
        "grid": rows_grid(z), "tools": [{"id": "B4", "diameter": 4, "flute_length": 10}],
        "tolerance": 0.05}).json()
    r = client.post("/v1/plans/scanline", files={"grid": ("z.npy", npy(z), NPY)},
                    data={"dx": "0.5", "dy": "0.5", "tools": tools, "tolerance": "0.05"})
    assert r.status_code == 200, r.text
    assert r.json()["task_id"] == js["task_id"]


def test_stage_models_as_npy_round_up_to_float32(client: TestClient) -> None:
    z = np.random.default_rng(3).normal(size=(9, 9)).cumsum(0)
    res = client.post("/v1/plans/contour", json={"grid": rows_grid(z),
                                                 "include_models": True}).json()
    tid = res["task_id"]
    for k, stage in enumerate(res["stages"]):
        f64 = load_npy(client.get(f"/v1/tasks/{tid}/models/{k}", headers={"accept": NPY}).content)
        np.testing.assert_array_equal(f64, np.array(stage["model"]["z"]))
        f32 = load_npy(client.get(f"/v1/tasks/{tid}/models/{k}?dtype=float32",
                                  headers={"accept": NPY}).content)
        assert f32.dtype == np.float32 and (f32.astype(float) >= f64).all()
    missing = client.get(f"/v1/tasks/{tid}/models/{len(res['stages'])}")
    assert_problem(missing, 404, "index", "no such grid")


# --- bad input ------------------------------------------------------------------------

@pytest.mark.parametrize(("body", "words"), [
    (b"", "empty"),
    (b"this is not an STL file", "no triangles"),
    (stl_bytes(box(0, 1, 0, 1, 0, 1))[:400], "STL"),
])
def test_bad_stl_bodies(client: TestClient, body: bytes, words: str) -> None:
    r = client.post("/v1/zmaps?dx=0.1", content=body, headers={"content-type": "model/stl"})
    assert_problem(r, 422, "stl", words)


def test_nan_vertex_stl(client: TestClient) -> None:
    tri = box(0, 1, 0, 1, 0, 1)
    tri[2, 0, 0] = np.nan
    r = client.post("/v1/zmaps?dx=0.1", content=stl_bytes(tri),
                    headers={"content-type": "model/stl"})
    assert_problem(r, 422, "stl", "non-finite")


def test_cell_size_over_the_cell_limit_is_413(tmp_path) -> None:  # type: ignore[no-untyped-def]
    with make_client(tmp_path, max_grid_cells=10_000) as c:
        r = c.post("/v1/zmaps?dx=0.05", content=steps_stl(), headers={"content-type": "model/stl"})
        assert_problem(r, 413, "dx", "more than the limit of 10000")


def test_zmap_parameters_and_media_type(client: TestClient) -> None:
    stl = {"content-type": "model/stl"}
    assert_problem(client.post("/v1/zmaps", content=steps_stl(), headers=stl), 422, "dx",
                   "cell size")
    assert_problem(client.post("/v1/zmaps?dx=1&nx=3&ny=3", content=steps_stl(), headers=stl),
                   422, "dx", "not both")
    r = client.post("/v1/zmaps?dx=-1", content=steps_stl(), headers=stl)
    assert r.status_code == 422 and "dx" in r.text
    assert_problem(client.post("/v1/zmaps?dx=1", content=b"x", headers={"content-type":
                                                                         "text/plain"}),
                   415, "content-type", "unsupported")
    assert_problem(client.post("/v1/zmaps", data={"dx": "1"}, files={"other": ("a", b"b")}),
                   422, "other", "only stl")


@pytest.mark.parametrize(("body", "status", "words"), [
    (npy(np.array([[1, None], [2, 3]], dtype=object)), 422, "not a number type"),
    (pickle.dumps(np.zeros((3, 3))), 422, "a pickle"),
    (npy(np.zeros(9)), 422, "2-D"),
    (npy(np.zeros((1, 9))), 422, "at least 2 x 2"),
    (npy(np.array([[1, 2], [3, 4]], dtype=complex)), 422, "not a number type"),
    (npy(np.zeros((30, 30)))[:500], 422, "unreadable .npy data"),
    (npy(np.array([[np.nan, 1], [2, 3]])), 422, "finite"),
    (b"PK\x03\x04 zip", 422, "npz"),
])
def test_bad_npy_bodies(client: TestClient, body: bytes, status: int, words: str) -> None:
    r = client.post("/v1/mrr?dx=1&dy=1", content=body, headers={"content-type": NPY})
    assert_problem(r, status, "body", words)


def test_npy_over_the_cell_limit_and_mismatched_fields(tmp_path) -> None:  # type: ignore[no-untyped-def]
    with make_client(tmp_path, max_grid_cells=100) as c:
        r = c.post("/v1/mrr?dx=1&dy=1", content=npy(np.zeros((11, 10))),
                   headers={"content-type": NPY})
        assert_problem(r, 413, "body", "exceeds 100 cells")
        ok = npy(np.zeros((3, 3)))
        assert_problem(c.post("/v1/mrr?dy=1", content=ok, headers={"content-type": NPY}),
                       422, "grid.dx", "required")
        assert_problem(c.post("/v1/mrr?dx=1&dy=1&levels=x", content=ok,
                              headers={"content-type": NPY}), 422, "levels", "integer")
        assert_problem(c.post("/v1/mrr?dx=1&dy=1&colour=red", content=ok,
                              headers={"content-type": NPY}), 422, "colour", "Extra")
        r = c.post("/v1/mrr", files={"grid": ("z", b"{}", "text/plain")},
                   data={"dx": "1", "dy": "1"})
        assert_problem(r, 422, "grid", "not an .npy file")
        r = c.post("/v1/mrr", files={"grid": (None, "[[1, 2], [3, 4]]")},
                   data={"dx": "1", "dy": "1"})
        assert_problem(r, 422, "grid", "file part")
        assert_problem(c.post("/v1/mrr", content=ok, headers={"content-type": "image/png"}),
                       415, "content-type", "unsupported")


def test_binary_bodies_are_not_counted_as_json_values(tmp_path) -> None:  # type: ignore[no-untyped-def]
    # int8 44 is the byte of a comma: a JSON value count would have refused this grid
    z = np.full((40, 40), 44, dtype=np.int8)
    with make_client(tmp_path, max_json_values=100) as c:
        r = c.post("/v1/mrr?dx=1&dy=1", content=npy(z), headers={"content-type": NPY})
        assert r.status_code == 200, r.text
        r = c.post("/v1/mrr", content=b"[" + b"1," * 200 + b"1]",
                   headers={"content-type": "application/json"})
        assert r.status_code == 413


def test_zmap_grid_encoding_and_model_etags(client: TestClient) -> None:
    r = client.post("/v1/zmaps?dx=2&grid_encoding=rows", content=steps_stl(),
                    headers={"content-type": "model/stl"})
    assert r.status_code == 200 and r.json()["grid"]["z"][0][0] == 2.0
    assert_problem(client.post("/v1/zmaps?dx=2&colour=red", content=steps_stl(),
                               headers={"content-type": "model/stl"}), 422, "query.colour",
                   "Extra")
    url = f"/v1/tasks/{r.json()['task_id']}/models/0"
    as_npy = client.get(url, headers={"accept": NPY})
    as_json = client.get(url)
    assert as_npy.headers["etag"] != as_json.headers["etag"]
    again = client.get(url, headers={"accept": NPY, "if-none-match": as_npy.headers["etag"]})
    assert again.status_code == 304
    np.testing.assert_array_equal(load_npy(as_npy.content), grid_array(as_json.json()))


@settings(max_examples=40, deadline=None)
@given(hnp.arrays(st.sampled_from([np.dtype("<f4"), np.dtype(">f8"), np.dtype("<i2"),
                                   np.dtype("u1")]),
                  hnp.array_shapes(min_dims=2, max_dims=2, min_side=2, max_side=6),
                  elements={"allow_nan": False, "allow_infinity": False}),
       st.booleans())
def test_decode_npy_gives_back_what_numpy_saved(z: np.ndarray, fortran: bool) -> None:
    a = np.asfortranarray(z) if fortran else z
    got = decode_npy(npy(a), max_cells=100)
    np.testing.assert_array_equal(got.astype(np.float64), z.astype(np.float64))
    assert got.shape == z.shape


def test_zmap_straight_to_npy(client: TestClient) -> None:
    r = client.post("/v1/zmaps?dx=0.5", content=steps_stl(),
                    headers={"content-type": "model/stl", "accept": NPY})
    assert r.status_code == 200 and r.headers["content-type"] == NPY
    np.testing.assert_array_equal(load_npy(r.content), expected_steps(0.5, 0.5))
    assert float(r.headers["x-grid-dx"]) == 0.5 and r.headers["x-cache"] == "miss"
    plan = client.post("/v1/mrr", json={"grid_task": r.headers["x-task-id"]})
    assert plan.status_code == 200
