"""The fast simulated stock (a stage's next pass visits only the positions whose CL may
fall or whose stock within R changed) against the straightforward one (every pass
simulates every position), pass by pass on random parts."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.scanline import _stock
from zwcore.scanline._stock_grid import GridMode
from zwcore.scanline.results import ScanLines


@st.composite
def _cases(draw: st.DrawFn) -> tuple[ZMap, Tool, int, int, bool]:
    n = draw(st.integers(12, 40))
    d = draw(st.sampled_from([0.25, 0.5]))
    x = np.arange(n) * d
    xx, yy = np.meshgrid(x, x)
    z = np.zeros((n, n))
    for _ in range(draw(st.integers(1, 3))):
        cx, cy = draw(st.floats(0, x[-1])), draw(st.floats(0, x[-1]))
        r = draw(st.floats(0.5, 4.0))
        h = draw(st.floats(-12.0, 12.0))
        if draw(st.booleans()):
            z = np.where(np.hypot(xx - cx, yy - cy) <= r, z + h, z)  # pocket or boss
        else:
            z = z + h * np.exp(-((xx - cx) ** 2 + (yy - cy) ** 2) / (r * r))
    dia = draw(st.sampled_from([1.0, 2.0, 3.0]))
    tool = Tool("B", "ball", dia, draw(st.sampled_from([0.5, 1.0, 2.0])))
    every = draw(st.sampled_from([1, 2]))  # scan lines every node row, or every other
    stride = draw(st.sampled_from([1, 3]))
    # passes alternate between lines along x and along y (two states per stage)
    return ZMap(z, dx=d, dy=d), tool, every, stride, draw(st.booleans())


def _stage(zmap: ZMap, tool: Tool, every: int, stride: int, alternate: bool,
           memo: _stock.PassMemo | None,
           ) -> list[tuple[np.ndarray, np.ndarray, int, float, float, float]]:
    """Passes of one stage (target: the part) until one is not lifted: per pass the
    stock, the lifted model, lifted nodes, depth max and mean, gouge."""
    n = zmap.shape[0]  # square parts
    rows = np.arange(0, n, every) * zmap.dy
    ends = np.zeros(rows.size), np.full(rows.size, (n - 1) * zmap.dx)
    lines = [ScanLines("x", rows, *ends), ScanLines("y", rows, *ends)]
    sim = _stock.StockSim(zmap, float(zmap.z.max()) + 8.0)
    out = []
    for k in range(60):
        model = zmap.z.copy()
        done = _stock.run_pass(sim, model, (zmap.dx, zmap.dy), tool,
                               lines[k % 2 if alternate else 0], stride, None, 1e-9,
                               memo=memo)
        cut = done.cut
        out.append((sim.stock.copy(), model, done.lifted_nodes, cut.depth_max,
                    cut.depth_mean, cut.gouge))
        if done.lifted_nodes == 0 and (k % 2 or not alternate):
            break
    return out


def _grid_mode(zmap: ZMap, tool: Tool, every: int, stride: int) -> bool:
    n = zmap.shape[0]
    px = np.zeros((n // every + 1) * (n // stride + 1))
    return GridMode.of(px, px, zmap, tool, _stock.BLOCK) is not None


@settings(max_examples=40, deadline=None)
@given(case=_cases())
def test_fast_passes_leave_the_same_stock(case: tuple[ZMap, Tool, int, int, bool]) -> None:
    """Same positions, same kernels: the same stock, models and figures bit for bit.
    Where a pass runs as whole-grid operations (grid mode: a float32 envelope, rounded
    up by its shift's rounding) the straightforward path re-applies it every pass with
    another shift, the fast one cuts only the changed positions with the exact kernel:
    the two stocks then agree within that rounding, once per pass (a lifted CL follows
    the stock read, so the rounding of one pass moves the next one's CL)."""
    zmap, tool, every, stride, alternate = case
    fast = _stage(zmap, tool, every, stride, alternate, _stock.PassMemo())
    slow = _stage(zmap, tool, every, stride, alternate, None)
    grid = _grid_mode(zmap, tool, every, stride)
    # the envelope's float32 bound (zwcore.sim._morph): 2 ** -22 * (span + 1) per rounded
    # value, a few times over; the span reaches from the lowest CL to the stock top
    span = float(zmap.z.max()) + 8.0 - float(zmap.z.min()) + tool.radius
    rounding = 8.0 * 2.0 ** -22 * (span + 1.0)
    if not grid:
        assert len(fast) == len(slow)
    for k, (f, s) in enumerate(zip(fast, slow, strict=False)):
        if grid:
            assert np.max(np.abs(f[0] - s[0])) <= (k + 1) * rounding
            continue
        assert np.array_equal(f[0], s[0])
        assert np.array_equal(f[1], s[1])
        assert f[2:] == s[2:]
    # both never below the part
    assert fast[-1][5] <= 1e-9 and slow[-1][5] <= 1e-9
