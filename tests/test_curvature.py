"""Concave radius estimation on grids with known curvature."""

from __future__ import annotations

import numpy as np
import pytest

from zwcore.grid.curvature import (
    concave_curvature,
    max_principal_curvature,
    min_concave_radius,
    steepest_slope,
)


def _grid(half: float, h: float) -> tuple[np.ndarray, np.ndarray]:
    x = np.arange(-half, half + 1e-9, h)
    return np.meshgrid(x, x)


def _bowl(r: float, h: float, max_slope_deg: float = 55.0) -> np.ndarray:
    """A spherical bowl of radius r filling the grid (corner slope max_slope_deg)."""
    half = r * np.sin(np.radians(max_slope_deg)) / np.sqrt(2.0)
    xx, yy = _grid(half, h)
    return r - np.sqrt(r * r - xx**2 - yy**2)


def _pocket(r: float, h: float) -> np.ndarray:
    """A spherical bowl sunk into a flat plate, rim at 45 degrees."""
    a = r * np.sin(np.radians(45.0))
    xx, yy = _grid(1.3 * a, h)
    return r - np.sqrt(r * r - np.minimum(np.hypot(xx, yy), a) ** 2)


@pytest.mark.parametrize("r", [3.5, 7.0, 20.0])
def test_sphere_bowl_radius(r: float) -> None:
    h = r / 70.0
    est = min_concave_radius(_bowl(r, h), h, h)
    # One-sided slopes in the metric make it slightly conservative, never large.
    assert 0.9 * r <= est <= 1.01 * r


@pytest.mark.parametrize("r", [3.5, 7.0])
def test_bowl_in_plate_rim_is_not_a_valley(r: float) -> None:
    h = r / 70.0
    est = min_concave_radius(_pocket(r, h), h, h)
    assert 0.78 * r <= est <= 1.01 * r


def test_sphere_bottom_is_exact() -> None:
    r, h = 5.0, 0.05
    k = max_principal_curvature(_bowl(r, h), h, h)
    c = k.shape[0] // 2
    assert k[c, c] == pytest.approx(1.0 / r, rel=1e-3)


@pytest.mark.parametrize("angle", [0.0, 22.5, 30.0, 45.0, 90.0])
def test_cylinder_groove_any_direction(angle: float) -> None:
    r, h = 6.0, 0.1
    xx, yy = _grid(4.0, h)
    u = xx * np.cos(np.radians(angle)) + yy * np.sin(np.radians(angle))
    z = r - np.sqrt(r * r - u**2)
    est = min_concave_radius(z, h, h)
    assert 0.85 * r <= est <= 1.01 * r


@pytest.mark.parametrize("wall_deg", [30.0, 45.0, 60.0])
def test_fillet_between_floor_and_wall(wall_deg: float) -> None:
    r, h = 5.0, 0.05
    al = np.radians(wall_deg)
    x = np.arange(0.0, 30.0, h)
    x1 = 10.0
    xt = x1 + r * np.sin(al)
    zt = r - r * np.cos(al)
    prof = np.where(x < x1, 0.0, np.where(x < xt, r - np.sqrt(np.maximum(r * r - (x - x1) ** 2, 0)),
                                          zt + np.tan(al) * (x - xt)))
    z = np.tile(prof, (9, 1))
    est = min_concave_radius(z, h, h)
    assert 0.9 * r <= est <= 1.01 * r
    # Transposed: the same fillet running the other way.
    assert min_concave_radius(z.T.copy(), h, h) == pytest.approx(est, rel=1e-12)


def test_planes_and_domes_have_no_concave_radius() -> None:
    xx, yy = _grid(5.0, 0.1)
    assert min_concave_radius(3.0 + 0.4 * xx - 1.3 * yy, 0.1, 0.1) == np.inf
    dome = np.sqrt(50.0**2 - xx**2 - yy**2)
    assert min_concave_radius(dome, 0.1, 0.1) == np.inf
    assert min_concave_radius(np.full((2, 2), 7.0), 1.0, 1.0) == np.inf


def test_sharp_crease_is_grid_scale() -> None:
    # A V groove with slope jump 2s: radius about h / (2s), sharper on a finer grid.
    for h in (0.5, 0.1):
        xx, _ = _grid(5.0, h)
        z = 0.3 * np.abs(xx)
        est = min_concave_radius(z, h, h)
        assert est == pytest.approx(h / 0.6, rel=0.05)


def test_steep_wall_foot_is_sharp() -> None:
    # The foot of a near-vertical wall is a sharp corner, not a big radius.
    h = 0.1
    z = np.zeros((7, 40))
    z[:, 20:] = 25.0
    assert min_concave_radius(z, h, h) < h


def test_noise_only_lowers_the_radius_and_smoothing_recovers_it() -> None:
    r, h = 7.0, 0.1
    z = _bowl(r, h)
    noisy = z + np.random.default_rng(1).normal(0.0, 2e-4, z.shape)
    raw = min_concave_radius(noisy, h, h)
    assert raw < min_concave_radius(z, h, h)
    smooth = min_concave_radius(noisy, h, h, smoothing=3.0)
    assert 0.85 * r <= smooth <= 1.05 * r


def test_concave_curvature_is_non_negative_and_anisotropic_spacing() -> None:
    # z = x^2/(2a) + y^2/(2b): curvatures 1/a, 1/b at the bottom.
    sx, sy = 0.05, 0.2
    x = np.arange(-2.0, 2.0 + 1e-9, sx)
    y = np.arange(-2.0, 2.0 + 1e-9, sy)
    xx, yy = np.meshgrid(x, y)
    z = xx**2 / (2 * 8.0) + yy**2 / (2 * 4.0)
    k = concave_curvature(z, sx, sy)
    assert (k >= 0).all()
    c = (k.shape[0] // 2, k.shape[1] // 2)
    assert k[c] == pytest.approx(1 / 4.0, rel=1e-6)


def test_steepest_slope_exact_on_bilinear() -> None:
    z = np.array([[0.0, 1.0], [2.0, 3.0]])
    assert steepest_slope(z, 1.0, 1.0) == pytest.approx(np.hypot(1.0, 2.0))
    z = np.array([[0.0, 0.0], [0.0, 4.0]])  # twisted patch: steepest at the raised corner
    assert steepest_slope(z, 2.0, 1.0) == pytest.approx(np.hypot(2.0, 4.0))
