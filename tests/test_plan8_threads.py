"""The plan's second thread (``zwcore.scanline._threads``): the split kernels give what
the whole ones give, bit for bit, and a plan is the same with one thread or two.

- the envelope sweep over two bands of node rows (``cut_lines(..., i_lo, i_hi)``), the
  bands run one after the other, equals one sweep over all rows, and the plain numpy
  brute force; a band leaves the other band's rows alone;
- ``LineSweep.cut``/``drop`` and the per-position kernels split between two threads
  (forced on small inputs) equal the one-thread results;
- the reach estimate's chain and figures, and whole plans, with two threads equal those
  with one (the chain search's pairs of candidates included);
- ``both``/``each``: results in order, errors raised, no hand-off from the helper thread.
"""

from __future__ import annotations

import dataclasses
import math
import threading

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.test_scanline_stock_sweep import _brute_cut, _cases
from tests.thread_modes import force_threads
from zwcore.grid.tools import default_tools
from zwcore.grid.zmap import ZMap
from zwcore.scanline import _reach, _regions, _stock_lines, _threads
from zwcore.scanline import _stock_kernels as _k
from zwcore.scanline._stock_state import BLOCK, Positions, block_max
from zwcore.scanline._stock_sweep import cut_lines, line_starts
from zwcore.scanline.planner import plan_scanline
from zwcore.sim import _morph

_Case = tuple[np.ndarray, float, float, float, np.ndarray, np.ndarray, np.ndarray]


def _sorted(case: _Case) -> tuple[np.ndarray, ...]:
    u, v, c = case[4:]
    order = np.lexsort((u, v))
    return (np.ascontiguousarray(u[order]), np.ascontiguousarray(v[order]),
            np.ascontiguousarray(c[order]), line_starts(v[order]), order)


@settings(max_examples=150, deadline=None)
@given(case=_cases(), along_x=st.booleans(), cut=st.integers(0, 6))
def test_envelope_by_row_bands_equals_one_sweep(case: _Case, along_x: bool,
                                                cut: int) -> None:
    """Two bands of node rows (split at a block boundary, either order) give the whole
    sweep's stock and lowered blocks bit for bit, and the brute force's stock; a band
    alone lowers no row of the other."""
    z, r, dx, dy, u, v, c = case
    pu, pv, pc, starts, _ = _sorted(case)
    du, dv = (dx, dy) if along_x else (dy, dx)
    stock = (z + 2.0) if along_x else np.ascontiguousarray((z + 2.0).T)
    nv = stock.shape[0]
    mid = min(cut * BLOCK, nv)
    skip = np.zeros(block_max(stock).shape, dtype=bool)

    def sweep(bands: list[tuple[int, int]]) -> tuple[np.ndarray, np.ndarray]:
        s = stock.copy()
        t = np.zeros_like(skip)
        for lo, hi in bands:
            cut_lines(s, pu, pv, pc, starts, r, du, dv, BLOCK, t, skip, lo, hi)
        return s, t

    whole, t_whole = sweep([(0, -1)])
    split, t_split = sweep([(mid, -1), (0, mid)])
    assert np.array_equal(split, whole)
    assert np.array_equal(t_split, t_whole)
    low, _ = sweep([(0, mid)])
    assert np.array_equal(low[mid:], stock[mid:])  # the other band's rows untouched
    assert np.array_equal(low[:mid], whole[:mid])
    x, y = (u, v) if along_x else (v, u)
    brute = _brute_cut(z + 2.0, x, y, c, r, dx, dy)
    np.testing.assert_allclose(whole if along_x else whole.T, brute, rtol=0, atol=1e-12)


@pytest.fixture
def forced_threads(monkeypatch: pytest.MonkeyPatch) -> None:
    """Two threads for every split, however small the work."""
    force_threads(monkeypatch, 2)


