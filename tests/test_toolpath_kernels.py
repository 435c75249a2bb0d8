"""The pieces that make scan-line tool paths fast (issue 12), each against an independent
computation: the band thinning against its definition, the coarse gouge look and the
threaded sweep against the plain exact sweep, the entry heights against the stock really
swept, and a stage restricted to a hand-made region mask, simulated from its program."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import zwcore.toolpath.sweep as sweep_mod
from tests.test_toolpath import wavy_part
from zwcore import ZMap, default_tools, plan_scanline
from zwcore.grid.tools import Tool
from zwcore.toolpath import parse_program, scanline_toolpaths, simulate_program
from zwcore.toolpath._polyline import PartGouge, thin
from zwcore.toolpath._scan_links import link_heights, merge_stretches, region_stretches
from zwcore.toolpath.sweep import BlockBounds, GridFrame, sweep_moves

#: Two compilations of the same sweep (the block and the plain kernel) differ where float
#: contraction lands elsewhere; at a ball's rim sqrt(R² - d²) magnifies a last-bit
#: difference of d² by R / sqrt(R² - d²) (1.1e-12 mm seen on a 0.33 mm ball): a nanometre.
KERNEL_ROUNDING = 1e-9


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-2, 2), min_size=3, max_size=80), st.floats(1e-3, 0.5),
       st.floats(0.0, 0.5))
def test_thinning_keeps_every_dropped_point_in_the_band(zs, above, below):
    z = np.cumsum(np.asarray(zs))
    u = np.arange(len(z), dtype=float) * 0.3
    fixed = np.zeros(len(z), bool)
    fixed[len(z) // 2] = True
    keep = thin(u, z, fixed, above, below)
    assert keep[0] and keep[-1] and keep[len(z) // 2]
    k = np.flatnonzero(keep)
    chord = np.interp(u, u[k], z[k])
    gap = chord - z  # > 0: the chord passes over the point
    assert gap.min() >= -below - 1e-9 and gap.max() <= above + 1e-9


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 10_000), st.sampled_from([2, 3, 5]), st.booleans())
def test_the_coarse_gouge_look_changes_no_value_that_matters(seed, block, ball):
    part = wavy_part(61, 0.25, seed)
    rng = np.random.default_rng(seed)
    tool = Tool("T", "ball" if ball else "flat", rng.uniform(0.5, 4.0), 20.0)
    lo = np.array([part.x0, part.y0, part.z.min() - 1])
    hi = np.array([part.x0 + 15, part.y0 + 15, part.z.max() + 2])
    p0 = rng.uniform(lo, hi, (300, 3))
    p1 = p0 + rng.normal(0, 1.5, (300, 3))
    fine = PartGouge(part, tool, 1)(p0, p1)
    look = PartGouge(part, tool, block)(p0, p1)
    # exact wherever a move gouges; elsewhere a bound that says it does not
    hit = fine > 0
    np.testing.assert_array_equal(look[hit], fine[hit])
    assert np.all(look[~hit] <= 0) and np.all((look > 0) == hit)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 10_000), st.sampled_from([1, 2, 3, 5, 8, 16]), st.booleans(),
       st.sampled_from(["cut", "measure", "threads"]), st.floats(0.3, 4.0))
def test_skipped_blocks_change_no_stock_and_no_positive_figure(seed, block, ball, mode, radius):
    """The sweep with :class:`BlockBounds` against the same kernel skipping nothing
    (``BlockBounds.none``): the same stock bit for bit, ``over_stock`` and ``over_ref`` the
    same wherever they are positive and ``<= 0`` elsewhere; and against the plain kernel to
    ``KERNEL_ROUNDING``; moves of every kind (along, across, steep, vertical, high above,
    grazing the part)."""
    part = wavy_part(71, 0.2, seed)
    frame = GridFrame(part.x0, part.y0, part.dx, part.dy, part.shape)
    rng = np.random.default_rng(seed)
    n = 600
    lo = np.array([part.x0 - 1, part.y0 - 1, part.z.min() - 0.5])
    hi = np.array([part.x0 + 15, part.y0 + 15, part.z.max() + 1.5])
    p0 = rng.uniform(lo, hi, (n, 3))
    step = rng.normal(0, rng.choice([0.2, 1.0, 4.0]), (n, 3))
    step[rng.random(n) < 0.1, :2] = 0.0  # vertical moves
    step[rng.random(n) < 0.3, 2] = 0.0  # level moves
    p1 = p0 + step
    flags = (rng.random(n) < 0.8) if mode != "measure" else False
    top = part.z.max() + rng.uniform(0.0, 1.0)
    plain = np.full(part.shape, top) if mode != "measure" else part.z.copy()
    skip = plain.copy()
    with pytest.MonkeyPatch.context() as mp:
        if mode == "threads":
            mp.setattr(sweep_mod, "MIN_MOVES_PER_THREAD", 50)
            mp.setattr(sweep_mod, "SWEEP_THREADS", 3)
        # the same kernel without skipping (bit for bit), and the plain kernel
        base = plain.copy()
        a_s, a_r = sweep_moves(frame, p0, p1, radius, ball, plain, ref=part.z, apply=flags,
                               bounds=BlockBounds.none(frame))
        c_s, c_r = sweep_moves(frame, p0, p1, radius, ball, base, ref=part.z, apply=flags)
        bounds = BlockBounds(frame, skip, part.z, block)
        b_s, b_r = sweep_moves(frame, p0, p1, radius, ball, skip, ref=part.z, apply=flags,
                               bounds=bounds)
    np.testing.assert_array_equal(plain, skip)
    for a, b in ((a_s, b_s), (a_r, b_r)):
        pos = a > 0
        np.testing.assert_array_equal(a[pos], b[pos])
        assert np.all(b[~pos] <= 0)
    # the plain kernel is compiled apart (float contraction may differ in the last bit)
    np.testing.assert_allclose(base, plain, rtol=0, atol=KERNEL_ROUNDING)
    for a, c in ((a_s, c_s), (a_r, c_r)):
        np.testing.assert_allclose(a, c, rtol=0, atol=KERNEL_ROUNDING)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 10_000), st.sampled_from([2, 4, 8]), st.floats(0.3, 4.0),
       st.sampled_from([0.05, 0.3, 2.0]), st.booleans())
def test_trailing_nodes_left_out_change_no_stock_and_no_figure_that_counts(
        seed, block, radius, step, threads):
    """Polylines (moves that continue each other: along rows, across, steep, with breaks,
    air moves and repeats back), swept with ``trail`` against the plain kernel that sweeps
    every node: the stock to ``KERNEL_ROUNDING``, ``over_stock`` wherever it says a move met
    material, and the deepest ``over_ref`` (a node a move leaves out is its predecessor's,
    as deep)."""
    part = wavy_part(71, 0.2, seed)
    frame = GridFrame(part.x0, part.y0, part.dx, part.dy, part.shape)
    rng = np.random.default_rng(seed)
    n = 500
    d = rng.normal(0.0, step, (n, 3))
    d[rng.random(n) < 0.4, 1] = 0.0  # along a row
    d[rng.random(n) < 0.1, :2] = 0.0  # vertical
    d[:, 2] *= rng.choice([0.1, 1.0, 5.0])
    pts = np.array([part.x0 + 7.0, part.y0 + 7.0, part.z.max()]) + np.cumsum(d, axis=0)
    pts[:, :2] = np.clip(pts[:, :2], part.x0 - 1, part.x0 + 15)
    pts[:, 2] = np.clip(pts[:, 2], part.z.min() - 0.3, part.z.max() + 1.0)
    p0, p1 = pts[:-1].copy(), pts[1:].copy()
    brk = rng.random(n - 1) < 0.05  # a jump: the next move does not continue this one
    p0[1:][brk[:-1]] += 0.5
    flags = rng.random(n - 1) < 0.9
    top = part.z.max() + 0.5
    plain, trailed = np.full(part.shape, top), np.full(part.shape, top)
    with pytest.MonkeyPatch.context() as mp:
        if threads:
            mp.setattr(sweep_mod, "MIN_MOVES_PER_THREAD", 50)
            mp.setattr(sweep_mod, "SWEEP_THREADS", 3)
        a_s, a_r = sweep_moves(frame, p0, p1, radius, True, plain, ref=part.z, apply=flags)
        b_s, b_r = sweep_moves(frame, p0, p1, radius, True, trailed, ref=part.z, apply=flags,
                               bounds=BlockBounds(frame, trailed, part.z, block), trail=True)
    assert (sweep_mod.trailing_cuts(p0, p1, np.full(n - 1, radius), flags) >= 0).any()
    np.testing.assert_allclose(trailed, plain, rtol=0, atol=KERNEL_ROUNDING)
    eps = 1e-9
    np.testing.assert_allclose(np.maximum(b_s, eps), np.maximum(a_s, eps), rtol=0, atol=1e-11)
    assert np.all(b_r <= np.maximum(a_r, -1e-11) + 1e-11)
    assert abs(max(b_r.max(), 0.0) - max(a_r.max(), 0.0)) <= 1e-11


def _plain_envelope(x, y, move, along_x):
    """The plain sweep's per-node envelope of the gathered offsets ``x, y`` for one move
    ``(sz, ax, ay, vz)`` of a Ø2.6 ball."""
    from zwcore.toolpath._sweep_plain import flat_envelope, row_envelope

    sz, ax, ay, vz = move
    r = 1.3
    a = ax * ax + ay * ay
    consts = (r, True, 1.0 / a, math.sqrt(1.0 / a), 1.0 / math.sqrt(a * (a + vz * vz)))
    out = np.empty(len(x))
    if along_x:
        sws = np.sqrt(np.maximum(r * r * (1.0 - 1e-10) - y * y, 0.0))
        row_envelope(len(x), x, y, sws, sz, ax, vz, *consts, out)
    else:
        flat_envelope(len(x), x, y, sz, ax, ay, vz, *consts, out)
    return out


@pytest.mark.parametrize("along_x", [False, True])
def test_plain_envelope_does_not_depend_on_a_nodes_place_in_the_gathered_arrays(along_x):
    """A band of rows gathers fewer nodes before a given one than the whole grid does, so
    the same node sits in another SIMD lane, or in the loop's scalar tail. With FMA
    contraction allowed the vector body and the tail rounded differently (one ulp: the
    threaded sweep differed from the single-thread one on CI); the envelope loops are now
    compiled without it, and a node's envelope is the same wherever it sits."""
    rng = np.random.default_rng(3)
    for _ in range(60):
        m = int(rng.integers(1, 120))
        wxs, wys = rng.uniform(-2, 2, m), rng.uniform(-2, 2, m)
        ax, ay, vz = rng.normal(0, 1, 3)
        move = (float(rng.normal()), ax, 0.0 if along_x else ay, vz)
        alone = _plain_envelope(wxs, wys, move, along_x)
        assert np.isfinite(alone).any()
        for pad in range(1, 20):
            x = np.r_[rng.uniform(-2, 2, pad), wxs]
            y = np.r_[rng.uniform(-2, 2, pad), wys]
            np.testing.assert_array_equal(_plain_envelope(x, y, move, along_x)[pad:], alone)


