"""The exact gouge measure of tools with block bounds as rewritten in session 10 (issue 12):
moves chained along a grid line measured in groups, each move's blocks best first
(:func:`~zwcore.toolpath._measure_kernel.measure_bounded`), against the sweep kernel
without skipping (bit for bit wherever a move gouges) and a brute-force node loop; the
groups' sag bound; and :func:`~zwcore.toolpath._polyline.follow_part` with the new
measure against the former one (the same path, bit for bit) and against a brute-force
drop-cutter (no vertex below the part's nodes' drop-cutter height, no move through a
node), on random surfaces and scan lines; the plain kernel with the gathering it shares
with the measure-only kernel against the former one."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit

from tests.test_paths9_measure import _brute, _lines, _moves
from tests.test_toolpath import wavy_part
from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.toolpath import _measure_kernel as mk
from zwcore.toolpath import _polyline as pl
from zwcore.toolpath import sweep as sweep_mod
from zwcore.toolpath._measure_kernel import _group_end, measure_moves_bounded
from zwcore.toolpath._polyline import PartBounds, PartGouge, follow_part, measure_block
from zwcore.toolpath._sweep_kernel import TIE_REACH, _move_box, _row_span
from zwcore.toolpath._sweep_plain import _envelopes, plain_kernel
from zwcore.toolpath.sweep import BlockBounds, GridFrame, sweep_moves


def _chains(part: ZMap, rng: np.random.Generator, step: float, along_y: bool
            ) -> tuple[np.ndarray, np.ndarray]:
    """Moves chained along scan lines (the thinned chords' case: each starts where the one
    before ends, ``y`` fixed, lines run both ways, links between them), along y on the
    transposed layout with ``along_y``; some random moves and vertical ones after."""
    points, _, _, _ = _lines(part, rng, 5, step)
    if along_y:  # the same lines with x and y swapped (the part is square)
        points = points[:, [1, 0, 2]].copy()
    p0, p1 = points[:-1], points[1:]
    q0, q1 = _moves(part, rng, 40, True)
    return np.vstack([p0, q0]), np.vstack([p1, q1])


def _sweep_gouge(part: ZMap, radius: float, p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    frame = GridFrame(part.x0, part.y0, part.dx, part.dy, part.shape)
    _, want = sweep_moves(frame, p0, p1, radius, True, part.z.copy(), ref=part.z,
                          apply=False, bounds=BlockBounds.none(frame))
    return want


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 10_000), st.floats(0.9, 3.0), st.booleans(),
       st.sampled_from([(2, 1e-3), (16, 0.05), (16, 10.0), (64, 0.05)]),
       st.sampled_from([1, 3]), st.sampled_from([0.05, 0.1, 0.3]))
def test_grouped_measure_is_the_sweep_where_it_gouges(seed, radius, along_y, group,
                                                     threads, step):
    """Every positive value is the sweep kernel's (no skipping) bit for bit, and ``<= 0``
    where that is; with thresholds, a value above its threshold is the sweep's or a lower
    bound of it, the others exact: whatever the groups (sizes, sags), the threads (chunks
    cut groups) and the blocks."""
    part = wavy_part(81, 0.1, seed, amplitude=1.0)
    rng = np.random.default_rng(seed)
    p0, p1 = _chains(part, rng, step, along_y)
    want = _sweep_gouge(part, radius, p0, p1)
    bounds = PartBounds(part)
    skip = bounds.skip_blocks(measure_block(radius, part.dx))
    old = (mk.GROUP_MAX, mk.GROUP_SAG, sweep_mod.SWEEP_THREADS,
           sweep_mod.MIN_MOVES_PER_THREAD)
    mk.GROUP_MAX, mk.GROUP_SAG = group
    sweep_mod.SWEEP_THREADS, sweep_mod.MIN_MOVES_PER_THREAD = threads, 20
    try:
        got = measure_moves_bounded(bounds.frame, p0, p1, radius, True, part.z, skip)
        above = np.where(rng.random(len(p0)) < 0.5, rng.uniform(0.0, 0.2, len(p0)), np.inf)
        low = measure_moves_bounded(bounds.frame, p0, p1, radius, True, part.z, skip, above)
    finally:
        (mk.GROUP_MAX, mk.GROUP_SAG, sweep_mod.SWEEP_THREADS,
         sweep_mod.MIN_MOVES_PER_THREAD) = old
    pos = want > 0
    assert pos.sum() > 5  # the lines gouge: the positive values are compared
    np.testing.assert_array_equal(got[pos], want[pos])
    assert np.all(got[~pos] <= 0)
    over = low > above
    assert np.all(want[over] >= low[over])  # a lower bound over the threshold
    rest = ~over & pos
    np.testing.assert_array_equal(low[rest], want[rest])
    assert np.all(low[~over & ~pos] <= 0)


@settings(max_examples=10, deadline=None)
@given(st.integers(0, 10_000), st.floats(0.9, 1.5))
def test_grouped_measure_against_a_brute_node_loop(seed, radius):
    """The positive values are those of the closed form evaluated node by node (to float
    contraction), the others ``<= 0`` where that is."""
    part = wavy_part(33, 0.1, seed, amplitude=0.5)
    rng = np.random.default_rng(seed)
    p0, p1 = _chains(part, rng, 0.1, bool(seed % 2))
    p0, p1 = p0[::3], p1[::3]  # a third of them: the brute loop is slow
    bounds = PartBounds(part)
    got = measure_moves_bounded(bounds.frame, p0, p1, radius, True, part.z,
                                bounds.skip_blocks(measure_block(radius, part.dx)))
    want = _brute(part, radius, p0, p1)
    pos = want > 1e-9
    np.testing.assert_allclose(got[pos], want[pos], rtol=0, atol=1e-9)
    assert np.all(got[want < -1e-9] <= 0)


@settings(max_examples=50, deadline=None)
@given(st.integers(0, 10_000), st.integers(1, 40), st.floats(1e-4, 0.2))
def test_group_sag_bounds_every_move(seed, gmax, sag):
    """A group chains along one line, one way, and every vertex of its moves lies at most
    ``delta`` (``<= sag``) under the straight move from its first start to its last end."""
    rng = np.random.default_rng(seed)
    n = 60
    x = np.round(np.cumsum(rng.uniform(0.01, 0.4, n + 1)), 4)
    z = np.cumsum(rng.normal(0, 0.05, n + 1))
    pts = np.column_stack([x, np.full(n + 1, 1.25), z])
    cut = rng.random(n) < 0.1  # a few chains broken (another line, a reversal)
    p0, p1 = pts[:-1].copy(), pts[1:].copy()
    p1[cut, 1] += 0.5
    s = 0
    while s < n:
        e, delta = _group_end(p0, p1, s, gmax, sag)
        assert s < e <= min(n, s + max(gmax, 1))
        assert 0.0 <= delta <= sag or e == s + 1
        if e > s + 1:
            assert not cut[s:e].any()
            assert np.array_equal(p0[s + 1:e], p1[s:e - 1])
            w0, w1, z0, z1 = p0[s, 0], p1[e - 1, 0], p0[s, 2], p1[e - 1, 2]
            for t in range(s, e):
                for q in (p0[t], p1[t]):
                    straight = z0 + (q[0] - w0) * (z1 - z0) / (w1 - w0)
                    assert q[2] >= straight - delta - 1e-12
        s = e


def _drop_cutter_nodes(part: ZMap, radius: float, xy: np.ndarray) -> np.ndarray:
    """The ball's drop-cutter tip height over the part's nodes at each ``xy``, brute force:
    the largest ``z_q - (R - sqrt(R² - d²))`` over the nodes within ``R``."""
    gy, gx = np.mgrid[0:part.shape[0], 0:part.shape[1]]
    qx, qy = part.x0 + gx * part.dx, part.y0 + gy * part.dy
    out = np.full(len(xy), -np.inf)
    for m, (x, y) in enumerate(xy):
        d2 = (qx - x) ** 2 + (qy - y) ** 2
        near = d2 < radius * radius
        if near.any():
            out[m] = np.max(part.z[near] - (radius - np.sqrt(radius * radius - d2[near])))
    return out


@settings(max_examples=8, deadline=None)
@given(st.integers(0, 10_000), st.sampled_from([0.9, 1.6]), st.sampled_from([0.01, 0.05]),
       st.booleans())
def test_follow_part_is_the_former_path_and_clear_of_the_part(seed, radius, tol, at_breaks):
    """The whole thin, measure, return, halve and lift step with the grouped best-first
    measure: the same points, parameters and lift bit for bit as with the sweep kernel's
    measure; and the path itself safe, brute force: every vertex on or above the part's
    nodes' drop-cutter height, every move clear of every node (its exact gouge, node by
    node, not above float contraction)."""
    part = wavy_part(41, 0.1, seed, amplitude=0.8)
    rng = np.random.default_rng(seed)
    tool = Tool("T", "ball", 2 * radius, 20.0)
    points, u, fixed, breaks = _lines(part, rng, 3, float(rng.choice([0.1, 0.05])))
    bounds = PartBounds(part)
    kw = dict(chord=tol, refine=tol, min_len=part.dx / 16, decimals=4,
              moves_at_breaks=at_breaks)
    old = pl.BEST_FIRST
    try:
        pl.BEST_FIRST = False
        want = follow_part(points, u, fixed, breaks, PartGouge(part, tool, 1, bounds), **kw)
        pl.BEST_FIRST = True
        got = follow_part(points, u, fixed, breaks, PartGouge(part, tool, 1, bounds), **kw)
    finally:
        pl.BEST_FIRST = old
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])
    assert got[2] == want[2]
    out = got[0]
    assert np.all(out[:, 2] >= _drop_cutter_nodes(part, radius, out[:, :2]) - 1e-9)
    seg = np.ones(len(out) - 1, bool)
    if not at_breaks:  # the links are no moves: each line is entered on its own
        seg = np.abs(np.diff(out[:, 1])) == 0
    gouge = _brute(part, radius, out[:-1][seg], out[1:][seg])
    assert np.all(gouge <= 1e-9)


@pytest.mark.parametrize("radius", [0.9, 2.0])
def test_a_move_alone_and_vertical_moves(radius):
    """Moves no group chains (random directions, vertical, off the grid, one long move)
    are measured alone: the sweep's values where they gouge."""
    part = wavy_part(61, 0.1, 7, amplitude=1.0)
    rng = np.random.default_rng(3)
    p0, p1 = _moves(part, rng, 120, False)
    p1[-6:-3] = p0[-6:-3] + np.array([0.0, 0.0, -0.5])  # plunges
    want = _sweep_gouge(part, radius, p0, p1)
    bounds = PartBounds(part)
    got = measure_moves_bounded(bounds.frame, p0, p1, radius, True, part.z,
                                bounds.skip_blocks(measure_block(radius, part.dx)))
    pos = want > 0
    assert pos.any()
    np.testing.assert_array_equal(got[pos], want[pos])
    assert np.all(got[~pos] <= 0)
    assert math.isinf(got[np.isinf(want)].max(initial=-math.inf)) or not np.isinf(want).any()


