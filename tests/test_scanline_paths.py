"""Scan lines laid by region (issue 16): every cell's scallop from the lines really present.

The checks rebuild, from the segments a plan reports (``stage.lines``) and the
stage model alone, which lines pass over each cell of the stage's level, the
largest gap between adjacent ones there, and the design's closed-form scallop
``R - sqrt(R^2 - (p / (2 cos theta))^2)`` with ``theta`` the steepest slope of
the bilinear cell across the lines (its edge differences). None of the
planner's own figures enter.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.scanline.planner import ScanlinePlan, plan_scanline
from zwcore.scanline.results import ScanlineStage


def _closed_form(gap: np.ndarray, slope: np.ndarray, radius: float) -> np.ndarray:
    e = 0.5 * gap / np.cos(np.arctan(slope))
    with np.errstate(invalid="ignore"):
        return np.where(e <= radius, radius - np.sqrt(np.maximum(radius**2 - e**2, 0.0)), np.inf)


def cell_scallops(stage: ScanlineStage, extent: tuple[float, float]) -> np.ndarray:
    """``(strips, cells)`` scallop of every cell of the stage's level from its reported lines.

    ``extent`` is the part's ``(width, height)`` in mm. Strips run across the
    lines (between adjacent grid lines of the level), cells along them.
    """
    sx, sy = stage.spacing
    m = stage.model
    lines = stage.lines
    if stage.scan_direction == "x":  # lines along x: strips are rows of cells
        across, along, s_across, s_along, grid = extent[1], extent[0], sy, sx, m
    else:
        across, along, s_across, s_along, grid = extent[0], extent[1], sx, sy, m.T
    n_strips = math.ceil(across / s_across - 1e-9)
    n_cells = max(math.ceil(along / s_along - 1e-9), 1)
    eps = 1e-9 * max(across, along, 1.0)
    out = np.zeros((n_strips, n_cells))
    c = np.arange(n_cells)
    cell_lo = c * s_along
    cell_hi = np.minimum((c + 1) * s_along, along)
    for i in range(n_strips):
        lo_off, hi_off = i * s_across, min((i + 1) * s_across, across)
        d = np.abs(grid[i + 1] - grid[i]) / s_across  # edge differences across the strip
        hi_node = np.minimum(c + 1, grid.shape[1] - 1)
        slope = np.maximum(d[c], d[hi_node])
        # Lines run along every k-th grid line where the scallop allows, so the lines
        # around a strip may lie beyond its grid lines: every pair of adjacent lines
        # over a cell whose gap overlaps the strip bounds the cell's scallop there.
        order = np.argsort(lines.offset, kind="stable")
        last = np.full(n_cells, np.nan)
        below = np.zeros(n_cells, dtype=bool)
        above = np.zeros(n_cells, dtype=bool)
        gap = np.zeros(n_cells)
        for o, a, b in zip(lines.offset[order], lines.start[order], lines.stop[order],
                           strict=True):
            covers = (a <= cell_lo + eps) & (b >= cell_hi - eps)
            spans = covers & ~np.isnan(last) & (o > lo_off + eps) & (last < hi_off - eps)
            gap = np.where(spans, np.maximum(gap, o - last), gap)
            below |= covers & (o <= lo_off + eps)
            above |= covers & (o >= hi_off - eps)
            last = np.where(covers, o, last)
        # Both strip edges must be bracketed everywhere (lines on grid lines run whole).
        assert np.all(below & above), f"strip {i}: no line at or beyond its grid lines"
        out[i] = _closed_form(gap, slope, stage.tool.radius)
    return out


def _extent(zmap: ZMap) -> tuple[float, float]:
    ny, nx = zmap.shape
    return (nx - 1) * zmap.dx, (ny - 1) * zmap.dy


def _check_lines(zmap: ZMap, plan: ScanlinePlan, tolerance: float) -> None:
    extent = _extent(zmap)
    for s in plan.stages:
        lines = s.lines
        assert np.all(lines.start <= lines.stop)
        along = extent[0] if s.scan_direction == "x" else extent[1]
        assert lines.start.min() >= 0.0 and lines.stop.max() <= along * (1 + 1e-12)
        total = float(np.sum(lines.stop - lines.start))
        assert s.path_length == pytest.approx(total, rel=1e-12, abs=1e-12)
        assert s.path_length <= s.path_length_whole_strips * (1 + 1e-12)
        if min(extent) > 0.0 and s.sim_lifted_nodes == 0:
            h = cell_scallops(s, extent)
            # Every pass keeps the scallop it reports (stock for the next pass)... except
            # a pass the flute rule on the simulated stock raised after its lines were
            # laid: its raised cells are the lift's own steps, and what it leaves for the
            # next pass of the same ball is simulated (sim_left_over_next_*).
            assert h.max() <= s.scallop_height * (1 + 1e-6) + 1e-12
    # ... and the finishing pass meets the tolerance in every cell.
    if min(extent) > 0.0:
        assert cell_scallops(plan.stages[-1], extent).max() <= tolerance


@st.composite
def surfaces(draw: st.DrawFn) -> ZMap:
    """Smooth bumps, slopes and walls: steep in places, flat in others."""
    ny, nx = draw(st.integers(3, 30)), draw(st.integers(3, 30))
    d = draw(st.floats(0.05, 1.0))
    y, x = np.mgrid[0:ny, 0:nx] * d
    z = np.zeros((ny, nx))
    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.sampled_from(["bump", "wall", "ramp"]))
        cx, cy = draw(st.floats(0, nx * d)), draw(st.floats(0, ny * d))
        h = draw(st.floats(-10.0, 10.0))
        w = draw(st.floats(0.1, 5.0))
        if kind == "bump":
            z += h * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (w * w))
        elif kind == "wall":
            z += h * 0.5 * (1.0 + np.tanh((x - cx) / (0.2 * w)))
        else:
            z += h / 10.0 * (x * math.cos(w) + y * math.sin(w))
    return ZMap(z, dx=d, dy=d * draw(st.sampled_from([1.0, 0.5, 2.0])))


@settings(max_examples=40, deadline=None)
@given(zmap=surfaces(), tol=st.floats(1e-3, 0.1),
       radius=st.sampled_from([None, 0.25, 1.0, 3.0]))
def test_every_cell_meets_its_scallop_from_the_lines_present(zmap: ZMap, tol: float,
                                                             radius: float | None) -> None:
    tools = None if radius is None else [Tool("B", "ball", 2 * radius, 10.0)]
    plan = plan_scanline(zmap, tools, tolerance=tol)
    assert plan.checks.ok
    _check_lines(zmap, plan, tol)


def test_a_boss_gets_extra_lines_only_near_its_flank() -> None:
    # A round boss on a flat plate four times its width: whichever way the lines run, they cross
    # its flank. The extra lines run over the flank's cells and one radius
    # either side, not across the whole plate.
    y, x = np.mgrid[0:241, 0:241] * 0.1
    z = 5.0 / (1.0 + np.exp((np.hypot(x - 12.0, y - 12.0) - 3.0) / 0.3))
    zmap = ZMap(z, dx=0.1, dy=0.1)
    tool = Tool("B", "ball", 2.0, 20.0)
    plan = plan_scanline(zmap, [tool], tolerance=0.005)
    last = plan.stages[-1]
    _check_lines(zmap, plan, 0.005)
    assert last.pick_feed_reduced and last.extra_segments > 0
    # Nominal lines sit on the grid lines; extra ones between them.
    k = last.lines.offset / 0.1
    extra = np.abs(k - np.round(k)) > 1e-6
    assert np.count_nonzero(extra) == last.extra_segments
    # The flank (slope over a few degrees) lies within 3 +- 2 mm of the centre.
    reach = 5.0 + tool.radius + 0.1
    centre = (12.0, 12.0)
    assert np.all(np.abs(last.lines.offset[extra] - centre[1]) < reach)
    assert np.all(last.lines.start[extra] > centre[0] - reach)
    assert np.all(last.lines.stop[extra] < centre[0] + reach)
    nominal = float(np.sum((last.lines.stop - last.lines.start)[~extra]))
    assert last.path_length - nominal < 0.5 * (last.path_length_whole_strips - nominal)
