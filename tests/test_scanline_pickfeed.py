"""The finishing pick-feed from the scallop: lines every k-th grid line where flat.

Checked against an independent brute force: the ball is dropped onto the part's
nodes at positions along the plan's own finishing lines, and the stock it leaves
is compared with the stock the same ball leaves running on every grid row (the
ball's reach; what the pick-feed adds on top of it is the scallop).
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
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