@pytest.mark.parametrize("apply", [True, False])
def test_threaded_sweep_is_the_single_thread_sweep(monkeypatch, apply):
    part = wavy_part(81, 0.2, 3)
    frame = GridFrame(part.x0, part.y0, part.dx, part.dy, part.shape)
    rng = np.random.default_rng(7)
    lo = np.array([part.x0, part.y0, part.z.min()])
    hi = np.array([part.x0 + 16, part.y0 + 16, part.z.max()])
    p0 = rng.uniform(lo, hi, (900, 3))
    p1 = p0 + rng.normal(0, 1.0, (900, 3))
    flags = rng.random(900) < 0.8 if apply else False
    results = []
    for threads in (1, 3):
        monkeypatch.setattr(sweep_mod, "SWEEP_THREADS", threads)
        monkeypatch.setattr(sweep_mod, "MIN_MOVES_PER_THREAD", 50)
        stock = np.full(part.shape, part.z.max() + 1.0)
        over_s, over_r = sweep_moves(frame, p0, p1, 1.3, True, stock, ref=part.z, apply=flags)
        results.append((stock, over_s, over_r))
    for a, b in zip(*results, strict=True):
        np.testing.assert_array_equal(a, b)


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 10_000), st.floats(0.3, 2.0))
def test_link_heights_keep_the_ball_off_the_stock_the_whole_lines_leave(seed, radius):
    # whole lines along u at a pick-feed under the radius, swept exactly over a stock; a
    # move along a random link (along the lines, across, over one point, off the stock)
    # with its tip at the bound from the lines' paths alone removes nothing, swept exactly
    part = wavy_part(51, 0.2, seed)
    rng = np.random.default_rng(seed)
    n = part.shape[1]
    u = np.arange(n) * part.dx
    pick = rng.uniform(0.3, 1.6) * radius
    offsets = np.arange(0.0, (part.shape[0] - 1) * part.dy + 1e-9, pick)
    top = part.z.max() + 1.0
    stock = np.full(part.shape, top)
    frame = GridFrame(0.0, 0.0, part.dx, part.dy, part.shape)
    paths = []
    for v in offsets:
        z = np.interp(u, u, part.z[min(round(v / part.dy), part.shape[0] - 1)]) + rng.uniform(
            0, 0.5)
        pts = np.column_stack([u, np.full(n, v), z])
        sweep_moves(frame, pts[:-1], pts[1:], radius, True, stock)
        paths.append(np.column_stack([u, z]))
    a = rng.uniform([-2, -2], [(n - 1) * part.dx + 2, (part.shape[0] - 1) * part.dy + 2],
                    (60, 2))
    b = a + rng.normal(0, 3, (60, 2))
    b[:15, 1] = a[:15, 1]  # along the lines
    b[15:30] = a[15:30]  # over one point (an entry)
    low = link_heights(a, b, offsets, paths, part.dx, part.dy, (n, part.shape[0]), radius,
                       top)
    reached = np.isfinite(low)
    z = np.where(reached, low, 0.0)[:, None]
    over, _ = sweep_moves(frame, np.hstack([a, z]), np.hstack([b, z]), radius, True,
                          stock.copy(), apply=False)
    assert np.all(over[reached] <= 1e-9)
    assert np.all(~np.isfinite(over[~reached]) | (over[~reached] <= 1e-9))
    # and it is the bound, not a height far above it: the stock just below the lines' top
    # reaches the links over the stock's middle
    inside = reached & (np.abs(a - b).sum(1) < 1e-12) & (a[:, 0] > 1) & (a[:, 1] > 1)
    assert np.all(low[inside] < top)