@settings(max_examples=60, deadline=None)
@given(case=_cases(), along_x=st.booleans())
def test_threaded_line_sweep_and_kernels_equal_one_thread(case: _Case, along_x: bool
                                                          ) -> None:
    """``LineSweep.cut``/``drop`` and the per-position drop and top, on two threads
    (forced), equal the one-thread results bit for bit."""
    z, r, dx, dy, u, v, c = case
    x, y = (u, v) if along_x else (v, u)
    along = "x" if along_x else "y"
    stock = z + 2.0
    cl0 = np.where(np.arange(c.size) % 3 == 0, -np.inf, c - 3.0)
    smax = block_max(stock)
    got = []
    for workers in (1, 2):
        with pytest.MonkeyPatch.context() as mp:
            force_threads(mp, workers, split=workers > 1)
            sweep = _stock_lines.LineSweep.of(x, y, along, r, dx, dy)
            s = stock.copy()
            t = np.zeros(smax.shape, dtype=bool)
            drop = None
            if sweep is not None:
                sweep.cut(s, c, t, np.zeros_like(t))
                drop = sweep.drop(z, cl0)
            per = _stock_lines.per_position(
                lambda a, b: _k.cl_part(z, block_max(z), BLOCK, x[a:b], y[a:b], cl0[a:b], r,
                                        dx, dy), x.size, r, dx, dy)
            top = _stock_lines.per_position(
                lambda a, b: _k.top(stock, smax, BLOCK, x[a:b], y[a:b], r, dx, dy), x.size,
                r, dx, dy)
            nodes = _stock_lines.drop_nodes(z, block_max(z), Positions(x, y, along), cl0, r,
                                            dx, dy)
            got.append((s, t, drop, per, top, nodes))
    for a, b in zip(*got, strict=True):
        if a is None or b is None:
            assert a is None and b is None
        else:
            assert np.array_equal(a, b)
    # the per-position drop: the kernel over all positions at once
    assert np.array_equal(got[1][3], _k.cl_part(z, block_max(z), BLOCK, x, y, cl0, r, dx, dy))


def _fillet_part(n: int = 97, d: float = 0.25) -> ZMap:
    """A floor with a sharp crease at a 45° wall's foot and a sharp-cornered pocket: a
    chain of several balls, rest regions and pair costs in the chain search."""
    x = np.arange(n) * d
    xx, yy = np.meshgrid(x, x)
    z = np.maximum(xx - 12.0, 0.0)
    pocket = (np.abs(xx - 6.0) < 3.0) & (np.abs(yy - 12.0) < 4.0)
    z = np.where(pocket, -2.0, z)
    return ZMap(z, dx=d, dy=d)


def _fields(obj: object) -> object:
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: _fields(getattr(obj, f.name)) for f in dataclasses.fields(obj)
                if f.name != "timings"}
    if isinstance(obj, (list, tuple)):
        return [_fields(o) for o in obj]
    if isinstance(obj, dict):
        return {k: _fields(o) for k, o in obj.items()}
    return obj


def _assert_same(a: object, b: object, path: str = "plan") -> None:
    if isinstance(a, dict):
        assert isinstance(b, dict) and a.keys() == b.keys(), path
        for k in a:
            _assert_same(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, list):
        assert isinstance(b, list) and len(a) == len(b), path
        for n, (u, w) in enumerate(zip(a, b, strict=True)):
            _assert_same(u, w, f"{path}[{n}]")
    elif isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray) and np.array_equal(a, b, equal_nan=True), path
    elif isinstance(a, float) and math.isnan(a):
        assert isinstance(b, float) and math.isnan(b), path
    else:
        assert a == b, path