@njit(cache=False, nogil=True, fastmath={"contract", "arcp", "reassoc"})
def _plain_reference(x0, y0, dx, dy, p0, p1, r, ball, apply, stock, ref, over_stock,
                     over_ref):  # pragma: no cover - compiled
    """The plain kernel before its gathering was shared (session 9): node indices gathered
    with the offsets, the stock compared and lowered through them."""
    nx = stock.shape[1]
    ny = stock.shape[0]
    sflat = stock.reshape(-1)
    rflat = ref.reshape(-1)
    cap = 1024
    wxs, wys, env, sws = np.empty(cap), np.empty(cap), np.empty(cap), np.empty(cap)
    idx = np.empty(cap, np.int64)
    for s in range(p0.shape[0]):
        sx, sy, sz = p0[s, 0], p0[s, 1], p0[s, 2]
        ax, ay, vz = p1[s, 0] - sx, p1[s, 1] - sy, p1[s, 2] - sz
        rr = r[s]
        k0, k1, i0, i1 = _move_box(x0, y0, dx, dy, nx, 0, ny, sx, sy, ax, ay, rr)
        over_stock[s] = over_ref[s] = -math.inf
        if k1 < k0 or i1 < i0:
            continue
        box = (k1 - k0 + 1) * (i1 - i0 + 1)
        if box > cap:
            cap = 2 * box
            wxs, wys, env, sws = np.empty(cap), np.empty(cap), np.empty(cap), np.empty(cap)
            idx = np.empty(cap, np.int64)
        ylo, yhi = min(sy, sy + ay), max(sy, sy + ay)
        m = 0
        for i in range(i0, i1 + 1):
            qy = y0 + i * dy
            ka, kb = _row_span(qy, x0, dx, k0, k1, sx, sy, ax, ay, ylo, yhi, rr)
            if kb < ka:
                continue
            wy = sy - qy
            sw = math.sqrt(max(rr * rr * TIE_REACH - wy * wy, 0.0))
            for k in range(ka, kb + 1):
                wxs[m] = sx - (x0 + k * dx)
                wys[m] = wy
                sws[m] = sw
                idx[m] = i * nx + k
                m += 1
        _envelopes(m, wxs, wys, sws, sx, sy, sz, ax, ay, vz, rr, ball, env)
        best_s, best_r = -math.inf, -math.inf
        for j in range(m):
            q, e = idx[j], env[j]
            best_s = max(best_s, sflat[q] - e)
            best_r = max(best_r, rflat[q] - e)
            if apply[s]:
                sflat[q] = min(sflat[q], e)
        over_stock[s] = best_s
        over_ref[s] = best_r


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 10_000), st.floats(0.2, 1.5), st.booleans())
def test_plain_kernel_with_the_shared_gathering_is_the_former_one(seed, radius, along):
    """The plain kernel reading the stock a row's run at a time (the gathering shared with
    the measure-only kernel): the same stock and figures bit for bit as the former one,
    moves that cut and moves that only measure, in order."""
    part = wavy_part(41, 0.1, seed, amplitude=0.5)
    rng = np.random.default_rng(seed)
    p0, p1 = _moves(part, rng, 150, along)
    n = len(p0)
    r = np.full(n, radius)
    app = rng.random(n) < 0.7
    args = (part.x0, part.y0, part.dx, part.dy, p0, p1, r, True, app)
    got = [part.z + 0.3, np.full(n, np.nan), np.full(n, np.nan)]
    want = [part.z + 0.3, np.full(n, np.nan), np.full(n, np.nan)]
    plain_kernel(*args, got[0], part.z, got[1], got[2], 0, part.shape[0])
    _plain_reference(*args, want[0], part.z, want[1], want[2])
    for g, w in zip(got, want, strict=True):
        np.testing.assert_array_equal(g, w)
