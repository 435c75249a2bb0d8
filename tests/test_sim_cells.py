"""The per-cell bound of small balls' bilinear drop-cutter (``zwcore.sim._cells``).

Checked against an independent computation: the true CL over the bilinear surface
sampled densely inside the disc (a lower bound of it: the result must never be below),
and against the exact answer on an inclined plane (``z(c) + R (sec θ - 1)``)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from zwcore import ZMap
from zwcore.grid.tools import Tool
from zwcore.sim import drop_cutter
from zwcore.sim._cells import TIGHT_MAX_CELLS, cells_within, tighten
from zwcore.sim._drop_bb import drop_cutter_pruned


def dense_cl(z: np.ndarray, dx: float, dy: float, radius: float, i: int, k: int,
             per: int = 24) -> float:
    """The ball's CL at node ``(i, k)`` over the bilinear surface sampled ``per`` times a
    cell along each axis inside the disc: never above the true CL."""
    ny, nx = z.shape
    cx, cy = k * dx, i * dy
    xs = np.arange(max(0.0, cx - radius), min((nx - 1) * dx, cx + radius) + 1e-12, dx / per)
    ys = np.arange(max(0.0, cy - radius), min((ny - 1) * dy, cy + radius) + 1e-12, dy / per)
    xx, yy = np.meshgrid(xs, ys)
    d2 = (xx - cx) ** 2 + (yy - cy) ** 2
    inside = d2 <= radius * radius
    xx, yy, d2 = xx[inside], yy[inside], d2[inside]
    fx, fy = xx / dx, yy / dy
    k0 = np.minimum(np.floor(fx).astype(int), nx - 2)
    i0 = np.minimum(np.floor(fy).astype(int), ny - 2)
    s, t = fx - k0, fy - i0
    zb = (z[i0, k0] * (1 - s) * (1 - t) + z[i0, k0 + 1] * s * (1 - t)
          + z[i0 + 1, k0] * (1 - s) * t + z[i0 + 1, k0 + 1] * s * t)
    return float((zb - (radius - np.sqrt(radius * radius - d2))).max())


def _surface(kind: str, n: int, m: int, dx: float, dy: float, rng: np.random.Generator
             ) -> np.ndarray:
    y, x = np.mgrid[0:n, 0:m]
    x, y = x * dx, y * dy
    z = 2.0 * np.sin(x * rng.uniform(0.2, 1.5)) * np.cos(y * rng.uniform(0.2, 1.5))
    if kind == "rough":
        z = z + 0.2 * rng.standard_normal(z.shape)
    elif kind == "steps":
        z = np.round(2.0 * z) / 2.0
    elif kind == "wall":
        z = np.where(x > 0.5 * x.max(), z + 5.0, z)
    return z


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 2**32 - 1), st.sampled_from(["smooth", "rough", "steps", "wall"]),
       st.sampled_from([(0.1, 0.1), (0.25, 0.2), (0.4, 0.4), (0.78, 0.6)]),
       st.floats(0.3, 3.0))
def test_never_below_the_bilinear_surface_and_never_above_the_plane_bound(
        seed: int, kind: str, spacing: tuple[float, float], radius: float) -> None:
    dx, dy = spacing
    if cells_within(radius, dx, dy) > TIGHT_MAX_CELLS:
        radius = 0.5 * radius
    rng = np.random.default_rng(seed)
    z = _surface(kind, 24, 21, dx, dy, rng)
    tool = Tool("t", "ball", 2.0 * radius, 10.0)
    part = ZMap(z, dx=dx, dy=dy)
    loose = drop_cutter_pruned(part, tool)
    cl = drop_cutter(part, tool, method="pruned", cell_bound=True)
    assert np.all(cl <= loose)
    for i, k in zip(rng.integers(0, 24, 12), rng.integers(0, 21, 12), strict=True):
        assert cl[i, k] >= dense_cl(z, dx, dy, radius, int(i), int(k)) - 1e-12
    # the dilation method gets the same bound
    by_dilation = drop_cutter(part, tool, cell_bound=True)
    np.testing.assert_allclose(by_dilation, cl, rtol=0, atol=5e-5)


@pytest.mark.parametrize(("dx", "dy", "radius"), [(0.1, 0.1, 0.5), (0.4, 0.3, 1.5),
                                                  (0.78, 0.78, 4.0)])
def test_inclined_plane_is_near_exact(dx: float, dy: float, radius: float) -> None:
    """On a plane of slope θ the CL is ``z(c) + R (sec θ - 1)`` wherever the disc lies on
    the grid; the plane bound stands above it by about ``cell² / 8R cos³θ``, the per-cell
    bound by a fifth of that or less (measured on this 25° plane: 10-14 %: the ball's
    curvature grows from the cell's nearest point to the contact)."""
    y, x = np.mgrid[0:40, 0:40]
    a, b = 0.4, -0.25
    z = a * x * dx + b * y * dy
    tool = Tool("t", "ball", 2.0 * radius, 10.0)
    part = ZMap(z, dx=dx, dy=dy)
    exact = z + radius * (math.sqrt(1.0 + a * a + b * b) - 1.0)
    A, B = math.ceil(radius / dy) + 1, math.ceil(radius / dx) + 1
    inner = (slice(A, 40 - A), slice(B, 40 - B))
    loose = drop_cutter_pruned(part, tool)[inner] - exact[inner]
    tight = drop_cutter(part, tool, method="pruned", cell_bound=True)[inner] - exact[inner]
    assert tight.min() >= -1e-9
    assert loose.max() > 0.0
    assert tight.max() <= 0.2 * loose.max() + 1e-9


def test_coarse_cells_close_in_on_the_surface() -> None:
    """A smooth part on cells about a ball radius wide: the per-cell bound's excess over
    dense sampling is a tenth of the plane bound's or less at the median (measured: a Ø3
    at 0.78 mm, 0.205 -> 0.006 mm)."""
    rng = np.random.default_rng(3)
    n = 33
    x = np.linspace(0.0, 25.0, n)
    xx, yy = np.meshgrid(x, x)
    z = 8.0 * np.sin(xx / 9.0) * np.cos(yy / 13.0) + 0.002 * (xx - 12.0) ** 2
    dx = x[1] - x[0]
    tool = Tool("t", "ball", 3.0, 10.0)
    part = ZMap(z, dx=dx, dy=dx)
    loose = drop_cutter_pruned(part, tool)
    cl = drop_cutter(part, tool, cell_bound=True)
    old, new = [], []
    for i, k in zip(rng.integers(0, n, 40), rng.integers(0, n, 40), strict=True):
        ref = dense_cl(z, dx, dx, 1.5, int(i), int(k))
        assert cl[i, k] >= ref - 1e-12
        old.append(loose[i, k] - ref)
        new.append(cl[i, k] - ref)
    assert np.median(new) <= 0.1 * np.median(old)


def test_order_rows_and_mask_do_not_change_a_node() -> None:
    """A node's value is the max over its cells of each cell's least bound: the same
    whatever order the looks take (the transposed grid), on some rows only, or on the
    masked nodes only (the others keep the plane bound)."""
    rng = np.random.default_rng(7)
    z = _surface("rough", 30, 26, 0.2, 0.25, rng)
    part = ZMap(z, dx=0.2, dy=0.25)
    loose = drop_cutter_pruned(part, Tool("t", "ball", 2.2, 10.0))
    whole = tighten(z, 0.2, 0.25, 1.1, loose)
    tr = tighten(np.ascontiguousarray(z.T), 0.25, 0.2, 1.1, np.ascontiguousarray(loose.T))
    np.testing.assert_allclose(tr.T, whole, rtol=0, atol=1e-12)
    rows = np.array([0, 5, 29])
    some = tighten(z, 0.2, 0.25, 1.1, loose, rows=rows)
    np.testing.assert_array_equal(some[rows], whole[rows])
    np.testing.assert_array_equal(np.delete(some, rows, axis=0), np.delete(loose, rows, axis=0))
    where = rng.random(z.shape) < 0.3
    masked = tighten(z, 0.2, 0.25, 1.1, loose, where=where)
    np.testing.assert_array_equal(masked[where], whole[where])
    np.testing.assert_array_equal(masked[~where], loose[~where])
    assert (whole < loose).mean() > 0.5