def test_region_stretches_follow_the_mask():
    region = np.zeros((5, 9), bool)
    region[2, 3:5] = True  # model nodes 3 and 4 of row 2
    li, a, b = region_stretches(region, np.array([2.0, 3.0, 1.5]), np.zeros(3),
                                np.full(3, 8.0), 1.0, 1.0)
    # row 2: cells 2..4 touch nodes 3-4; row 3 none; row 1.5 lies between rows 1 and 2
    np.testing.assert_array_equal(li, [0, 2])
    np.testing.assert_allclose(a, [2.0, 2.0])
    np.testing.assert_allclose(b, [5.0, 5.0])


@pytest.mark.parametrize("direction", ["x", "y"])
def test_cl_on_the_lines_rows_only_gives_the_same_path(monkeypatch, direction):
    """The default drop-cutter computes only the model rows (columns) a stage's lines read:
    on passes whose lines skip rows, the path is the one from the whole CL grid, and it is
    clear of the part (swept exactly, independently of the path's own lift)."""
    import dataclasses

    import zwcore.sim.cutting as cutting
    from zwcore.scanline.results import ScanLines
    from zwcore.toolpath.plans import tool_numbers
    from zwcore.toolpath.scanline_paths import scanline_stage_path, sim_cl_heights

    monkeypatch.setattr(cutting, "PRUNE_FOOTPRINT", 0)  # every tool by the pruned method
    part = wavy_part(49, 0.25, 5)
    plan = plan_scanline(part, default_tools("ball"), tolerance=0.05)
    data = tool_numbers(list(dict.fromkeys(s.tool for s in plan.stages)), None)
    frame = GridFrame(part.x0, part.y0, part.dx, part.dy, part.shape)
    for i, stage in enumerate(plan.stages):
        ln = stage.lines
        keep = np.arange(len(ln.offset)) % 3 == 0  # lines on every third model row or so
        half = 0.5 * stage.spacing[1 if direction == "x" else 0]
        off = ln.offset[keep] + np.where(np.arange(keep.sum()) % 2 == 1, half, 0.0)
        lines = ScanLines(direction, off, ln.start[keep], ln.stop[keep])
        st_ = dataclasses.replace(stage, lines=lines, scan_direction=direction)
        kw = dict(clearance=plan.stock_top + 5, chord_tolerance=0.0125,
                  stock_top=plan.stock_top)
        a = scanline_stage_path(part, st_, i, data[stage.tool.id], sim_cl_heights, **kw)
        b = scanline_stage_path(part, st_, i, data[stage.tool.id],
                                lambda m, t: sim_cl_heights(m, t), **kw)
        if direction == "x":
            np.testing.assert_array_equal(a.moves.end, b.moves.end)
        else:  # the transposed surface's rounding may differ in the last bit
            np.testing.assert_allclose(a.moves.end, b.moves.end, rtol=0, atol=2e-4)
        feed = a.moves.kind != 0
        p0 = np.vstack([a.start[None], a.moves.end[:-1]])[feed]
        _, below = sweep_moves(frame, p0, a.moves.end[feed], stage.tool.radius, True,
                               part.z.copy(), ref=part.z, apply=False)
        assert below.max() <= 1e-9


