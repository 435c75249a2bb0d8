"""STL to z-map (zwcore.io.mesh): the known answer, a brute-force z-buffer, undercuts,
bad files."""

from __future__ import annotations

import io
import pathlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from stl import mesh as stl_mesh

from zwcore.errors import InvalidInputError, LimitExceededError
from zwcore.io import rasterise, read_stl, zmap_grid

_HERE = pathlib.Path(__file__).resolve()
# ../shared/data beside the clone (CI, /work/main); two up from a worktree under wt/
DATA = next((p / "shared" / "data" for p in (_HERE.parents[2], _HERE.parents[3])
             if (p / "shared" / "data" / "mount_rush.stl").exists()),
            _HERE.parents[2] / "shared" / "data")


def stl_bytes(tri: np.ndarray, ascii: bool = False) -> bytes:
    out = stl_mesh.Mesh(np.zeros(len(tri), dtype=stl_mesh.Mesh.dtype))
    out.vectors[:] = tri
    buf = io.BytesIO()
    out.save("t.stl", fh=buf, mode=stl_mesh.stl.Mode.ASCII if ascii else stl_mesh.stl.Mode.BINARY)
    return buf.getvalue()


def box(x0: float, x1: float, y0: float, y1: float, z0: float, z1: float) -> np.ndarray:
    """A closed axis-aligned box, 12 triangles, outward windings."""
    v = np.array([[x, y, z] for z in (z0, z1) for y in (y0, y1) for x in (x0, x1)], dtype=float)
    faces = [(0, 2, 1), (1, 2, 3), (4, 5, 6), (5, 7, 6), (0, 1, 4), (1, 5, 4),
             (2, 6, 3), (3, 6, 7), (0, 4, 2), (2, 4, 6), (1, 3, 5), (3, 7, 5)]
    return v[np.array(faces)]


def brute_zbuffer(tri: np.ndarray, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """Highest triangle over each node by barycentric coordinates, node by node."""
    out = np.full((len(ys), len(xs)), -np.inf)
    for t in tri:
        (ax, ay, az), (bx, by, bz), (cx, cy, cz) = t
        det = (by - cy) * (ax - cx) + (cx - bx) * (ay - cy)
        if abs(det) < 1e-12:
            continue
        for i, y in enumerate(ys):
            for k, x in enumerate(xs):
                l1 = ((by - cy) * (x - cx) + (cx - bx) * (y - cy)) / det
                l2 = ((cy - ay) * (x - cx) + (ax - cx) * (y - cy)) / det
                l3 = 1 - l1 - l2
                if min(l1, l2, l3) >= -1e-9:
                    out[i, k] = max(out[i, k], l1 * az + l2 * bz + l3 * cz)
    return out


@pytest.mark.skipif(not (DATA / "mount_rush.stl").exists(), reason="no shared data")
def test_mount_rushmore_reproduces_the_reference_zmap() -> None:
    tri = read_stl((DATA / "mount_rush.stl").read_bytes())
    ref = np.load(DATA / "mount_rush_zmap_0.1mm.npy", allow_pickle=False).astype(np.float64)
    grid = zmap_grid(tri, dx=0.1)
    # README: node (0, 0) at the model's lower-left corner; outside nodes 1 mm below it
    assert (grid.ny, grid.nx) == ref.shape
    assert grid.x0 == pytest.approx(-40.958, abs=1e-3) and grid.y0 == pytest.approx(-24.696,
                                                                                       abs=1e-3)
    res = rasterise(tri, grid, background=float(tri[:, :, 2].min()) - 1.0)
    assert np.abs(res.z - ref).max() <= 1e-4


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 12), st.booleans())
def test_zbuffer_matches_a_brute_force_one(seed: int, n: int, skew: bool) -> None:
    rng = np.random.default_rng(seed)
    tri = rng.uniform(-5, 5, (n, 3, 3))
    if skew:  # thin, steep triangles
        tri[:, 2, :2] = tri[:, 0, :2] + rng.uniform(-0.05, 0.05, (n, 2))
    grid = zmap_grid(tri, dx=0.37, dy=0.29)
    res = rasterise(tri, grid, background=-99.0)
    xs = grid.x0 + grid.dx * np.arange(grid.nx)
    ys = grid.y0 + grid.dy * np.arange(grid.ny)
    ref = brute_zbuffer(tri, xs, ys)
    hit = np.isfinite(ref)
    # nodes within rounding of an edge may go either way; every other must agree
    ambiguous = (res.covered != hit)
    assert ambiguous.sum() <= max(1, hit.sum() // 200)
    both = hit & res.covered
    np.testing.assert_allclose(res.z[both], ref[both], atol=1e-9)
    assert (res.z[~res.covered] == -99.0).all()


def test_a_cap_floating_over_a_block_is_an_undercut_and_the_block_is_not() -> None:
    tri = np.concatenate([box(0, 10, 0, 10, 0, 2), box(3, 6, 3, 6, 4, 5)])
    grid = zmap_grid(tri, dx=0.5)
    res = rasterise(tri, grid)
    xs = grid.x0 + grid.dx * np.arange(grid.nx)
    ys = grid.y0 + grid.dy * np.arange(grid.ny)
    under = ((xs[None, :] >= 3) & (xs[None, :] <= 6)) & ((ys[:, None] >= 3) & (ys[:, None] <= 6))
    np.testing.assert_array_equal(res.undercut, under)
    np.testing.assert_array_equal(res.z, np.where(under, 5.0, 2.0))
    assert res.covered.all() and res.background == 0.0


def test_ascii_and_binary_stl_read_the_same_triangles() -> None:
    tri = box(0, 1, 0, 2, 0, 3)
    a, b = read_stl(stl_bytes(tri, ascii=True)), read_stl(stl_bytes(tri))
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(a, tri)


@pytest.mark.parametrize(("data", "reason"), [
    (b"", "empty"),
    (b"hello, this is not an STL file at all", "no triangles"),
    (stl_bytes(box(0, 1, 0, 1, 0, 1))[:300], "STL"),
    (stl_bytes(box(0, 1, 0, 1, 0, 1), ascii=True)[:200], "STL"),
])
def test_bad_files_are_named(data: bytes, reason: str) -> None:
    with pytest.raises(InvalidInputError) as err:
        read_stl(data)
    assert err.value.field == "stl" and reason in err.value.reason


def test_nan_vertices_are_refused() -> None:
    tri = box(0, 1, 0, 1, 0, 1)
    tri[4, 1, 2] = np.nan
    with pytest.raises(InvalidInputError, match="triangle 4 has a non-finite"):
        read_stl(stl_bytes(tri))


def test_a_cell_size_over_the_cell_limit_is_refused_before_any_work() -> None:
    tri = box(0, 100, 0, 100, 0, 1)
    with pytest.raises(LimitExceededError) as err:
        zmap_grid(tri, dx=0.01, max_cells=1_000_000)
    assert err.value.field == "dx" and "10001 x 10001" in err.value.reason


def test_many_overlapping_large_triangles_are_refused_by_the_work_bound() -> None:
    tri = np.repeat(box(0, 100, 0, 100, 0, 1), 50, axis=0)
    grid = zmap_grid(tri, dx=1.0)
    with pytest.raises(LimitExceededError, match="pairs"):
        rasterise(tri, grid, max_pairs=100_000)
