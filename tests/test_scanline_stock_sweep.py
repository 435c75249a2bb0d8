"""The line-sweep kernels of the simulated stock (``zwcore.scanline._stock_sweep``)
against the per-position kernels and a plain numpy brute force, on random stocks, parts
and positions on scan lines (grid lines and lines between them, points on the nodes and
between them, both directions)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.test_scanline_stock import _assert_sim_holds
from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.scanline import _stock, _stock_lines
from zwcore.scanline import _stock_kernels as _k
from zwcore.scanline import _stock_sweep as _sw
from zwcore.scanline._stock_state import BLOCK, block_max
from zwcore.scanline._stock_sweep import cl_lines, cut_lines, line_starts
from zwcore.scanline.planner import plan_scanline
from zwcore.scanline.results import ScanLines

#: Balls that reach a node at the same height differ in their rounding only: the sweep
#: takes one of them, a few ulps from the least (the per-position kernel's).
_ULPS = 8

_Case = tuple[np.ndarray, float, float, float, np.ndarray, np.ndarray, np.ndarray]


@st.composite
def _cases(draw: st.DrawFn) -> _Case:
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    ny, nx = draw(st.integers(3, 40)), draw(st.integers(3, 40))
    dx, dy = draw(st.sampled_from([0.1, 0.25, 0.3])), draw(st.sampled_from([0.1, 0.2, 0.25]))
    r = draw(st.floats(0.05, 3.0))
    z = rng.normal(0.0, 2.0, (ny, nx)).cumsum(axis=1) * 0.3
    if draw(st.booleans()):  # terraces: ties between nodes and between balls
        z = np.round(z)
    pu, pv = [], []
    for _ in range(draw(st.integers(1, 6))):
        v = (float(rng.integers(0, ny)) * dy if draw(st.booleans())
             else float(rng.uniform(-1.0, ny * dy + 1.0)))
        if draw(st.booleans()):
            u = np.arange(0, nx, draw(st.integers(1, 3))) * dx
        else:
            u = np.sort(rng.uniform(-1.0, nx * dx + 1.0, draw(st.integers(1, 25))))
        pu.append(u)
        pv.append(np.full(u.size, v))
    u, v = np.concatenate(pu), np.concatenate(pv)
    c = rng.normal(1.0, 2.0, u.size)
    if draw(st.booleans()):
        c = np.round(c)
    return z, r, dx, dy, u, v, c


def _brute_cut(s: np.ndarray, x: np.ndarray, y: np.ndarray, c: np.ndarray, r: float,
               dx: float, dy: float) -> np.ndarray:
    """min(stock, c + h) over every node and position, plain numpy."""
    ny, nx = s.shape
    yy, xx = np.mgrid[0:ny, 0:nx]
    out = s.copy()
    for p, q, cl in zip(x, y, c, strict=True):
        d2 = (xx * dx - p) ** 2 + (yy * dy - q) ** 2
        env = np.where(d2 <= r * r * _k.RIM, cl + (r - np.sqrt(np.maximum(r * r - d2, 0.0))),
                       np.inf)
        out = np.minimum(out, env)
    return out


@settings(max_examples=150, deadline=None)
@given(case=_cases(), along_x=st.booleans())
def test_sweep_cut_equals_the_per_position_kernel(case: _Case, along_x: bool) -> None:
    """Same stock and lowered blocks bit for bit; and equal to the brute force (to its
    own rounding: numpy's expression order)."""
    z, r, dx, dy, u, v, c = case
    stock = z + 2.0
    x, y = (u, v) if along_x else (v, u)
    order = np.lexsort((u, v))
    ref = stock.copy()
    t_ref = np.zeros(block_max(stock).shape, dtype=bool)
    _k.cut(ref, block_max(stock), BLOCK, x, y, c, r, dx, dy, t_ref, np.zeros_like(t_ref))
    got = stock.copy()
    t_got = np.zeros_like(t_ref)
    view = (lambda a: a) if along_x else (lambda a: a.T)
    du, dv = (dx, dy) if along_x else (dy, dx)
    cut_lines(view(got), np.ascontiguousarray(u[order]), np.ascontiguousarray(v[order]),
              np.ascontiguousarray(c[order]), line_starts(v[order]), r, du, dv, BLOCK,
              view(t_got), view(np.zeros_like(t_ref)))
    # the same to the rounding of tied balls, and never below (a winner rounded higher)
    assert np.all(got >= ref)
    assert np.all(got - ref <= _ULPS * np.spacing(np.abs(ref)))
    assert not np.any(t_got & ~t_ref)
    np.testing.assert_allclose(got, _brute_cut(stock, x, y, c, r, dx, dy), rtol=0, atol=1e-12)
    # the envelope is never below a ball: every lowered node lies on some ball
    assert np.all(got <= stock)


@settings(max_examples=150, deadline=None)
@given(case=_cases(), along_x=st.booleans())
def test_sweep_drop_equals_the_per_position_kernel(case: _Case, along_x: bool) -> None:
    """The drop against the nodes, with a floor (``cl0``, -inf in places), bit for bit."""
    z, r, dx, dy, u, v, c = case
    x, y = (u, v) if along_x else (v, u)
    cl0 = np.where(np.arange(c.size) % 3 == 0, -np.inf, c - 3.0)
    ref = _k.cl_part(z, block_max(z), BLOCK, x, y, cl0, r, dx, dy)
    order = np.lexsort((u, v))
    zz = z if along_x else np.ascontiguousarray(z.T)
    du, dv = (dx, dy) if along_x else (dy, dx)
    got = np.empty(c.size)
    got[order] = cl_lines(zz, np.ascontiguousarray(u[order]), np.ascontiguousarray(v[order]),
                          np.ascontiguousarray(cl0[order]), line_starts(v[order]), r, du, dv)
    assert np.array_equal(np.isfinite(got), np.isfinite(ref))
    fin = np.isfinite(ref)
    assert np.all(got[fin] <= ref[fin])
    assert np.all(ref[fin] - got[fin] <= _ULPS * np.spacing(np.abs(ref[fin])))
    # against the brute force: the highest node under the ball, plain numpy
    ny, nx = z.shape
    yy, xx = np.mgrid[0:ny, 0:nx]
    for n in range(0, c.size, max(1, c.size // 8)):
        d2 = (xx * dx - x[n]) ** 2 + (yy * dy - y[n]) ** 2
        h = r - np.sqrt(np.maximum(r * r - d2, 0.0))
        best = max(cl0[n], float(np.where(d2 <= r * r * _k.RIM, z - h, -np.inf).max()))
        assert got[n] == best or abs(got[n] - best) <= 1e-12


def test_stock_sim_gives_the_same_pass_with_either_kernel(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The stock simulation picks the sweep by cost; forcing either kernel gives the same
    pass (same stock, lifted model and depth figures)."""
    n, d = 48, 0.1
    xx, yy = np.meshgrid(np.arange(n) * d, np.arange(n) * d)
    part = ZMap(np.sin(xx) * np.cos(yy) + 0.3 * xx, dx=d, dy=d)
    tool = Tool("B", "ball", 3.0, 3.0)
    rows = np.arange(n) * d
    lines = ScanLines("y", rows, np.zeros(n), np.full(n, (n - 1) * d))
    results = []
    calls = []
    swept: list[int] = []
    sweep = _sw.cut_lines

    def counted(*args: object) -> None:
        calls.append(1)
        sweep(*args)  # type: ignore[arg-type]

    monkeypatch.setattr(_sw, "cut_lines", counted)
    for share in (0.0, 1e9):  # never, always
        monkeypatch.setattr(_stock_lines, "SWEEP_SHARE", share)
        monkeypatch.setattr(_stock_lines, "SWEEP_RUN_SHARE", share)
        sim = _stock.StockSim(part, float(part.z.max()) + 3.0)
        model = part.z.copy()
        done = _stock.run_pass(sim, model, (d, d), tool, lines, 1, None, 1e-9)
        results.append((sim.stock.copy(), model, done.cut.depth_max, done.cut.depth_mean))
        swept.append(len(calls))
    assert swept[0] == 0 < swept[1]  # only the second run swept
    assert np.array_equal(results[0][0], results[1][0])
    assert np.array_equal(results[0][1], results[1][1])
    assert results[0][2:] == results[1][2:]
    assert _stock_lines.LineSweep.of(np.zeros(4), np.zeros(4), None, 1.0, d, d) is None


def test_plan_with_swept_passes_holds_against_the_brute_force(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """A ball large against the grid (Ø8 on 0.1 mm: R = 40 nodes) finishing a small
    part: its passes run through the sweep (counted), and the plan re-simulated by the
    brute-force numpy reference of ``test_scanline_stock`` (positions from the reported
    lines, every node within R) keeps its flutes, does not gouge and reports the same
    depth and material left."""
    n, d = 97, 0.1
    xx, yy = np.meshgrid(np.arange(n) * d, np.arange(n) * d)
    z = 1.5 * np.sin(xx / 1.3) * np.cos(yy / 1.7) - 0.02 * (xx - 4.0) ** 2
    z = np.where(np.hypot(xx - 5.0, yy - 4.0) < 2.0, z - 1.0, z)  # a pocket with a wall
    zmap = ZMap(z, dx=d, dy=d)
    calls = []
    cut, drop = _sw.cut_lines, _sw.cl_lines

    def counted_cut(*args: object) -> None:
        calls.append("cut")
        cut(*args)  # type: ignore[arg-type]

    def counted_drop(*args: object) -> np.ndarray:
        calls.append("drop")
        out: np.ndarray = drop(*args)  # type: ignore[arg-type]
        return out

    monkeypatch.setattr(_sw, "cut_lines", counted_cut)
    monkeypatch.setattr(_sw, "cl_lines", counted_drop)
    plan = plan_scanline(zmap, [Tool("B8", "ball", 8.0, 6.0)], tolerance=0.01)
    assert "cut" in calls
    _assert_sim_holds(zmap, plan)