def test_a_region_mask_restricts_the_cut_and_keeps_every_guarantee():
    part = wavy_part(65, 0.25, 11)
    plan = plan_scanline(part, default_tools("ball"), tolerance=0.05)
    # a hand-made mask: a disc in the middle of each stage's model
    regions = []
    for s in plan.stages:
        my, mx = s.model.shape
        yy, xx = np.mgrid[0:my, 0:mx]
        cx, cy = 8.0 / s.spacing[0], 8.0 / s.spacing[1]
        regions.append(np.hypot((xx - cx) * s.spacing[0], (yy - cy) * s.spacing[1]) < 4.0)
    tp = scanline_toolpaths(part, plan, regions=regions)
    chk = tp.check
    assert chk is not None
    assert chk.gouge <= 1e-9 and chk.below_part_moves == 0 and chk.rapid_in_material == 0.0
    # read the program back independently: the feed moves stay over the disc, grown by a
    # model cell (a cut cell touches a node of the region), and the tool's reach leaves
    # the stock untouched beyond it
    prog = parse_program(tp.program)
    feed = prog.motion > 0
    cell = max(max(s.spacing) for s in plan.stages)
    centre = np.array([part.x0 + 8.0, part.y0 + 8.0])
    # (a stretch leads in and out by up to the ball's radius: with the reach plan's Ø20
    # on 8 mm cells that is what the bound of a cell alone missed)
    lead = max(math.sqrt(2) * max(s.spacing) + s.tool.radius for s in plan.stages)
    assert np.hypot(*(prog.end[feed, :2] - centre).T).max() <= 4.0 + lead + 1e-6
    ny, nx = part.shape
    yy, xx = np.mgrid[0:ny, 0:nx]
    far = np.hypot(part.x0 + xx * part.dx - centre[0], part.y0 + yy * part.dy - centre[1])
    reach = 4.0 + math.sqrt(2) * cell + max(s.tool.radius for s in plan.stages) + 1e-6
    table = {p.cutting.tool_number: p.tool for p in tp.stages}
    sim = simulate_program(prog, table, part, plan.stock_top, tolerance=plan.tolerance)
    assert np.all(sim.machined[far > reach] == plan.stock_top)
    assert (sim.machined < plan.stock_top).any()
    assert any(p.figures["segments"] > 0 for p in tp.stages)
    for p, r in zip(tp.stages, regions, strict=True):  # an empty region: nothing to cut
        assert r.any() or len(p.moves) == 0


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 10_000))
def test_segment_points_are_the_cl_rows_interpolated(seed):
    # oracle: per segment, the CL row interpolated between grid rows, then np.interp along it
    from zwcore.toolpath.scanline_paths import _segment_points
    rng = np.random.default_rng(seed)
    cl = rng.normal(size=(9, 13))
    sx, sy = 0.5, 0.7
    n = 6
    offset = rng.uniform(0, 8 * sy, n)
    a = rng.uniform(0, 12 * sx, n)
    b = np.minimum(a + rng.uniform(0.01, 4.0, n), 12 * sx)
    u, v, z, sizes = _segment_points(cl, offset, a, b, sx, sy)
    cols = np.arange(13) * sx
    pos = 0
    for k in range(n):
        r = offset[k] / sy
        r0 = int(np.floor(r))
        r1 = min(r0 + 1, 8)
        row = (1 - (r - r0)) * cl[r0] + (r - r0) * cl[r1]
        want_u = np.concatenate([[a[k]], cols[(cols > a[k]) & (cols < b[k])], [b[k]]])
        got = slice(pos, pos + sizes[k])
        np.testing.assert_allclose(u[got], want_u, atol=1e-12)
        np.testing.assert_allclose(z[got], np.interp(want_u, cols, row), atol=1e-12)
        assert np.all(v[got] == offset[k])
        pos += sizes[k]
    assert pos == len(u)