def test_reach_chain_is_the_same_on_two_threads(forced_threads: None,
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    """The chain search with its pairs of candidates on two threads visits the pairs the
    one-by-one search visits (and maybe one more), and ends with the same chain and
    figures; the pairs it computes side by side are counted."""
    part = _fillet_part()
    balls = list(default_tools("ball"))
    runs = []
    for workers in (1, 2):
        monkeypatch.setattr(_threads, "WORKERS", workers)
        reach = _regions._Reach(part.z, part.dx, part.dy, 0.01)
        chain, times = _regions._plan(balls, reach)
        runs.append((chain, times, dict(reach.times)))
    assert runs[0][0] == runs[1][0]
    assert runs[0][1] == runs[1][1]
    one, two = runs[0][2], runs[1][2]
    assert set(one) <= set(two)  # the speculative pairs may add some
    assert all(two[k] == one[k] for k in one)
    assert len(runs[0][0]) >= 2  # a chain with rest balls: the pair search ran


@pytest.mark.parametrize("part", ["fillet", "synthetic"])
def test_plan_is_the_same_on_two_threads(part: str, forced_threads: None,
                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """Every plan field (timings aside) with every split on two threads equals the
    one-thread plan."""
    if part == "fillet":
        zmap = _fillet_part()
    else:  # the bench part (bench/bench_scanline_core.py) on 129²: bumps, a pocket, a wall
        x = np.linspace(0.0, 100.0, 129)
        xx, yy = np.meshgrid(x, x)
        z = 8.0 * np.sin(xx / 9.0) * np.cos(yy / 13.0) + 0.002 * (xx - 50.0) ** 2
        pocket = np.hypot(xx - 60.0, yy - 40.0)
        z = np.where(pocket < 15.0, np.minimum(z, -12.0 + 15.0 - np.sqrt(
            np.maximum(15.0**2 - pocket**2, 0.0))), z)
        z = np.where(xx > 85.0, z + 10.0, z)
        zmap = ZMap(z, dx=100.0 / 128, dy=100.0 / 128)
    plans = []
    for workers in (1, 2):
        monkeypatch.setattr(_threads, "WORKERS", workers)
        monkeypatch.setattr(_morph, "THREADS", workers)
        plans.append(_fields(plan_scanline(zmap)))
    _assert_same(plans[0], plans[1])


def test_both_and_each_keep_order_and_raise(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(_threads, "WORKERS", 2)
    main = threading.get_ident()
    seen: list[int] = []

    def who() -> int:
        seen.append(threading.get_ident())
        return threading.get_ident()

    a, b = _threads.both(who, who)
    assert b == main and a != main  # the first on the helper thread
    assert _threads.each([lambda n=n: n * n for n in range(7)]) == [n * n for n in range(7)]

    def nested() -> tuple[int, int]:  # from the helper thread: both run there, in turn
        return _threads.both(who, who)

    inner, _ = _threads.both(nested, lambda: 0)
    assert inner[0] == inner[1] != main

    def boom() -> None:
        raise ValueError("boom")

    with pytest.raises(ValueError, match="boom"):
        _threads.both(boom, lambda: 1)
    with pytest.raises(ValueError, match="boom"):
        _threads.both(lambda: 1, boom)
    with pytest.raises(ValueError, match="boom"):
        _threads.each([lambda: 1, boom, lambda: 2])
    monkeypatch.setattr(_threads, "WORKERS", 1)
    assert _threads.both(who, who) == (main, main)


@settings(max_examples=100, deadline=None)
@given(w=st.lists(st.floats(0.0, 100.0), min_size=2, max_size=40))
def test_split_at_weight_halves(w: list[float]) -> None:
    """Both runs non-empty; the first holds at least half the weight, less its last."""
    a = np.array(w)
    m = _threads.split_at_weight(a)
    assert 1 <= m <= a.size - 1
    total = float(a.sum())
    if m < a.size - 1:
        assert float(a[:m].sum()) >= 0.5 * total - 1e-9 * max(total, 1.0)
    assert float(a[:m - 1].sum()) <= 0.5 * total + 1e-9 * max(total, 1.0)



@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), ny=st.integers(1, 60), nx=st.integers(1, 30),
       a=st.integers(0, 4), b=st.integers(0, 4), wide=st.booleans())
def test_dilation_in_two_runs_of_strips_equals_one(seed: int, ny: int, nx: int, a: int,
                                                   b: int, wide: bool) -> None:
    """The grey dilation with its strips on two threads (forced; small strips so there
    are several) equals one thread bit for bit, and is never below the brute force
    (nor above it by more than its stated rounding)."""
    rng = np.random.default_rng(seed)
    z = rng.normal(0.0, 100.0 if wide else 1.0, (ny, nx))
    s = -rng.uniform(0.0, 1.0, (2 * a + 1, 2 * b + 1))
    s = np.minimum(s, s[::-1])
    s = np.minimum(s, s[:, ::-1])
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(_morph, "_STRIP_BYTES", 8 * max(nx, 1))  # the fewest rows a strip takes: 8
        force_threads(mp, 1, split=False)
        one = _morph.dilate(z, s)
        force_threads(mp, 2)
        two = _morph.dilate(z, s)
    assert np.array_equal(one, two)
    zp = np.pad(z, ((a, a), (b, b)), constant_values=-np.inf)
    brute = np.full(z.shape, -np.inf)
    for i in range(2 * a + 1):
        for k in range(2 * b + 1):
            brute = np.maximum(brute, zp[i:i + ny, k:k + nx] + s[i, k])
    assert np.all(two >= brute)
    assert np.all(two - brute <= 4.0 * _morph.FLOAT32_MARGIN + 1e-9 * np.abs(brute).max())


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), ny=st.integers(1, 30), nx=st.integers(1, 30))
def test_concave_radii_in_two_bands_equal_one(seed: int, ny: int, nx: int) -> None:
    """The concave radii by two bands of rows on two threads equal one pass, and are at
    most a plain numpy evaluation of the same formula along x at the inner nodes (the
    least of four directions)."""
    rng = np.random.default_rng(seed)
    z = rng.normal(0.0, 1.0, (ny, nx)).cumsum(axis=0)
    with pytest.MonkeyPatch.context() as mp:
        force_threads(mp, 1, split=False)
        one = _reach.concave_radii(z, 0.2, 0.3)
        force_threads(mp, 2)
        two = _reach.concave_radii(z, 0.2, 0.3)
    assert np.array_equal(one, two)
    if nx >= 3:
        right = (z[:, 2:] - z[:, 1:-1]) / 0.2
        left = (z[:, 1:-1] - z[:, :-2]) / 0.2
        curv = (right - left) / 0.2
        s = np.where(left * right > 0.0, np.minimum(np.abs(left), np.abs(right)), 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            rho = np.where(curv > 0.0, (1.0 + s * s) ** 1.5 / curv, np.inf)
        assert np.all(one[:, 1:-1] <= rho * (1.0 + 1e-12))
