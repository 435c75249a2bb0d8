"""The block bounds of the simulated stock (``zwcore.scanline._stock_bounds``) and what
they let a pass skip: the highest stock within R where the bounds settle it against a
plain numpy maximum; the envelope with settled blocks skipped against the kernels
without (bit for bit) and a numpy brute force; a lifted pass that finds its unlifted CL
only where the flute rule may leave it against the eager pass (bit for bit); and the
cusp a thinned pass may leave on a flat against the pass at every position."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.scanline import _stock, _stock_lines
from zwcore.scanline import _stock_bounds as _b
from zwcore.scanline import _stock_kernels as _k
from zwcore.scanline._stock_state import BLOCK, block_max, grow_blocks
from zwcore.scanline.results import ScanLines


def _brute_top(s: np.ndarray, x: np.ndarray, y: np.ndarray, r: float, dx: float,
               dy: float) -> np.ndarray:
    yy, xx = np.mgrid[0:s.shape[0], 0:s.shape[1]]
    out = np.empty(x.size)
    for n in range(x.size):
        d2 = (xx * dx - x[n]) ** 2 + (yy * dy - y[n]) ** 2
        out[n] = np.where(d2 <= r * r * _k.RIM, s, -np.inf).max()
    return out


def _brute_cut(s: np.ndarray, x: np.ndarray, y: np.ndarray, c: np.ndarray, r: float,
               dx: float, dy: float) -> np.ndarray:
    yy, xx = np.mgrid[0:s.shape[0], 0:s.shape[1]]
    out = s.copy()
    for n in range(x.size):
        d2 = (xx * dx - x[n]) ** 2 + (yy * dy - y[n]) ** 2
        h = r - np.sqrt(np.maximum(r * r - d2, 0.0))
        out = np.minimum(out, np.where(d2 <= r * r * _k.RIM, c[n] + h, np.inf))
    return out


@st.composite
def _stocks(draw: st.DrawFn) -> tuple[np.ndarray, float, float, np.ndarray, np.ndarray]:
    """A stock with plateaus (where the bounds settle) and bumps, positions on its nodes
    and between them."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    n = draw(st.integers(20, 70))
    d = draw(st.sampled_from([0.1, 0.25]))
    s = np.full((n, n), 5.0)
    for _ in range(draw(st.integers(0, 4))):
        i, k = rng.integers(0, n, 2)
        w = int(rng.integers(1, 12))
        s[max(i - w, 0):i + w, max(k - w, 0):k + w] += float(rng.normal(0.0, 2.0))
    r = draw(st.floats(0.5, 3.0))
    m = draw(st.integers(1, 300))
    on = draw(st.booleans())
    x = rng.integers(0, n, m) * d if on else rng.uniform(-0.5 * d, (n - 0.5) * d, m)
    y = rng.integers(0, n, m) * d if on else rng.uniform(-0.5 * d, (n - 0.5) * d, m)
    return s, r, d, x.astype(float), y.astype(float)


@settings(max_examples=80, deadline=None)
@given(case=_stocks())
def test_settled_top_is_the_highest_stock_within_r(
        case: tuple[np.ndarray, float, float, np.ndarray, np.ndarray]) -> None:
    s, r, d, x, y = case
    smax = block_max(s)
    top, rest = _b.top_bounded(smax, grow_blocks(smax, r, d, d), s.shape, x, y, r, d, d,
                               BLOCK)
    sure = np.ones(x.size, dtype=bool)
    sure[rest] = False
    want = _brute_top(s, x, y, r, d, d)
    assert np.array_equal(top[sure], want[sure])
    assert np.all(np.isnan(top[rest]))


def test_a_level_stock_is_settled_without_the_kernel() -> None:
    s = np.full((64, 64), 3.0)
    x = np.arange(64) * 0.1
    smax = block_max(s)
    top, rest = _b.top_bounded(smax, grow_blocks(smax, 2.0, 0.1, 0.1), s.shape, x, x, 2.0,
                               0.1, 0.1, BLOCK)
    assert rest.size == 0 and np.all(top == 3.0)


