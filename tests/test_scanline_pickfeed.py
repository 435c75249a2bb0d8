"""The finishing pick-feed from the scallop: lines every k-th grid line where flat.

Checked against an independent brute force: the ball is dropped onto the part's
nodes at positions along the plan's own finishing lines, and the stock it leaves
is compared with the stock the same ball leaves running on every grid row (the
ball's reach; what the pick-feed adds on top of it is the scallop). The simulated
stock's thinning of such a pass is checked by brute force too: every position of the
pass lies within the thinning's gap of a simulated one.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.scanline import _stock as stock_sim
from zwcore.scanline.planner import plan_scanline
from zwcore.scanline.results import ScanLines

D = 0.125  # grid spacing, mm
N = 49  # nodes a side (6 mm)
R = 5.0  # ball radius, mm
TOL = 0.01


def _stock(z: np.ndarray, d: float, offsets: np.ndarray, spans: np.ndarray, along_x: bool,
           step: float) -> np.ndarray:
    """Stock a ball of radius ``R`` leaves at the nodes, run along the given lines.

    Positions every ``step`` along each line; at each the tip drops until it
    touches a node (``max z(q) - h(|q - c|)``), and every node within ``R`` is
    cut to ``tip + h``: the nodal closing restricted to the lines' positions.
    """
    ny, nx = z.shape
    yy, xx = np.mgrid[0:ny, 0:nx] * d
    q = np.stack((xx.ravel(), yy.ravel()), axis=1)
    zq = z.ravel()
    out = np.full(zq.size, np.inf)
    for off, (a, b) in zip(offsets, spans, strict=True):
        u = np.arange(a, b + 1e-9, step)
        c = np.stack((u, np.full_like(u, off)), axis=1) if along_x else \
            np.stack((np.full_like(u, off), u), axis=1)
        d2 = ((c[:, None, :] - q[None, :, :]) ** 2).sum(axis=2)
        h = np.where(d2 <= R * R, R - np.sqrt(np.maximum(R * R - d2, 0.0)), np.inf)
        tip = (zq[None, :] - h).max(axis=1)
        out = np.minimum(out, (tip[:, None] + h).min(axis=0))
    return out.reshape(z.shape)


@st.composite
def smooth_parts(draw: st.DrawFn) -> np.ndarray:
    """A tilted plane with a Gaussian bump or dimple a ball of radius R fits."""
    yy, xx = np.mgrid[0:N, 0:N] * D
    a, b = draw(st.floats(-0.3, 0.3)), draw(st.floats(-0.3, 0.3))
    amp = draw(st.floats(-0.3, 0.6))
    sigma = draw(st.floats(1.5, 3.0))
    cx, cy = draw(st.floats(0.0, 6.0)), draw(st.floats(0.0, 6.0))
    bump = amp * np.exp(-((xx - cx) ** 2 + (yy - cy) ** 2) / (2.0 * sigma * sigma))
    z: np.ndarray = 5.0 + a * xx + b * yy + bump
    return z


@settings(max_examples=12, deadline=None)
@given(z=smooth_parts())
def test_finishing_lines_wider_than_grid_and_scallop_within_tolerance(z: np.ndarray) -> None:
    ball = Tool("B10", "ball", 2.0 * R, 40.0)
    plan = plan_scanline(ZMap(z, dx=D, dy=D), [ball], tolerance=TOL)
    last = plan.stages[-1]
    assert last.tool.id == ball.id
    across = last.spacing[1] if last.scan_direction == "x" else last.spacing[0]
    # Flat enough here for the flat rule's 0.63 mm: lines skip grid lines somewhere.
    assert last.pick_feed_max >= 2.0 * across * (1 - 1e-9)
    lines: ScanLines = last.lines
    along_x = lines.direction == "x"
    assert np.unique(lines.offset).size < (N - 1) * D / across + 1
    step = D / 2.0
    got = _stock(z, D, lines.offset, np.stack((lines.start, lines.stop), axis=1), along_x, step)
    length = (N - 1) * D
    every = np.arange(N) * D
    dense = _stock(z, D, every, np.tile([0.0, length], (N, 1)), along_x, step)
    # The lines leave at most the tolerance above what the ball leaves anyway.
    assert (got - dense).max() <= TOL + 1e-9


@st.composite
def line_sets(draw: st.DrawFn) -> tuple[ScanLines, int]:
    """Lines along x on a 0.1 mm grid: whole lines every ``k_pick``-th grid line over some
    stretches of rows and on every one elsewhere (a finishing pass's layout), a few
    extra segments between grid lines, and the last line at the part's edge."""
    n = draw(st.integers(40, 160))  # strips
    k_pick = draw(st.integers(1, 9))
    coarse_rows = draw(st.lists(st.booleans(), min_size=n // max(k_pick, 1) + 1,
                                max_size=n // max(k_pick, 1) + 1))
    rows: list[int] = []
    for g, coarse in enumerate(coarse_rows):
        a = g * k_pick
        rows.extend([a] if coarse else range(a, min(a + k_pick, n)))
    rows = sorted({r for r in rows if r < n} | {0})
    offset = [0.1 * r for r in rows] + [0.1 * n]
    length = 0.1 * n
    start, stop = [0.0] * len(offset), [length] * len(offset)
    for r in draw(st.lists(st.integers(0, n - 1), max_size=5)):
        offset.append(0.1 * r + 0.05)
        start.append(draw(st.floats(0.0, length / 2)))
        stop.append(length)
    off, lo, hi = np.array(offset), np.array(start), np.array(stop)
    order = np.lexsort((lo, off))
    return ScanLines("x", off[order], lo[order], hi[order]), n


@settings(max_examples=40, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])  # same patch each time
@given(case=line_sets())
def test_thinning_keeps_lines_at_most_gap_apart(case: tuple[ScanLines, int],
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    """Thinning a pass whose lines skip grid lines: every position the full pass has lies
    within the thinning's ``gap`` of a simulated one (brute force over the positions), and
    on lines on every grid line it keeps the rows divisible by ``k`` (as it always did)."""
    lines, n = case
    monkeypatch.setattr(stock_sim, "MAX_PASS_WORK", 2_000)  # force thinning on this small part
    part = ZMap(np.zeros((n + 1, n + 1)), dx=0.1, dy=0.1)
    ball = Tool("B10", "ball", 10.0, 40.0)
    thin = stock_sim._Thinning.of(lines, part, 1, ball, (0.1, 0.1))
    assert thin.k > 1
    full = stock_sim.positions(lines, part, 1)
    kept = stock_sim.positions(thin.lines, part, thin.k)
    d2 = (full.x[:, None] - kept.x[None, :]) ** 2 + (full.y[:, None] - kept.y[None, :]) ** 2
    assert np.sqrt(d2.min(axis=1)).max() <= thin.gap * (1 + 1e-9)
    assert thin.gap <= 0.7 * ball.radius
    grid = np.abs(lines.offset / 0.1 - np.rint(lines.offset / 0.1)) <= 1e-9
    if np.unique(np.rint(lines.offset[grid] / 0.1)).size == n + 1:  # every grid line
        idx = np.rint(thin.lines.offset / 0.1).astype(int)
        assert set(idx) == set(range(0, n + 1, thin.k)) | {n}
