"""The gouge measure's shortcuts on stage-model paths (issue 12), against independent
computations: the coarser first look and the lower bound on every ``block``-th node change
no value a path depends on (against the exact sweep, and the bound against a brute-force
sweep of those nodes); segments entered on their own are each lifted by their own moves
only (a wall between two stretches of a line lifts neither), and every point is counted
with its own segment; a depth pass's plateaus take their own heights as CL."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.test_toolpath import wavy_part
from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.sim.cutting import footprint
from zwcore.toolpath._polyline import PartBounds, PartGouge
from zwcore.toolpath._scan_cl import _plateau_cl
from zwcore.toolpath.scanline_paths import _Polyline, _segments, sim_cl_heights
from zwcore.toolpath.sweep import GridFrame, sweep_moves


def _brute_gouge(part: ZMap, radius: float, p0: np.ndarray, p1: np.ndarray,
                 every: int = 1, samples: int = 2001) -> np.ndarray:
    """Per ball move, the largest depth of the nodes on every ``every``-th row and column
    below the ball's lower surface, over ``samples`` positions along the move (a lower
    bound of the exact value, within the sampling step of it)."""
    ny, nx = part.shape
    yy, xx = np.mgrid[0:ny:every, 0:nx:every]
    qx, qy = part.x0 + xx * part.dx, part.y0 + yy * part.dy
    qz = part.z[::every, ::every]
    t = np.linspace(0.0, 1.0, samples)
    out = np.full(len(p0), -np.inf)
    for m, (a, b) in enumerate(zip(p0, p1, strict=True)):
        c = a[None] + t[:, None] * (b - a)[None]  # (samples, 3) tips
        near = (np.abs(qx - a[0]) < abs(b[0] - a[0]) + radius + 1) & (
            np.abs(qy - a[1]) < abs(b[1] - a[1]) + radius + 1)
        if not near.any():
            continue
        d2 = ((qx[near][None] - c[:, :1]) ** 2 + (qy[near][None] - c[:, 1:2]) ** 2)
        low = c[:, 2:3] + radius - np.sqrt(np.maximum(radius * radius - d2, 0.0))
        depth = np.where(d2 < radius * radius, qz[near][None] - low, -np.inf)
        out[m] = depth.max()
    return out


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 10_000), st.sampled_from([2, 3, 5]), st.floats(0.0, 0.5))
def test_the_coarse_looks_and_the_lower_bound_change_no_value_that_matters(seed, block, tol):
    """With per-move thresholds (``above``): a value above its threshold is a lower bound
    of the exact gouge (so the exact one lies above it too); every other value is the
    exact one where the move gouges, and ``<= 0`` where it does not."""
    part = wavy_part(61, 0.25, seed)
    rng = np.random.default_rng(seed)
    tool = Tool("T", "ball", rng.uniform(0.5, 3.0), 20.0)
    lo = np.array([part.x0, part.y0, part.z.min() - 1])
    hi = np.array([part.x0 + 15, part.y0 + 15, part.z.max() + 2])
    p0 = rng.uniform(lo, hi, (300, 3))
    p1 = p0 + rng.normal(0, 1.5, (300, 3))
    above = np.where(rng.random(300) < 0.7, tol, np.inf)
    exact = PartGouge(part, tool, 1)(p0, p1)
    bounds = PartBounds(part)
    got = PartGouge(part, tool, block, bounds)(p0, p1, above)
    low = got > above
    assert np.all(exact[low] > above[low])
    assert np.all(got[low] <= exact[low] + 1e-9)
    hit = ~low & (exact > 0)
    np.testing.assert_array_equal(got[hit], exact[hit])
    assert np.all(got[~low & ~hit] <= 0)
    # without thresholds: the exact values (as the single coarse look gave)
    plain = PartGouge(part, tool, block, bounds)(p0, p1)
    np.testing.assert_array_equal(plain[exact > 0], exact[exact > 0])
    assert np.all(plain[exact <= 0] <= 0)
    # a value above its threshold is the exact one or the exact sweep of every block-th
    # node (the part with its other nodes sunk out of reach, swept by the plain kernel),
    # and at least a brute-force sweep of those nodes over sampled positions
    if low.any():
        sunk = np.full(part.shape, part.z.min() - 1e3)
        sunk[::block, ::block] = part.z[::block, ::block]
        frame = GridFrame(part.x0, part.y0, part.dx, part.dy, part.shape)
        _, sub = sweep_moves(frame, p0, p1, tool.radius, True, sunk, ref=sunk, apply=False)
        assert np.all((np.abs(got[low] - sub[low]) <= 1e-9) | (got[low] == exact[low]))
        pick = np.flatnonzero(low)[:20]
        brute = _brute_gouge(part, tool.radius, p0[pick], p1[pick], every=block)
        assert np.all(brute <= got[pick] + 1e-9)


def _flat_with_wall(height: float) -> ZMap:
    z = np.zeros((21, 61))
    z[:, 28:33] = height  # a wall across every line, x in [2.8, 3.2] mm
    return ZMap(z, 0.0, 0.0, 0.1, 0.1)


def test_a_wall_between_two_stretches_of_a_line_lifts_neither():
    """Two stretches of one line on a flat part, entered on their own, with a 20 mm wall
    between them: every point stays on the flat (the move from one to the other is no
    move of the path); the former measure swept that move and lifted both stretches' ends
    by the wall's height."""
    part = _flat_with_wall(20.0)
    tool = Tool("B2", "ball", 0.5, 10.0)
    poly = _Polyline(part, tool, True, 0.0025, 4, 0.0025, 0.1 / 16)
    u = np.array([0.0, 0.5, 1.0, 2.0, 4.5, 5.0, 5.5, 6.0])
    raw = (u, np.full(8, 1.0), np.zeros(8), np.array([4, 4]))
    pts, kept, lift, _ = _segments(raw, poly)
    assert kept.tolist() == [2, 2]  # flat: each stretch one move
    assert lift == 0.0 and np.all(pts[:, 2] == 0.0)
    # each stretch's own moves are still swept and clear the part
    first = np.cumsum(kept) - kept
    for a, n in zip(first, kept, strict=True):
        g = PartGouge(part, tool, 1)(pts[a:a + n - 1], pts[a + 1:a + n])
        assert np.all(g <= 1e-9)