@st.composite
def _passes(draw: st.DrawFn) -> tuple[np.ndarray, float, float, np.ndarray, np.ndarray,
                                      np.ndarray]:
    """Positions on every node of every (or every other) row, CL level over patches
    (where the envelope settles) and varying elsewhere, over a stock with bumps."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    n = draw(st.integers(20, 60))
    d = draw(st.sampled_from([0.1, 0.2]))
    every = draw(st.sampled_from([1, 2]))
    yy, xx = np.mgrid[0:n:every, 0:n]
    x, y = (xx.ravel() * d).astype(float), (yy.ravel() * d).astype(float)
    c = np.full(x.size, 1.0)
    if draw(st.booleans()):
        c = c + np.round(rng.normal(0.0, 0.5, x.size), 1) * (rng.random(x.size) < 0.2)
    if draw(st.booleans()):
        c = c + 0.05 * x  # a slope: nothing settles
    stock = 3.0 + rng.normal(0.0, 0.5, (n, n))
    r = draw(st.floats(0.3, 2.5))
    return stock, r, d, x, y, c


@settings(max_examples=60, deadline=None)
@given(case=_passes(), along_x=st.booleans())
def test_settled_envelope_equals_the_kernels(
        case: tuple[np.ndarray, float, float, np.ndarray, np.ndarray, np.ndarray],
        along_x: bool) -> None:
    """Settling first and skipping the settled blocks leaves the same stock and lowered
    blocks as the kernels alone, bit for bit (the per-position kernel and the sweep),
    and the brute force's to its rounding."""
    stock, r, d, x, y, c = case
    if not along_x:
        x, y = y, x
    smax = block_max(stock)
    none = np.zeros(smax.shape, dtype=bool)
    ref = stock.copy()
    t_ref = none.copy()
    _k.cut(ref, smax, BLOCK, x, y, c, r, d, d, t_ref, none)
    for swept in (False, True):
        got = stock.copy()
        t_got = none.copy()
        skip = _b.settle(got, x, y, c, r, d, d, BLOCK, t_got)
        if swept:
            sweep = _stock_lines.LineSweep.of(x, y, "x" if along_x else "y", r, d, d)
            if sweep is None:  # forced: the choice is by cost alone
                u, v = (x, y) if along_x else (y, x)
                order = np.lexsort((u, v))
                sweep = _stock_lines.LineSweep(order, np.ascontiguousarray(u[order]),
                                      np.ascontiguousarray(v[order]),
                                      _stock_lines._sw.line_starts(v[order]), along_x, r, d, d)
            sweep.cut(got, c, t_got, skip)
            # the sweep may take a tied ball rounded a few ulps higher (its module)
            assert np.all(got >= ref)
            assert np.all(got - ref <= 8 * np.spacing(np.abs(ref)))
        else:
            _k.cut(got, smax, BLOCK, x, y, c, r, d, d, t_got, skip)
            assert np.array_equal(got, ref)
        assert np.array_equal(t_got, t_ref)
    np.testing.assert_allclose(ref, _brute_cut(stock, x, y, c, r, d, d), rtol=0, atol=1e-12)


def test_a_level_pass_settles_its_blocks() -> None:
    n, d = 48, 0.1
    yy, xx = np.mgrid[0:n, 0:n]
    x, y = (xx.ravel() * d).astype(float), (yy.ravel() * d).astype(float)
    stock = np.full((n, n), 4.0)
    touched = np.zeros(block_max(stock).shape, dtype=bool)
    skip = _b.settle(stock, x, y, np.full(x.size, 1.0), 1.5, d, d, BLOCK, touched)
    assert skip.all() and touched.all() and np.all(stock == 1.0)


def _stage(zmap: ZMap, tool: Tool, every: int, bounds: bool, top: float,
           monkeypatch: pytest.MonkeyPatch) -> list[tuple[np.ndarray, ...]]:
    monkeypatch.setattr(_stock, "BOUNDS", bounds)
    n = zmap.shape[0]
    rows = np.arange(0, n, every) * zmap.dy
    lines = ScanLines("x", rows, np.zeros(rows.size), np.full(rows.size, (n - 1) * zmap.dx))
    sim = _stock.StockSim(zmap, top)
    memo = _stock.PassMemo()
    out = []
    for _ in range(40):
        model = zmap.z.copy()
        done = _stock.run_pass(sim, model, (zmap.dx, zmap.dy), tool, lines, 1, None, 1e-9,
                               memo=memo)
        out.append((sim.stock.copy(), model, np.array([done.lifted_nodes,
                                                       done.cut.depth_max,
                                                       done.cut.depth_mean,
                                                       done.cut.gouge])))
        if done.lifted_nodes == 0:
            break
    return out


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), every=st.sampled_from([1, 2]),
       flute=st.sampled_from([0.5, 1.5, 4.0]))
