"""Feed links between contour rings (issue 12): checked on the program read back by the
parser and simulated, and against a brute-force distance to the terraces written here."""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from zwcore import ZMap, default_tools, plan_contour
from zwcore.toolpath import contour_toolpaths, parse_program
from zwcore.toolpath.contour_paths import link_is_clear
from zwcore.toolpath.parse import ParsedProgram


def _segment_distance(q: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Brute force: distance from every point ``q`` (m, 2) to every segment ``a b`` (n, 2)."""
    ab = b - a
    ll = np.maximum((ab**2).sum(1), 1e-300)
    t = np.clip((((q[None] - a[:, None]) * ab[:, None]).sum(2)) / ll[:, None], 0.0, 1.0)
    foot = a[:, None] + t[..., None] * ab[:, None]
    return np.hypot(*(q[None] - foot).transpose(2, 0, 1))  # (n, m)


def _level_feeds(prog: ParsedProgram) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Straight feed moves at one height (rings' lines and the links between rings):
    start, end, and the tool number."""
    sel = ((prog.motion == 1) & np.isfinite(prog.start).all(1)
           & (np.abs(prog.end[:, 2] - prog.start[:, 2]) < 1e-9))
    return prog.start[sel], prog.end[sel], prog.tool[sel]


def _terrace_clearance(part: ZMap, plan, tp, prog: ParsedProgram) -> float:
    """Smallest (distance to the stage model's nodes above the move) minus the tool radius
    over all straight feed moves at one height: >= 0 means every such move keeps its tool
    centre where the tool cuts no terrace above it."""
    by_number = {p.cutting.tool_number: i for i, p in enumerate(tp.stages)}
    p0, p1, tool = _level_feeds(prog)
    worst = np.inf
    ny, nx = part.shape
    yy, xx = np.mgrid[0:ny, 0:nx]
    for number in np.unique(tool):
        st_ = plan.stages[by_number[int(number)]]
        model = np.repeat(np.repeat(st_.model, st_.scale, 0), st_.scale, 1)[:ny, :nx]
        sel = tool == number
        for h in np.unique(np.round(p0[sel, 2], 4)):
            m = sel & (np.abs(p0[:, 2] - h) < 1e-3)
            above = model > h + 1e-4
            if not above.any():
                continue
            q = np.column_stack([part.x0 + xx[above] * part.dx, part.y0 + yy[above] * part.dy])
            d = _segment_distance(q, p0[m, :2], p1[m, :2]).min()
            worst = min(worst, d - st_.tool.radius)
    return float(worst)


def _pocket(n: int, dx: float, boxes, discs) -> ZMap:
    y, x = np.mgrid[0:n, 0:n] * dx
    z = np.zeros((n, n))
    for cx, cy, hw, hh, depth in boxes:
        z = np.where((abs(x - cx) < hw) & (abs(y - cy) < hh), np.minimum(z, -depth), z)
    for cx, cy, r, depth in discs:  # islands / steps inside the pockets
        z = np.where(np.hypot(x - cx, y - cy) < r, -depth, z)
    return ZMap(z, 0.0, 0.0, dx, dx)


def _check(part: ZMap, tolerance: float = 0.02):
    tools = [t for t in default_tools("flat") if t.diameter in (10, 6, 3)]
    plan = plan_contour(part, tools)
    tp = contour_toolpaths(part, plan, tolerance=tolerance)
    chk = tp.check
    assert chk is not None
    # the program itself, simulated: no gouge, no move below the part, rapids in air only
    assert chk.gouge <= 1e-9 and chk.below_part_moves == 0 and chk.rapid_in_material == 0.0
    prog = parse_program(tp.program)
    # every feed move at one height (the links included) keeps the tool off the terraces
    assert _terrace_clearance(part, plan, tp, prog) >= 0.0
    return plan, tp, prog


def test_contour_rings_are_linked_by_feed_moves_inside_the_allowed_region():
    part = _pocket(161, 0.25, [(20, 20, 14, 12, 6.0)], [(14, 20, 4, 1.0), (28, 22, 5, 3.0)])
    _plan, tp, prog = _check(part)
    d = prog.end - prog.start
    retracts = int(((prog.motion == 0) & (d[:, 2] > 0)).sum())
    ramps = int(((prog.motion > 0) & (d[:, 2] < -1e-9)).sum())
    n_rings = int(sum(p.figures["rings"] for p in tp.stages))
    # most rings are reached at their height from the ring before, not from the clearance
    assert n_rings >= 40 and retracts <= n_rings // 4
    assert ramps > 0  # the rings entered from above still ramp in


def test_two_pockets_are_not_linked_across_the_wall_between_them():
    # two pockets 4 mm apart: any straight move between them below the top cuts the wall
    part = _pocket(129, 0.25, [(8, 16, 6, 8, 4.0), (24, 16, 6, 8, 4.0)], [])
    plan, _tp, prog = _check(part)
    p0, p1, _tool = _level_feeds(prog)
    deep = p0[:, 2] < -1e-6
    assert deep.sum() > 20
    crosses = (np.minimum(p0[:, 0], p1[:, 0]) < 16.0) & (np.maximum(p0[:, 0], p1[:, 0]) > 16.0)
    assert not (crosses & deep).any()
    # the other pocket is reached over the wall: up to the clearance, ramped into
    d = prog.end - prog.start
    assert ((prog.motion == 0) & (d[:, 2] > 0) & (prog.end[:, 2] >= plan.stock_top)).sum() >= 4


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 2**31 - 1))
def test_contour_links_never_cut_the_part_on_random_pockets(seed):
    rng = np.random.default_rng(seed)
    boxes = [(rng.uniform(6, 26), rng.uniform(6, 26), rng.uniform(3, 9), rng.uniform(3, 9),
              rng.uniform(1, 6)) for _ in range(rng.integers(1, 4))]
    discs = [(rng.uniform(4, 28), rng.uniform(4, 28), rng.uniform(1, 4), rng.uniform(0, 5))
             for _ in range(rng.integers(0, 3))]
    _check(_pocket(97, 1 / 3, boxes, discs), tolerance=0.03)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_link_check_agrees_with_brute_force(seed):
    from scipy.spatial import cKDTree

    rng = np.random.default_rng(seed)
    q = rng.uniform(0, 10, (rng.integers(1, 40), 2))
    a, b = rng.uniform(-2, 12, 2), rng.uniform(-2, 12, 2)
    clear = rng.uniform(0.1, 3)
    brute = _segment_distance(q, a[None], b[None]).min()
    if abs(brute - clear) < 1e-9:
        return
    assert link_is_clear(cKDTree(q), a, b, clear) == (brute >= clear)


def test_rings_of_one_offset_are_each_cut_once():
    """Two rings of the same offset in one part: both come out, each once (a ring was once
    removed from the queue by ``==``, which compares the loops' arrays and raised)."""
    from zwcore.toolpath.contour_paths import order_rings

    part = ZMap(np.zeros((41, 41)), dx=0.5, dy=0.5)
    labels = np.ones(part.shape, np.int32)
    t = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    ring = np.column_stack([np.cos(t), np.sin(t)])
    far, near, mid = ring + np.full(2, 15.0), ring + np.full(2, 5.0), ring + np.full(2, 10.0)
    out = order_rings(part, labels, [(2, far), (2, near), (1, mid)], np.array([0.0, 0.0]))
    assert len(out) == 3
    centres = [tuple(np.round(o.mean(axis=0))) for o in out]
    assert centres == [(5.0, 5.0), (15.0, 15.0), (10.0, 10.0)]
