"""The CL a plan's large-ball pass takes where its target is not dropped whole (session 9).

Dropping the ball on the model's nodes only let it sink below the bilinear surface beside a
steep wall at its rim (the plan said "finished" where its program left up to 5 mm on the
1025² bench part). :func:`drop_target` takes the bilinear drop-cutter on the rows the
positions use, interpolated as the tool paths take it; checked against dense sampling of
the bilinear surface (a lower bound of the true CL) and against the whole-grid drop.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.test_sim import reference_cl
from zwcore import Tool, ZMap
from zwcore.scanline import _stock_kernels as _k
from zwcore.scanline._stock_lines import drop_nodes, drop_target
from zwcore.scanline._stock_state import Positions
from zwcore.sim import drop_cutter


def _cliff(n: int, d: float, seed: int) -> np.ndarray:
    """A floor with a 6-12 mm step across a random line, some relief."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:n, 0:n] * d
    angle = rng.uniform(0, np.pi)
    side = x * np.cos(angle) + y * np.sin(angle) > rng.uniform(0.3, 0.7) * n * d
    return rng.uniform(6, 12) * side + 0.3 * np.sin(x * 1.3) * np.cos(y * 0.7)


@settings(max_examples=12, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from(["x", "y"]))
def test_drop_target_is_never_below_the_bilinear_surface_on_nodes(seed: int, along: str
                                                                   ) -> None:
    n, d = 25, 0.25
    z = _cliff(n, d, seed)
    tool = Tool("b", "ball", 3.0, 6.0)
    lines = np.arange(0, n, 3) * d
    along_pts = np.arange(n) * d
    if along == "x":
        py, px = np.meshgrid(lines, along_pts, indexing="ij")
    else:
        px, py = np.meshgrid(lines, along_pts, indexing="ij")
    pos = Positions(px.ravel().copy(), py.ravel().copy(), along)
    got = drop_target(z, pos, tool, d, d)
    ref = reference_cl(z, d, tool.radius, "ball", m=6)
    cols, rows = np.rint(pos.x / d).astype(int), np.rint(pos.y / d).astype(int)
    assert np.all(got >= ref[rows, cols] - 1e-9)  # never below the surface's CL
    # the whole-grid drop, read at the same nodes: the same values
    whole = drop_cutter(ZMap(z, dx=d, dy=d), tool, "bilinear", method="pruned")
    np.testing.assert_allclose(got, whole[rows, cols], rtol=0, atol=1e-9)


@pytest.mark.parametrize("along", ["x", "y"])
def test_drop_target_between_nodes_is_the_paths_interpolated_cl(along: str) -> None:
    n, d = 41, 0.2
    z = _cliff(n, d, 7)
    tool = Tool("b", "ball", 4.0, 8.0)
    rng = np.random.default_rng(3)
    u = rng.uniform(0, (n - 1) * d, 300)
    v = np.repeat(rng.uniform(0, (n - 1) * d, 30), 10)
    px, py = (u, v) if along == "x" else (v, u)
    pos = Positions(px, py, along)
    got = drop_target(z, pos, tool, d, d)
    whole = drop_cutter(ZMap(z, dx=d, dy=d), tool, "bilinear", method="pruned")
    paths = _k.interpolate(whole, 1.0 / d, 1.0 / d, px, py)
    nodal = drop_nodes(z, _k.block_max(z, 8), pos, np.full(pos.size, -np.inf), tool.radius,
                       d, d)
    np.testing.assert_allclose(got, np.maximum(paths, nodal), rtol=0, atol=1e-9)
    # the nodes alone sink below what the paths take beside the step: what was wrong
    assert (paths - nodal).max() > 0.3