def test_lazy_lifted_passes_equal_the_eager_ones(seed: int, every: int, flute: float) -> None:
    """A ball of 16 spacings in radius (the sweep or the per-position kernels, not grid
    mode) from a stock well above the part: the stage's passes with the bounds (the
    top and envelope settled where they can be, the unlifted CL found only where the
    flute rule may leave it) leave the same stock, lifted models and figures as without."""
    rng = np.random.default_rng(seed)
    n, d = 56, 0.1
    xx, yy = np.meshgrid(np.arange(n) * d, np.arange(n) * d)
    z = np.zeros((n, n))
    for _ in range(3):
        cx, cy, w = rng.uniform(0, n * d, 3)
        z = z + rng.normal(0.0, 1.5) * np.exp(-((xx - cx) ** 2 + (yy - cy) ** 2)
                                               / (0.2 + w) ** 2)
    zmap = ZMap(z, dx=d, dy=d)
    tool = Tool("B", "ball", 3.2, flute)
    top = float(z.max()) + 2.0 * flute + 1.0
    with pytest.MonkeyPatch.context() as mp:
        lazy = _stage(zmap, tool, every, True, top, mp)
        eager = _stage(zmap, tool, every, False, top, mp)
    assert len(lazy) == len(eager) > 1  # lifted passes, then the one that reaches
    for a, b in zip(lazy, eager, strict=True):
        for u, v in zip(a, b, strict=True):
            assert np.array_equal(u, v)


@pytest.mark.parametrize("cusp", [0.0025, 0.01, 0.04])
def test_thinned_pass_leaves_at_most_the_lattice_cusp_on_a_flat(cusp: float) -> None:
    """A pass too large to simulate everywhere, over a flat part: its simulated positions
    are at most ``sqrt(8 R cusp)`` apart, and the stock it leaves lies between the stock
    of the pass at every position and that plus the ball's height at the farthest a node
    can lie from a simulated one (half the gap's diagonal, ``<= 2 cusp``): above, never
    below."""
    n, d = 257, 0.1
    zmap = ZMap(np.zeros((n, n)), dx=d, dy=d)
    tool = Tool("B20", "ball", 20.0, 40.0)
    rows = np.arange(n) * d
    lines = ScanLines("x", rows, np.zeros(n), np.full(n, (n - 1) * d))
    thin = _stock._Thinning.of(lines, zmap, 1, tool, (d, d), cusp)
    assert thin.k > 1  # the bound lets it thin
    assert thin.gap <= math.sqrt(8.0 * tool.radius * cusp) + 1e-12
    stocks = []
    for thinning in (True, False):
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(_stock, "THINNING", thinning)
            sim = _stock.StockSim(zmap, 1.0)
            _stock.run_pass(sim, zmap.z.copy(), (d, d), tool, lines, 1, None, 1e-9,
                            lift=False, cusp=cusp)
            stocks.append(sim.stock.copy())
    thinned, full = stocks
    # every position: the plate itself, to the rounding (up) of the target's drop-cutter
    # when it is dropped whole (the thinned pass, with fewer positions, drops the ball at
    # them only: exactly 0 there)
    assert full.min() >= 0.0 and full.max() <= 1e-5
    corner = thin.gap / math.sqrt(2.0)
    assert thinned.min() >= 0.0  # never below the envelope
    assert thinned.max() <= tool.radius - math.sqrt(tool.radius ** 2 - corner ** 2) + 1e-5
    assert thinned.max() <= 2.0 * cusp * 1.01
    assert thinned.max() > 1e-4  # (it is thinned: the cusps show)


def test_a_cheap_pass_is_not_thinned() -> None:
    """The thinning counts the kernels' real work (the sweep's, where it is the cheaper):
    a Ø12 ball on an 82² grid at 0.1 mm (R = 60 spacings, 7.6e7 footprint visits) is
    simulated at every position."""
    n, d = 82, 0.1
    zmap = ZMap(np.zeros((n, n)), dx=d, dy=d)
    rows = np.arange(n) * d
    lines = ScanLines("x", rows, np.zeros(n), np.full(n, (n - 1) * d))
    tool = Tool("B12", "ball", 12.0, 24.0)
    assert _stock._Thinning.of(lines, zmap, 1, tool, (d, d), None).k == 1


def test_positions_bounds_are_block_lookups() -> None:
    """``block_at`` reads the block of each position's nearest node."""
    grid = np.arange(9.0).reshape(3, 3)
    x = np.array([0.0, 0.74, 0.81, 2.0])
    y = np.array([0.0, 0.0, 0.81, 2.0])
    got = _b.block_at(grid, BLOCK, x, y, 10.0, 10.0)
    assert got.tolist() == [0.0, 0.0, 4.0, 8.0]