def test_finishing_closing_and_its_argmin_against_the_brute_envelope():
    from tests.test_toolpath import brute_cl, brute_envelope
    from zwcore.toolpath._scallop import _best_positions, finishing_closing
    part = wavy_part(41, 0.25, 5)
    tool = Tool("B", "ball", 2.0, 10.0)
    cl = brute_cl(part, tool)
    best = finishing_closing(part, tool, cl)
    np.testing.assert_allclose(best, brute_envelope(cl, part, tool), atol=1e-12)
    # the argmin position leaves exactly that over its node
    rng = np.random.default_rng(1)
    i, k = rng.integers(0, 41, 50), rng.integers(0, 41, 50)
    ci, ck = _best_positions(part, tool, cl, i, k)
    d2 = ((ci - i) * part.dy) ** 2 + ((ck - k) * part.dx) ** 2
    left = cl[ci, ck] + tool.radius - np.sqrt(tool.radius ** 2 - d2)
    np.testing.assert_allclose(left, best[i, k], atol=1e-12)


RUSHMORE = Path(__file__).resolve().parents[2] / "shared" / "data" / "mount_rush_zmap_0.1mm.npy"


@pytest.mark.skipif(not RUSHMORE.exists(), reason="shared data not available")
def test_mount_rushmore_crop_program_read_back_and_simulated_never_gouges():
    # a 12.8 x 25.6 mm window of the face at 0.1 mm, planned as a part of its own: the
    # program's own text read back and simulated at the input resolution
    z = np.load(RUSHMORE).astype(np.float64)[150:279, 300:557]
    part = ZMap(z, 0.0, 0.0, 0.1, 0.1)
    plan = plan_scanline(part)
    tp = scanline_toolpaths(part, plan)
    chk = tp.check
    assert chk is not None
    assert chk.gouge <= 1e-9 and chk.below_part_moves == 0 and chk.rapid_in_material == 0.0
    prog = parse_program(tp.program)
    assert prog.ended and prog.arc_radius_mismatch == 0.0
    # every tool of the plan runs, in the plan's order, and its stretch's stock ends above
    # the part everywhere
    assert len(chk.stages) == len({s.tool.id for s in plan.stages})
    assert np.all(chk.machined >= part.z - 1e-9)


