"""Links between scan-line segments (issue 12): segments are reached from the previous one
by staying down or by a short lift, not from the clearance. Checked on the program read
back by the parser and swept move by move over the stock here."""

from __future__ import annotations

import re

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.test_toolpath import brute_cl, hemisphere_pocket, wavy_part
from zwcore import ZMap, default_tools, plan_scanline
from zwcore.toolpath import parse_program, scanline_toolpaths
from zwcore.toolpath.sweep import GridFrame, sweep_moves


def _moves_over_stock(part: ZMap, plan, tp) -> list[tuple[np.ndarray, np.ndarray, np.ndarray,
                                                             np.ndarray]]:
    """Per stage (the program's text cut at its stage comments, each piece read back by the
    parser): start, end, motion and each move's largest stock above its swept envelope
    before it (> 0: it met material), swept in program order over one stock."""
    head, *stages = re.split(r"(?m)^(?=\(stage )", tp.program)
    radius = {p.cutting.tool_number: p.tool.radius for p in tp.stages}
    stock = np.full(part.shape, plan.stock_top)
    frame = GridFrame(part.x0, part.y0, part.dx, part.dy, part.shape)
    out = []
    tool = 0
    assert len(stages) == len(plan.stages)
    for text in stages:
        prog = parse_program(head + text)
        sel = np.isfinite(prog.start).all(1)
        p0, p1, motion = prog.start[sel], prog.end[sel], prog.motion[sel]
        assert not (motion >= 2).any()  # scan-line programs are lines only
        # a stage with the tool of the stage before changes nothing: no T word of its own
        tool = int(prog.tool[-1]) or tool
        over, _ = sweep_moves(frame, p0, p1, radius[tool], True, stock,
                              apply=motion != 0)
        out.append((p0, p1, motion, over))
    return out


def _check(part: ZMap, tolerance: float) -> tuple[int, int, int]:
    plan = plan_scanline(part, default_tools("ball"), tolerance=tolerance)
    tp = scanline_toolpaths(part, plan, brute_cl)
    chk = tp.check
    assert chk is not None
    assert chk.gouge <= 1e-9 and chk.below_part_moves == 0 and chk.rapid_in_material == 0.0
    clearance = tp.settings.clearance
    links = up_high = 0
    for p0, p1, motion, over in _moves_over_stock(part, plan, tp):
        d = p1 - p0
        # the stage's lines run along the axis most feed moves keep
        along_x = (np.abs(d[:, 1]) < 1e-9).sum() >= (np.abs(d[:, 0]) < 1e-9).sum()
        across = np.abs(d[:, 1] if along_x else d[:, 0]) > 1e-9
        link = (motion == 1) & across
        # a feed move from one line to another (a link) cuts nothing
        assert np.all(over[link] <= 1e-9)
        # rapids (down to an entry, across at a lift height) run in air
        assert np.all(over[motion == 0] <= 1e-6)
        links += int(link.sum())
        up_high += int(((motion == 0) & (p1[:, 2] >= clearance - 1e-9) & (d[:, 2] > 0)).sum())
    segments = int(sum(p.figures["segments"] + p.figures["scallop_segments"]
                       for p in tp.stages))
    return segments, links, up_high


def test_segments_on_the_r8_pocket_are_linked_without_the_clearance():
    segments, links, up_high = _check(hemisphere_pocket(), 0.01)
    assert segments > 100
    # before: each segment was left by a rapid up to the clearance
    assert up_high <= segments // 10
    assert links > 0


@settings(max_examples=5, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 2**31 - 1))
def test_segment_links_never_cut_on_random_surfaces(seed):
    _check(wavy_part(41, 0.5, seed, amplitude=4.0), 0.02)
