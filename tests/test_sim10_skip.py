"""The block skip test of the sweep (sim10): distance from the move's xy segment, the rim
bound, the tangent plane, with the per-move constants computed once per move. Read against
a brute force (:func:`node_envelope` over every node of every block the test skips) and,
whole sweeps, against the plain kernel and the same kernel skipping nothing."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit

import zwcore.toolpath.sweep as sweep_mod
from tests.test_toolpath import wavy_part
from tests.test_toolpath_kernels import KERNEL_ROUNDING
from zwcore.toolpath._sweep_kernel import move_constants, node_envelope, skip_block
from zwcore.toolpath.sweep import BlockBounds, GridFrame, sweep_moves


@njit(cache=False)  # (a cache would keep an old skip_block: numba does not track callees)
def _violations(x0, y0, dx, dy, u, b, f, cx, cy, hx, hy, bst, ccx, ccy, chx, chy, cst,
                p0, p1, r, ball):  # pragma: no cover - compiled
    """Per move, over every block and coarse block :func:`skip_block` skips: the largest
    ``U - env`` of its nodes (brute force, ``node_envelope``; must stay ``<= 0``), and how
    many blocks were skipped that hold a node the move reaches (the test is not vacuous)."""
    ny, nx = u.shape
    worst = -math.inf
    reached_skips = 0
    hdf = math.sqrt(np.max(hx) ** 2 + np.max(hy) ** 2)
    hdc = math.sqrt(np.max(chx) ** 2 + np.max(chy) ** 2)
    for s in range(p0.shape[0]):
        sx, sy, sz = p0[s, 0], p0[s, 1], p0[s, 2]
        ax, ay, vz = p1[s, 0] - sx, p1[s, 1] - sy, p1[s, 2] - sz
        a, inv_a, _, kz, _, zlow, slack = move_constants(sx, sy, sz, ax, ay, vz, r)
        for level in range(2):
            side = b if level == 0 else b * f
            cxs, cys = (cx, cy) if level == 0 else (ccx, ccy)
            hxs, hys = (hx, hy) if level == 0 else (chx, chy)
            sts = bst if level == 0 else cst
            hd = hdf if level == 0 else hdc
            for bi in range(sts.shape[0]):
                for bk in range(sts.shape[1]):
                    if not skip_block(cxs[bk], cys[bi], hxs[bk], hys[bi], sts[bi, bk, 0],
                                      sts[bi, bk, 1], sts[bi, bk, 2], sts[bi, bk, 3], sx, sy,
                                      sz, ax, ay, vz, r, ball, a, inv_a, kz, zlow, slack,
                                      hd):
                        continue
                    reached = False
                    for i in range(bi * side, min(bi * side + side, ny)):
                        for k in range(bk * side, min(bk * side + side, nx)):
                            env = node_envelope(x0 + k * dx, y0 + i * dy, sx, sy, sz, ax, ay,
                                                vz, r, ball)
                            if env < math.inf:
                                reached = True
                                worst = max(worst, u[i, k] - env)
                    reached_skips += reached
    return worst, reached_skips


def _moves(rng: np.random.Generator, part, n: int, radius: float) -> tuple[np.ndarray,
                                                                             np.ndarray]:
    """Moves of every kind near the part: along x, along y, diagonal, short (a node or
    less), long, vertical, level, plunging and climbing, their tips from well below to
    above the surface under them (near contact is where a bound is tight)."""
    ny, nx = part.shape
    ext = np.array([(nx - 1) * part.dx, (ny - 1) * part.dy])
    xy0 = np.array([part.x0, part.y0]) + rng.uniform(-0.2, 1.2, (n, 2)) * ext
    length = rng.choice([0.0, 0.3 * part.dx, part.dx, 1.0, 0.5 * ext.min()], n) * rng.random(n)
    ang = rng.choice([0.0, 0.5 * np.pi, np.pi, 0.25 * np.pi, 0.0], n) + np.where(
        rng.random(n) < 0.4, rng.uniform(0, 2 * np.pi, n), 0.0)
    xy1 = xy0 + length[:, None] * np.column_stack([np.cos(ang), np.sin(ang)])
    k = np.clip(np.round((xy0[:, 0] - part.x0) / part.dx).astype(int), 0, nx - 1)
    i = np.clip(np.round((xy0[:, 1] - part.y0) / part.dy).astype(int), 0, ny - 1)
    z0 = part.z[i, k] + rng.uniform(-0.5, 1.0, n) * radius
    z1 = z0 + np.where(rng.random(n) < 0.4, 0.0, rng.normal(0, 0.5 * radius, n))
    return np.column_stack([xy0, z0]), np.column_stack([xy1, z1])


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10_000), st.sampled_from([2, 3, 4, 6]), st.sampled_from([1, 2, 4]),
       st.floats(0.3, 3.0), st.booleans(), st.booleans())
def test_a_skipped_block_holds_no_node_the_move_lowers(seed, block, coarse, radius, ball,
                                                        cut_stock):
    """Every block (and coarse block) :func:`skip_block` skips holds no node whose exact
    envelope (``node_envelope``, brute force over its nodes) lies below ``U = max(stock,
    ref)``: moves of every kind, ball and flat, on a part and on a stock partly cut (bounds
    measured on it as the sweep measures them)."""
    part = wavy_part(41, 0.1, seed, amplitude=0.8)
    frame = GridFrame(part.x0, part.y0, part.dx, part.dy, part.shape)
    rng = np.random.default_rng(seed)
    stock = part.z.copy()
    if cut_stock:  # a stock above the part, cut in places: U is not the part's smooth waves
        stock = part.z + rng.uniform(0.0, 0.3) * (rng.random(part.shape) < 0.5)
    bounds = BlockBounds(frame, stock, part.z, block, coarse)
    p0, p1 = _moves(rng, part, 120, radius)
    worst, _ = _violations(frame.x0, frame.y0, frame.dx, frame.dy, np.maximum(stock, part.z),
                           bounds.block, bounds.coarse, bounds.cx, bounds.cy, bounds.hx,
                           bounds.hy, bounds.st, bounds.ccx, bounds.ccy, bounds.chx,
                           bounds.chy, bounds.cst, p0, p1, radius, ball)
    assert worst <= 0.0


def test_the_skip_test_skips_what_it_should():
    """The skip test is not vacuous: on the same kind of moves it skips blocks the moves
    reach (the tangent plane and the rim bound), and blocks beyond a short move's end
    (within ``R`` plus a block of its line, further than that from its segment) go by
    distance alone, whatever the stock."""
    part = wavy_part(41, 0.1, 7, amplitude=0.8)
    frame = GridFrame(part.x0, part.y0, part.dx, part.dy, part.shape)
    bounds = BlockBounds(frame, part.z, part.z, 4, 2)
    rng = np.random.default_rng(7)
    for ball in (True, False):
        p0, p1 = _moves(rng, part, 200, 2.0)
        worst, reached = _violations(frame.x0, frame.y0, frame.dx, frame.dy, part.z,
                                     bounds.block, bounds.coarse, bounds.cx, bounds.cy,
                                     bounds.hx, bounds.hy, bounds.st, bounds.ccx, bounds.ccy,
                                     bounds.chx, bounds.chy, bounds.cst, p0, p1, 2.0, ball)
        assert worst <= 0.0 and reached > 50
    # a move 0.1 mm along x, R = 1; a block (half extents 0.2) centred 1.5 mm ahead of its
    # end on its line: 1.3 mm from the segment, beyond R; its top far above the tool
    r, h = 1.0, 0.2
    sx, sy, sz, ax, ay, vz = 0.0, 0.0, 0.0, 0.1, 0.0, 0.0
    a, inv_a, _, kz, _, zlow, slack = move_constants(sx, sy, sz, ax, ay, vz, r)
    for ball in (True, False):
        args = (0.0, 0.0, 100.0, 100.0, sx, sy, sz, ax, ay, vz, r, ball, a, inv_a, kz, zlow,
                slack, math.hypot(h, h))
        assert skip_block(1.6, 0.0, h, h, *args)
        assert not skip_block(1.3, 0.0, h, h, *args)  # within R + its half diagonal
    # the rim bound: a ball low under a block at 0.9 R from the segment whose top lies
    # under the ball's side there (R - sqrt(R² - 0.81 R²) = 0.564 R above the tip)
    for top, skipped in ((0.5, True), (0.6, False)):
        args = (0.0, 0.0, top, top, sx, sy, sz, ax, ay, vz, r, True, a, inv_a, kz, zlow,
                slack, 0.0)
        assert skip_block(0.05, 0.9, 0.0, 0.0, *args) is skipped


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10_000), st.sampled_from([2, 3, 5, 8]), st.floats(0.5, 3.0),
       st.booleans(), st.sampled_from(["cut", "measure", "threads"]))
def test_the_bounded_sweep_is_the_plain_sweep(seed, block, radius, ball, mode):
    """Random move sets swept with block bounds and with the plain kernel
    (:mod:`~zwcore.toolpath._sweep_plain`, every node within reach gathered): the same
    stock (to ``KERNEL_ROUNDING``: the plain kernel is compiled apart, float contraction
    may differ in the last bit) and, against the same kernel skipping nothing
    (``BlockBounds.none``), bit for bit; ``over_stock`` and ``over_ref`` the same wherever
    they are positive, ``<= 0`` elsewhere."""
    part = wavy_part(61, 0.1, seed, amplitude=1.0)
    frame = GridFrame(part.x0, part.y0, part.dx, part.dy, part.shape)
    rng = np.random.default_rng(seed)
    p0, p1 = _moves(rng, part, 400, radius)
    apply = (rng.random(len(p0)) < 0.85) if mode != "measure" else False
    top = part.z.max() + rng.uniform(0.0, 1.0)
    start = np.full(part.shape, top) if mode != "measure" else part.z.copy()
    plain, none, skip = start.copy(), start.copy(), start.copy()
    with pytest.MonkeyPatch.context() as mp:
        if mode == "threads":
            mp.setattr(sweep_mod, "MIN_MOVES_PER_THREAD", 50)
            mp.setattr(sweep_mod, "SWEEP_THREADS", 3)
        c_s, c_r = sweep_moves(frame, p0, p1, radius, ball, plain, ref=part.z, apply=apply)
        a_s, a_r = sweep_moves(frame, p0, p1, radius, ball, none, ref=part.z, apply=apply,
                               bounds=BlockBounds.none(frame))
        b_s, b_r = sweep_moves(frame, p0, p1, radius, ball, skip, ref=part.z, apply=apply,
                               bounds=BlockBounds(frame, skip, part.z, block))
    np.testing.assert_array_equal(skip, none)
    np.testing.assert_allclose(skip, plain, rtol=0, atol=KERNEL_ROUNDING)
    for a, b, c in ((a_s, b_s, c_s), (a_r, b_r, c_r)):
        pos = a > 0
        np.testing.assert_array_equal(b[pos], a[pos])
        assert np.all(b[~pos] <= 0)
        np.testing.assert_allclose(np.maximum(b, 0), np.maximum(c, 0), rtol=0,
                                   atol=KERNEL_ROUNDING)
    if mode != "measure":
        assert (skip < start).any()  # the moves cut