@pytest.mark.parametrize("coords", [
    (1.03, 1.03, 0.44, 1.03, 1.03, 1.03),  # vertical, a row exactly R = 1.03 below the tip
    (1.016, 0.52375, 0.52375, -3.75e-200, 0.52375, -3.75e-200),
    (0.9153, 0.9153, 2.3698, 3.0, 1.98886, 0.9153)])
def test_sweep_at_rows_exactly_a_radius_away(coords):
    # with fused multiply-adds R^2 - d^2 came out just below 0 there: a NaN column bound
    # made a range wrap around (a crash); now the nodes are the sampled envelope's
    from tests.test_toolpath import sampled_envelope
    frame = GridFrame(-4.0, -4.0, 0.25, 0.25, (33, 33))
    p0, p1 = np.array(coords[:3]), np.array(coords[3:])
    r = float(coords[1]) if coords[1] > 0.3 else 0.5237533164272623
    for ball in (True, False):
        stock = np.full(frame.shape, 100.0)
        sweep_moves(frame, p0[None], p1[None], r, ball, stock)
        oracle = sampled_envelope(frame, p0, p1, r, ball)
        hit = np.isfinite(oracle)
        assert np.all(stock[hit] <= oracle[hit] + 1e-9)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_merged_stretches_cover_the_same_union_disjointly(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 60))
    off = rng.integers(0, 6, n) * 0.25
    a = np.round(rng.uniform(0, 10, n), 1)
    b = a + np.round(rng.uniform(0.1, 4, n), 1)
    dup = rng.random(n) < 0.3  # the same stretch given twice
    off, a, b = np.r_[off, off[dup]], np.r_[a, a[dup]], np.r_[b, b[dup]]
    mo, ma, mb = merge_stretches(off, a, b)
    u = np.arange(0, 15, 0.05) + 0.025  # sample points between the 0.1 mm ends
    for o in np.unique(off):
        want = ((u[:, None] >= a[off == o]) & (u[:, None] <= b[off == o])).any(1)
        got_ab = np.sort(np.column_stack([ma[mo == o], mb[mo == o]]), axis=0)
        got = ((u[:, None] >= got_ab[:, 0]) & (u[:, None] <= got_ab[:, 1])).any(1)
        np.testing.assert_array_equal(got, want)
        assert np.all(got_ab[1:, 0] > got_ab[:-1, 1])  # disjoint, not touching
    # offsets in order, every other offset's stretches backwards
    assert np.all(np.diff(mo) >= 0)
    ranks = np.searchsorted(np.unique(mo), mo)
    for r in np.unique(ranks):
        starts = ma[ranks == r]
        assert np.all(np.diff(starts) > 0) if r % 2 == 0 else np.all(np.diff(starts) < 0)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_line_heights_at_the_nodes_are_numpy_interp(seed):
    from zwcore.toolpath._scan_links import _along

    rng = np.random.default_rng(seed)
    m = int(rng.integers(1, 30))
    u = np.sort(rng.uniform(-1, 11, m))
    u[rng.random(m) < 0.1] = 5.0  # some repeated u (a vertical step)
    u.sort()
    z = rng.normal(size=m)
    out = np.empty(101)
    _along(u, z, 0.1, out)
    want = np.interp(np.arange(101) * 0.1, u, z)
    steps = np.isin(np.round(np.arange(101) * 0.1, 9), u[np.r_[np.diff(u) == 0, False]])
    np.testing.assert_allclose(out[~steps], want[~steps], atol=1e-12)
    # at a vertical step any of its heights is a height the tip passes there
    assert all(np.isclose(z[u == 5.0], o).any() for o in out[steps])
