"""The tool paths' measure and halving as rewritten (issue 12), against straightforward
references: the measure-only plain sweep against the plain kernel (bit for bit) and a
brute-force node loop; the measure's larger skip blocks against no skipping; the halving
that carries only the segments being halved, and :func:`follow_part` as a whole, against
the former code (every round inserting into the whole polyline, unchanged chords found by
``np.isin``), kept here as the reference, on random surfaces and polylines."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.test_toolpath import wavy_part
from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.toolpath import _polyline as pl
from zwcore.toolpath import sweep as sweep_mod
from zwcore.toolpath._measure_kernel import measure_moves
from zwcore.toolpath._polyline import (
    LazyPoints,
    PartBounds,
    PartGouge,
    _above,
    _measure_moves,
    _split,
    follow_part,
    lift_points,
    measure_block,
    thin,
)
from zwcore.toolpath._sweep_kernel import node_envelope
from zwcore.toolpath.sweep import BlockBounds, GridFrame, sweep_moves


def _moves(part: ZMap, rng: np.random.Generator, n: int, along: bool) -> tuple[np.ndarray,
                                                                                 np.ndarray]:
    """Random moves over the part, some along x (``ay = 0``, the scan lines' case), some
    vertical, some off the grid."""
    lo = np.array([part.x0 - 2, part.y0 - 2, part.z.min() - 1])
    hi = np.array([part.x0 + (part.shape[1] - 1) * part.dx + 2,
                   part.y0 + (part.shape[0] - 1) * part.dy + 2, part.z.max() + 1])
    p0 = rng.uniform(lo, hi, (n, 3))
    p1 = p0 + rng.normal(0, 1.0, (n, 3))
    if along:
        p1[: n // 2, 1] = p0[: n // 2, 1]
    p1[-3:, :2] = p0[-3:, :2]  # vertical
    return p0, p1


def _brute(part: ZMap, radius: float, p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """Per ball move, the largest part height over the closed-form envelope, node by node
    (the scalar :func:`node_envelope`, no rows, no gathering)."""
    ny, nx = part.shape
    out = np.full(len(p0), -np.inf)
    for m, (a, b) in enumerate(zip(p0, p1, strict=True)):
        for i in range(ny):
            for k in range(nx):
                qx, qy = part.x0 + k * part.dx, part.y0 + i * part.dy
                e = node_envelope(qx, qy, a[0], a[1], a[2], b[0] - a[0], b[1] - a[1],
                                  b[2] - a[2], radius, True)
                if e < math.inf:
                    out[m] = max(out[m], part.z[i, k] - e)
    return out


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10_000), st.floats(0.2, 0.9), st.booleans(), st.integers(1, 3))
def test_measure_only_plain_sweep_is_the_plain_kernel_bit_for_bit(seed, radius, along,
                                                                  threads):
    """Every value (not only the positive ones) is the plain kernel's ``over_ref``, on one
    thread or several (chunks of moves)."""
    part = wavy_part(41, 0.1, seed, amplitude=0.5)
    rng = np.random.default_rng(seed)
    p0, p1 = _moves(part, rng, 200, along)
    frame = GridFrame(part.x0, part.y0, part.dx, part.dy, part.shape)
    _, want = sweep_moves(frame, p0, p1, radius, True, part.z.copy(), ref=part.z,
                          apply=False)
    old = sweep_mod.SWEEP_THREADS, sweep_mod.MIN_MOVES_PER_THREAD
    sweep_mod.SWEEP_THREADS, sweep_mod.MIN_MOVES_PER_THREAD = threads, 20
    try:
        got = measure_moves(part.x0, part.y0, part.dx, part.dy, p0, p1, radius, True,
                            part.z)
    finally:
        sweep_mod.SWEEP_THREADS, sweep_mod.MIN_MOVES_PER_THREAD = old
    np.testing.assert_array_equal(got, want)


@settings(max_examples=10, deadline=None)
@given(st.integers(0, 10_000), st.floats(0.2, 0.6))
def test_measure_only_plain_sweep_against_a_brute_node_loop(seed, radius):
    """The same maxima as the closed form evaluated node by node (to float contraction)."""
    part = wavy_part(17, 0.1, seed, amplitude=0.5)
    rng = np.random.default_rng(seed)
    p0, p1 = _moves(part, rng, 30, True)
    got = measure_moves(part.x0, part.y0, part.dx, part.dy, p0, p1, radius, True, part.z)
    want = _brute(part, radius, p0, p1)
    assert np.array_equal(np.isinf(got), np.isinf(want))
    fin = np.isfinite(want)
    np.testing.assert_allclose(got[fin], want[fin], rtol=0, atol=1e-9)


@settings(max_examples=10, deadline=None)
@given(st.integers(0, 10_000), st.floats(1.0, 3.0))
def test_measure_blocks_change_no_positive_gouge(seed, radius):
    """The measure's skip blocks (at least ``MEASURE_BLOCK_MIN`` nodes) against the same
    kernel without skipping: the same value wherever a move gouges, ``<= 0`` elsewhere."""
    part = wavy_part(81, 0.1, seed, amplitude=1.0)
    tool = Tool("T", "ball", 2 * radius, 20.0)
    assert radius >= sweep_mod.MIN_BLOCK_RADIUS * part.dx  # the block kernel's case
    assert measure_block(radius, part.dx) >= pl.MEASURE_BLOCK_MIN
    rng = np.random.default_rng(seed)
    p0, p1 = _moves(part, rng, 150, True)
    got = PartGouge(part, tool, 1, PartBounds(part))(p0, p1)
    frame = GridFrame(part.x0, part.y0, part.dx, part.dy, part.shape)
    _, want = sweep_moves(frame, p0, p1, radius, True, part.z.copy(), ref=part.z,
                          apply=False, bounds=BlockBounds.none(frame))
    pos = want > 0
    np.testing.assert_array_equal(got[pos], want[pos])
    assert np.all(got[~pos] <= 0)


def _split_reference(points, u, gouge, breaks, measure, tol, min_len, decimals, rounds):
    """The former halving: each round inserts the midpoints into the whole polyline."""
    for r in range(rounds):
        seg_len = np.hypot(*(points[1:, :2] - points[:-1, :2]).T)
        split = np.flatnonzero((gouge > tol) & (seg_len > min_len) & ~breaks)
        if not len(split):
            break
        at = split + 1
        mid = 0.5 * (points[at - 1] + points[at])
        mid[:, :2] = np.round(mid[:, :2], decimals)
        a = np.stack([points[split], mid], axis=1).reshape(-1, 3)
        b = np.stack([mid, points[at]], axis=1).reshape(-1, 3)
        g_new = measure(a, b, _above(a, b, tol, min_len, r + 1 < rounds)).reshape(-1, 2)
        points = np.insert(points, at, mid, axis=0)
        u = np.insert(u, at, 0.5 * (u[at - 1] + u[at]))
        breaks = np.insert(breaks, split, False)
        gouge = np.insert(gouge, split, 0.0)
        pos = split + np.arange(len(split))
        gouge[pos] = g_new[:, 0]
        gouge[pos + 1] = g_new[:, 1]
    return points, u, gouge


def _follow_reference(points, u, fixed, breaks, measure, *, chord, refine, min_len,
                      decimals=4, rounds=8, moves_at_breaks=True):
    """The former :func:`follow_part` (``np.isin`` and ``searchsorted`` for the unchanged
    chords, the former halving)."""
    keep = thin(u, points[:, 2], fixed, 0.5 * chord, 0.5 * chord)
    idx = np.flatnonzero(keep)
    a, b, link = points[idx[:-1]], points[idx[1:]], breaks[idx[:-1]]
    gap = idx[1:] - idx[:-1] > 1
    above = np.where(gap, refine, _above(a, b, refine, min_len, rounds > 0))
    gouge = _measure_moves(measure, a, b, above, link, moves_at_breaks)
    bad = np.flatnonzero((gouge > refine) & ~link & gap)
    if len(bad):
        back = np.zeros(len(points) + 1, np.int64)
        np.add.at(back, idx[bad] + 1, 1)
        np.add.at(back, idx[bad + 1], -1)
        keep |= np.cumsum(back)[:-1] > 0
        new = np.flatnonzero(keep)
        known = np.isin(new[:-1], idx[:-1]) & np.isin(new[1:], idx[1:])
        g = np.empty(len(new) - 1)
        g[known] = gouge[np.searchsorted(idx, new[:-1][known])]
        fresh = np.flatnonzero(~known)
        a, b, link = points[new[fresh]], points[new[fresh + 1]], breaks[new[fresh]]
        g[fresh] = _measure_moves(measure, a, b, _above(a, b, refine, min_len, rounds > 0),
                                  link, moves_at_breaks)
        idx, gouge = new, g
    pts, uu, gouge = _split_reference(points[idx], u[idx], gouge, breaks[idx[:-1]], measure,
                                      refine, min_len, decimals, rounds)
    # the lift and rounding are follow_part's own (unchanged); the oracle is the split above
    out, vmax = lift_points(pts, gouge, decimals)
    return out, uu, vmax


def _lines(part: ZMap, rng: np.random.Generator, n_lines: int, step: float):
    """Scan lines along x over the part, points ``step`` apart at heights a little under
    and over the part's (so that chords gouge, come back and are halved), links between
    lines."""
    width = (part.shape[1] - 1) * part.dx
    xs = np.arange(0.0, width, step)
    pts, fixed, breaks = [], [], []
    for j in range(n_lines):
        y = (j + 0.5) * (part.shape[0] - 1) * part.dy / n_lines
        i = min(round(y / part.dy), part.shape[0] - 1)
        z = np.interp(xs, np.arange(part.shape[1]) * part.dx, part.z[i])
        z = z + rng.uniform(-0.05, 0.3) + rng.normal(0, 0.02, len(xs))
        p = np.column_stack([np.round(part.x0 + xs, 4), np.full(len(xs), round(part.y0 + y, 4)),
                             z])
        pts.append(p if j % 2 == 0 else p[::-1])
        f = np.zeros(len(xs), bool)
        f[[0, -1]] = True
        fixed.append(f)
        b = np.zeros(len(xs), bool)
        b[-1] = True  # the link to the next line
        breaks.append(b)
    points = np.vstack(pts)
    u = np.arange(len(points), dtype=np.float64)  # increasing along the whole polyline
    return points, u, np.concatenate(fixed), np.concatenate(breaks)[:-1]


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 10_000), st.sampled_from([0.3, 0.6, 1.5]), st.sampled_from([1, 2]),
       st.booleans(), st.sampled_from([0.01, 0.05]))
def test_follow_part_is_the_former_code_move_for_move(seed, radius, block, at_breaks, tol):
    """Thinning, returned points, halving and lift: the same points, parameters and lift,
    bit for bit, as the former code (with the coarse looks or without, links measured or
    not), on random surfaces and lines that gouge."""
    part = wavy_part(61, 0.1, seed, amplitude=1.0)
    rng = np.random.default_rng(seed)
    tool = Tool("T", "ball", 2 * radius, 20.0)
    points, u, fixed, breaks = _lines(part, rng, 4, rng.choice([0.1, 0.05]))
    bounds = PartBounds(part)
    kw = dict(chord=tol, refine=tol, min_len=part.dx / 16, decimals=4,
              moves_at_breaks=at_breaks)
    got = follow_part(points, u, fixed, breaks, PartGouge(part, tool, block, bounds), **kw)
    want = _follow_reference(points, u, fixed, breaks, PartGouge(part, tool, block, bounds),
                             **kw)
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])
    assert got[2] == want[2]
    # the points built lazily (only the kept vertices): the same path
    x0, y0 = part.x0 - 0.25, part.y0 + 0.5
    lazy = LazyPoints(x0, y0, points[:, 0] - x0, points[:, 1] - y0, points[:, 2], 4)
    whole = lazy.take(np.arange(len(points)))
    built = np.column_stack([np.round(x0 + (points[:, 0] - x0), 4),
                             np.round(y0 + (points[:, 1] - y0), 4), points[:, 2]])
    np.testing.assert_array_equal(whole, built)
    got = follow_part(lazy, u, fixed, breaks, PartGouge(part, tool, block, bounds), **kw)
    want = _follow_reference(built, u, fixed, breaks, PartGouge(part, tool, block, bounds),
                             **kw)
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])
    assert got[2] == want[2]


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10_000), st.integers(2, 60), st.integers(0, 8), st.floats(0.0, 1.0))
def test_split_is_the_former_halving(seed, n, rounds, tol):
    """The halving alone, with a measure that depends only on each move (a hash of it),
    thresholds respected as the real one does, random breaks: the same points, parameters
    and gouges as inserting into the whole polyline every round, and every segment of the
    result measured once as it is."""
    rng = np.random.default_rng(seed)
    points = np.column_stack([np.cumsum(rng.uniform(0.0, 0.3, n)), rng.uniform(0, 1, n),
                              rng.uniform(-1, 1, n)])
    points[:, :2] = np.round(points[:, :2], 4)
    u = np.cumsum(rng.uniform(0.1, 1.0, n))
    breaks = rng.random(n - 1) < 0.2
    seen: list[tuple[np.ndarray, np.ndarray]] = []

    def measure(a, b, above=None):
        seen.append((a.copy(), b.copy()))
        h = np.sin(a @ [12.9898, 78.233, 37.719] + b @ [4.1414, 9.187, 21.3]) * 43758.5453
        return (h - np.floor(h)) * 2.0 - 0.5  # in [-0.5, 1.5)

    gouge = measure(points[:-1], points[1:])
    min_len = 0.01
    got = _split(points, u, gouge.copy(), breaks, measure, tol, min_len, 4, rounds)
    first = len(seen)
    want = _split_reference(points, u, gouge.copy(), breaks, measure, tol, min_len, 4,
                            rounds)
    assert len(seen) - first == first - 1  # the same measure calls, in the same order
    for (a0, b0), (a1, b1) in zip(seen[1:first], seen[first:], strict=True):
        np.testing.assert_array_equal(a0, a1)
        np.testing.assert_array_equal(b0, b1)
    for g, w in zip(got, want, strict=True):
        np.testing.assert_array_equal(g, w)