def test_a_stretch_next_to_the_wall_is_lifted_by_its_own_moves():
    """A stretch that runs into the wall's reach is lifted out of it (its own moves)."""
    part = _flat_with_wall(2.0)
    tool = Tool("B1", "ball", 1.0, 10.0)  # radius 0.5 mm
    poly = _Polyline(part, tool, True, 0.0025, 4, 0.0025, 0.1 / 16)
    u = np.array([0.0, 1.0, 2.0, 2.5, 4.5, 5.0, 5.5, 6.0])
    raw = (u, np.full(8, 1.0), np.zeros(8), np.array([4, 4]))
    pts, kept, lift, _ = _segments(raw, poly)
    first = np.cumsum(kept) - kept
    for a, n in zip(first, kept, strict=True):
        g = PartGouge(part, tool, 1)(pts[a:a + n - 1], pts[a + 1:a + n])
        assert np.all(g <= 1e-9)
    assert lift > 1.0  # the first stretch's end, 0.3 mm from the wall, came up
    assert np.all(pts[first[1]:, 2] == 0.0)  # the second starts 1.3 mm past it


def test_every_point_counts_with_its_own_segment():
    """Segments from 0 to 41.6 mm (span 42.6): ``n * span / span`` rounds below ``n`` for
    some ``n`` (7 among them), which gave a segment's first point to the one before."""
    span = 42.6
    n = np.arange(1, 20)
    assert np.any(np.floor((0.0 + n * span) / span) != n)  # the premise
    part = ZMap(np.zeros((41, 451)), 0.0, 0.0, 0.1, 0.1)
    tool = Tool("B2", "ball", 0.5, 10.0)
    poly = _Polyline(part, tool, True, 0.0025, 4, 0.0025, 0.1 / 16)
    count = 20
    off = 0.5 + (np.arange(count) % 7) * 0.5  # neighbours on other lines
    u = np.tile([0.0, 20.0, 41.6], count)
    raw = (u, np.repeat(off, 3), np.zeros(3 * count), np.full(count, 3))
    pts, kept, _, _ = _segments(raw, poly)
    assert kept.sum() == len(pts) and np.all(kept >= 2)
    owner = np.repeat(np.arange(count), kept)
    np.testing.assert_array_equal(pts[:, 1], np.round(off[owner], 4))


@settings(max_examples=8, deadline=None)
@given(st.integers(0, 10_000), st.floats(0.2, 0.8))
def test_plateau_nodes_take_their_own_height_and_the_others_the_drop_cutter(seed, share):
    """A depth pass's model (the part, raised to a level): where no node within the ball's
    reach is higher, the CL is the node's own height (the library's rounds it up by ulps);
    elsewhere the drop-cutter's value on the whole grid, bit for bit (computed on a crop);
    everywhere at least a brute-force node drop-cutter."""
    part = wavy_part(170, 0.1, seed)
    level = np.quantile(part.z, share)
    z = np.maximum(part.z, level)
    z[:, 85:] = level  # the part lies below the level there
    model = ZMap(z, part.x0, part.y0, part.dx, part.dy)
    tool = Tool("B10", "ball", 10.0, 30.0)  # a footprint the pruned method takes
    rows = np.arange(0, 170, 4, dtype=np.int64)
    got = _plateau_cl(model, tool, rows)
    ref = sim_cl_heights(model, tool)
    wy, wx = footprint(tool, model.dx, model.dy)
    zz = model.z
    ny, nx = zz.shape
    top = np.array([[zz[max(0, i - wy):i + wy + 1, max(0, k - wx):k + wx + 1].max()
                     for k in range(nx)] for i in rows])
    flat = zz[rows] >= top
    assert flat.any() and (~flat).any()
    np.testing.assert_array_equal(got[rows][flat], zz[rows][flat])
    np.testing.assert_array_equal(got[rows][~flat], ref[rows][~flat])
    assert np.all(got[rows][flat] <= ref[rows][flat])
    assert np.all(got[rows][flat] >= ref[rows][flat] - 1e-9)
    # the node drop-cutter (a lower bound of the bilinear one), by brute force
    r = tool.radius
    yy, xx = np.mgrid[0:ny, 0:nx]
    for i in rows[::6]:
        for k in range(0, nx, 9):
            d2 = ((xx - k) * model.dx) ** 2 + ((yy - i) * model.dy) ** 2
            inside = d2 <= r * r
            node = (zz[inside] - (r - np.sqrt(r * r - d2[inside]))).max()
            assert got[i, k] >= node - 1e-9
    assert np.all(np.isnan(np.delete(got, rows, axis=0)))
