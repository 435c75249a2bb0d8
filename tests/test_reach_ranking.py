"""The reach estimate's ranking of finishing chains by the positions that really cut.

The compiled cutting test (:func:`zwcore.scanline._reach_cut.cutting_positions`,
:class:`~zwcore.scanline._reach_cut.CuttingRegion`) is checked against a brute force written
here (every node offset of the ball, numpy), the rest carried to a finer lattice against
the fine lattice's own rest, and the pruned chain search against the full one.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.test_reach import _fillet, _pocket, _rect_pocket
from tests.test_scanline_stock import _trench
from zwcore.grid.tools import Tool, default_tools
from zwcore.grid.zmap import ZMap
from zwcore.scanline import _regions
from zwcore.scanline._reach import ball_reach
from zwcore.scanline._reach_cut import CuttingRegion, cutting_positions, material_grid

BALLS = list(default_tools("ball"))


def _known_parts() -> dict[str, ZMap]:
    """The known-answer parts of ``tests/test_reach.py`` and the trenches of
    ``tests/test_scanline_stock.py`` (as ``bench/bench_reach.py`` writes them out)."""
    parts = {"R 8 pocket": _pocket(), "45° fillet": _fillet(45.0)[0],
             "rectangular pocket": _rect_pocket()}
    for width in (2.0, 3.0):
        parts[f"trench {width:g} mm"] = _trench(width=width)
    return parts


def _offsets(radius: float, dx: float, dy: float) -> list[tuple[int, int, float]]:
    """Every node offset within the ball (``d² <= R²``) with ``h`` there."""
    ra, rb = int(radius // dy) + 1, int(radius // dx) + 1
    return [(a, b, radius - math.sqrt(max(radius**2 - (a * dy) ** 2 - (b * dx) ** 2, 0.0)))
            for a in range(-ra, ra + 1) for b in range(-rb, rb + 1)
            if (a * dy) ** 2 + (b * dx) ** 2 <= radius**2]


def brute_cuts(material: np.ndarray, cl: np.ndarray, radius: float, dx: float, dy: float,
               positions: np.ndarray) -> np.ndarray:
    """``cl(c) < max over nodes q within R of material(q) - h(|q - c|)`` at every position."""
    ny, nx = material.shape
    out = np.zeros(material.shape, dtype=bool)
    offs = _offsets(radius, dx, dy)
    for i, k in zip(*np.nonzero(positions), strict=True):
        top = max((material[i + a, k + b] - h for a, b, h in offs
                   if 0 <= i + a < ny and 0 <= k + b < nx), default=-np.inf)
        out[i, k] = cl[i, k] < top
    return out


def brute_cl(z: np.ndarray, radius: float, dx: float, dy: float) -> np.ndarray:
    """Nodal drop-cutter CL at every node, the part continued by its edge heights."""
    offs = _offsets(radius, dx, dy)
    p = max(max(abs(a), abs(b)) for a, b, _ in offs) + 1
    zp = np.pad(z, p, mode="edge")
    ny, nx = z.shape
    cl = np.full(z.shape, -np.inf)
    for a, b, h in offs:
        cl = np.maximum(cl, zp[p + a:p + a + ny, p + b:p + b + nx] - h)
    return cl


def _surface(rng: np.random.Generator, ny: int, nx: int, h: float) -> np.ndarray:
    y, x = np.mgrid[0:ny, 0:nx] * h
    z = np.zeros((ny, nx))
    for _ in range(4):
        cx, cy, w = rng.uniform(0, max(nx, ny) * h, 3)
        z += rng.uniform(-3, 3) * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (0.3 + w))
    return z + np.where(x > rng.uniform(0, nx * h), rng.uniform(-3, 3), 0.0)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), ny=st.integers(1, 30), nx=st.integers(1, 30),
       dx=st.floats(0.1, 0.5), dy=st.floats(0.1, 0.5), radius=st.floats(0.05, 3.0),
       share=st.floats(0.0, 1.0))
def test_cutting_positions_is_the_brute_force_test(seed: int, ny: int, nx: int, dx: float,
                                                   dy: float, radius: float,
                                                   share: float) -> None:
    # Material on a share of the nodes (-inf elsewhere), tips anywhere around it: the
    # block skipping and the early exit change nothing.
    rng = np.random.default_rng(seed)
    material = np.where(rng.random((ny, nx)) < share, rng.uniform(-2, 2, (ny, nx)), -np.inf)
    cl = rng.uniform(-2.5, 2.5, (ny, nx))
    positions = rng.random((ny, nx)) < 0.7
    got = cutting_positions(material, cl, radius, dx, dy, positions)
    np.testing.assert_array_equal(got, brute_cuts(material, cl, radius, dx, dy, positions))


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), ny=st.integers(1, 28), nx=st.integers(1, 28),
       h=st.floats(0.1, 0.4), radius=st.floats(0.1, 2.5), flute=st.floats(0.2, 4.0))
def test_cutting_region_is_the_brute_force_region(seed: int, ny: int, nx: int, h: float,
                                                  radius: float, flute: float) -> None:
    # The positions within the radius of the seeds whose ball, at its nodal CL on the part
    # (edge heights continued), cuts the material; their layers; twice on one object
    # (the CL kept from the first call, the stamps renewed).
    rng = np.random.default_rng(seed)
    z = _surface(rng, ny, nx, h)
    z.setflags(write=False)  # a stored grid: read-only inputs are accepted
    cl = brute_cl(z, radius, h, h)
    known = np.where(rng.random(z.shape) < 0.3, cl, np.nan)  # some CL given up front
    known.setflags(write=False)
    cutter = CuttingRegion(z, h, h, radius, known)
    offs = _offsets(radius, h, h)
    for _ in range(2):
        rest = np.where(rng.random(z.shape) < 0.4, rng.uniform(0.0, 3.0, z.shape), 0.0)
        nodes = np.flatnonzero(rest > 0.01)
        heights = z.ravel()[nodes] + rest.ravel()[nodes]
        grid, blocks = material_grid(z.shape, nodes, heights)
        ref_grid = np.full(z.shape, -np.inf)
        ref_grid.flat[nodes] = heights
        np.testing.assert_array_equal(grid, ref_grid)
        seeds = nodes[rng.random(nodes.size) < 0.5]
        skip = rng.random(z.shape) < 0.1
        grid.setflags(write=False)
        rest.setflags(write=False)
        count, layers = cutter.layers(seeds, grid, blocks, rest, flute, skip)
        near = np.zeros(z.shape, dtype=bool)
        for s in seeds:
            i, k = divmod(int(s), nx)
            for a, b, _ in offs:
                if 0 <= i + a < ny and 0 <= k + b < nx:
                    near[i + a, k + b] = True
        ref = brute_cuts(ref_grid, cl, radius, h, h, near & ~skip)
        np.testing.assert_array_equal(cutter.last_region(), ref)
        assert count == int(ref.sum())
        want = float(np.maximum(np.ceil(rest[ref] / flute), 1.0).sum())
        assert layers == pytest.approx(want, rel=1e-12)
        computed = ~np.isnan(cutter.cl)
        np.testing.assert_allclose(cutter.cl[computed], cl[computed], rtol=0, atol=1e-12)


def _bilinear(coarse: np.ndarray, f: int, shape: tuple[int, int]) -> np.ndarray:
    """``coarse`` at the nodes of an ``f`` times finer lattice (clamped at the last node)."""
    i = np.arange(shape[0]) / f
    k = np.arange(shape[1]) / f
    i0 = np.minimum(np.floor(i).astype(int), coarse.shape[0] - 1)
    k0 = np.minimum(np.floor(k).astype(int), coarse.shape[1] - 1)
    i1, k1 = np.minimum(i0 + 1, coarse.shape[0] - 1), np.minimum(k0 + 1, coarse.shape[1] - 1)
    wa, wb = (i - np.floor(i))[:, None], (k - np.floor(k))[None, :]
    return ((1 - wa) * (1 - wb) * coarse[np.ix_(i0, k0)] + (1 - wa) * wb * coarse[np.ix_(i0, k1)]
            + wa * (1 - wb) * coarse[np.ix_(i1, k0)] + wa * wb * coarse[np.ix_(i1, k1)])


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), my=st.integers(1, 9), mx=st.integers(1, 9),
       f=st.sampled_from([2, 4, 8]))
def test_rest_carried_to_a_finer_lattice_is_the_lesser_interpolant(seed: int, my: int,
                                                                   mx: int, f: int) -> None:
    # Where a cell corner's rest exceeds the tolerance: the lesser of the rest and the
    # closing less the fine part, both interpolated bilinearly; 0 elsewhere.
    rng = np.random.default_rng(seed)
    tol = 0.01
    shape = ((my - 1) * f + 1, (mx - 1) * f + 1)
    zf = rng.uniform(-3, 3, shape)
    zc = zf[::f, ::f]
    rest = np.where(rng.random((my, mx)) < 0.5, rng.uniform(0, 2, (my, mx)), 0.0)
    got = _regions._upsample_where(rest, zc, f, zf, tol)
    want = np.minimum(_bilinear(rest, f, shape),
                      np.maximum(_bilinear(zc + rest, f, shape) - zf, 0.0))
    near = _bilinear((rest > tol).astype(float), f, shape) > 0  # a corner over tol
    # (a corner whose weight is 0 counts too: the kernel asks the four corners)
    corners = np.zeros(shape, dtype=bool)
    for i in range(shape[0]):
        for k in range(shape[1]):
            a0, b0 = min(i // f, my - 1), min(k // f, mx - 1)
            a1, b1 = min(a0 + 1, my - 1), min(b0 + 1, mx - 1)
            corners[i, k] = (rest[[a0, a0, a1, a1], [b0, b1, b0, b1]] > tol).any()
    assert (near <= corners).all()
    np.testing.assert_allclose(got[corners], want[corners], rtol=0, atol=1e-12)
    assert (got[~corners] == 0.0).all()


@pytest.mark.parametrize("name", ["trench 2 mm", "trench 3 mm"])
def test_rest_carried_across_a_slot_makes_up_no_material(name: str) -> None:
    # A large ball's rest computed on its coarse lattice and carried to the fine nodes
    # stands nowhere above the rest the same ball leaves computed on the fine nodes
    # themselves: none on the plate beside the trench (the rest alone, interpolated
    # across the trench's edge, stood up to 10 mm over the plate), and in the trench no
    # more than its depth.
    zmap = _known_parts()[name]
    tol = 0.01
    reach = _regions._Reach(zmap.z, zmap.dx, zmap.dy, tol)
    for prev in (10.0, 6.0):
        assert _regions.lattice(prev, zmap.dx, zmap.dy) > 1
        fine = ball_reach(zmap.z, zmap.dx, zmap.dy, prev, tol).rest
        carried = reach.material(prev, 1).rest
        assert carried.max() > 0.5 * fine.max() > 9.0  # the trench is left
        assert (carried <= fine + 1e-9).all()
        assert (carried[zmap.z == 0.0] == 0.0).all()


@pytest.mark.parametrize("name", ["R 8 pocket", "45° fillet", "rectangular pocket",
                                  "trench 2 mm", "trench 3 mm"])
def test_pruned_chain_search_finds_the_full_searchs_chain(name: str) -> None:
    # The search skips a pair when the pair's cost after a smaller previous ball already
    # loses; on the known-answer parts it picks what trying every pair picks, with fewer
    # pairs.
    zmap = _known_parts()[name]
    asked: dict[bool, int] = {}
    chains = {}
    for bound in (True, False):
        reach = _regions._Reach(zmap.z, zmap.dx, zmap.dy, 0.01)
        cost = reach.cost
        calls = [0]

        def counted(prev: float, nxt: Tool, cost: Callable[[float, Tool], float | None] = cost,
                    calls: list[int] = calls) -> float | None:
            calls[0] += 1
            return cost(prev, nxt)

        reach.cost = counted  # type: ignore[method-assign]
        chains[bound] = _regions._plan(BALLS, reach, bound)[0]
        asked[bound] = calls[0]
    assert chains[True] == chains[False]
    assert asked[True] <= asked[False]
