"""Tool choice by simulated reach and rest finishing by region (issue 11, parts 2 and 3).

The reach kernels are checked against a brute-force nodal closing written here
(numpy, every node offset of the ball), the known answers of the issue against
geometry (where a ball's region may lie) and that brute force.
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from scipy import ndimage

from service.schemas.plans import ScanlinePlanResult
from tests.test_scanline_stock import _resimulate
from tests.test_service_mrr import grid_array
from zwcore.grid.tools import Tool, default_tools
from zwcore.grid.zmap import ZMap
from zwcore.scanline._reach import ball_reach
from zwcore.scanline.planner import plan_scanline
from zwcore.sim import (
    drop_cutter,
    envelope,
    nodal_closing,
    nodal_drop_cutter,
    refine_rest,
)

BALLS = default_tools("ball")


def brute_closing(z: np.ndarray, radius: float, dx: float, dy: float,
                  pad: bool = False) -> np.ndarray:
    """Nodal closing by every node offset: CL at every position (beyond the grid too, over
    the edge heights continued, when ``pad``), then the least ball over each node."""
    ny, nx = z.shape
    # one offset more than the footprint each way, the distance test below decides: ``//``
    # alone would drop the nodes at exactly R (1.0 // 0.2 == 4.0), which are in the ball
    ra, rb = int(radius // dy) + 1, int(radius // dx) + 1
    pa, pb = (ra + 1, rb + 1) if pad else (0, 0)
    zp = np.pad(z, ((pa, pa), (pb, pb)), mode="edge")
    my, mx = zp.shape
    offsets = [(a, b, radius - math.sqrt(max(radius**2 - (a * dy) ** 2 - (b * dx) ** 2, 0.0)))
               for a in range(-ra, ra + 1) for b in range(-rb, rb + 1)
               if (a * dy) ** 2 + (b * dx) ** 2 <= radius**2]
    big = np.full((my + 2 * ra, mx + 2 * rb), -np.inf)
    big[ra:ra + my, rb:rb + mx] = zp
    cl = np.full((my, mx), -np.inf)
    for a, b, h in offsets:
        cl = np.maximum(cl, big[ra + a:ra + a + my, rb + b:rb + b + mx] - h)
    big = np.full((my + 2 * ra, mx + 2 * rb), np.inf)
    big[ra:ra + my, rb:rb + mx] = cl
    out = np.full((my, mx), np.inf)
    for a, b, h in offsets:
        out = np.minimum(out, big[ra + a:ra + a + my, rb + b:rb + b + mx] + h)
    return out[pa:pa + ny, pb:pb + nx]


# --------------------------------------------------------------------------
# Kernels
# --------------------------------------------------------------------------


@settings(max_examples=60, deadline=None)
@given(z=hnp.arrays(np.float64, st.tuples(st.integers(1, 24), st.integers(1, 24)),
                    elements=st.floats(-20, 20, width=64)),
       dx=st.floats(0.05, 1.0), dy=st.floats(0.05, 1.0), radius=st.floats(0.01, 6.0))
def test_nodal_closing_is_the_brute_force_one(z: np.ndarray, dx: float, dy: float,
                                              radius: float) -> None:
    # Both paths: a plain scan for small balls, branch and bound for large footprints.
    cl, contact = nodal_drop_cutter(z, radius, dx, dy)
    out = nodal_closing(z, cl, radius, dx, dy, np.ones(z.shape, dtype=bool))
    ref = brute_closing(z, radius, dx, dy)
    np.testing.assert_allclose(out, ref, rtol=0, atol=1e-9)
    # the contact node is one the ball at its CL touches
    _ny, nx = z.shape
    ci, ck = np.divmod(contact, nx)
    ii, kk = np.indices(z.shape)
    d = np.hypot((ci - ii) * dy, (ck - kk) * dx)
    assert (d <= radius * (1 + 1e-12)).all()
    touch = z[ci, ck] - (radius - np.sqrt(np.maximum(radius**2 - d**2, 0.0)))
    np.testing.assert_allclose(touch, cl, rtol=0, atol=1e-9)


def subnode_rest(z: np.ndarray, radius: float, h: float, split: int = 4) -> np.ndarray:
    """Rest with ball positions on a ``split`` times finer lattice than the nodes (CL
    against the nodes), edge heights continued outwards: node cusps shrink ``split²``-fold."""
    ny, nx = z.shape
    r = int(radius // h) + 2
    zp = np.pad(z, r + 1, mode="edge")
    big = np.full((zp.shape[0] + 2 * r, zp.shape[1] + 2 * r), -np.inf)
    big[r:-r, r:-r] = zp
    my, mx = zp.shape
    out = np.full(z.shape, np.inf)
    for u in range(split):
        for v in range(split):
            fu, fv = u / split, v / split
            cl = np.full((my, mx), -np.inf)  # positions at node + (fu, fv) cells
            for a in range(-r, r + 1):
                for b in range(-r, r + 1):
                    d2 = ((a - fu) * h) ** 2 + ((b - fv) * h) ** 2
                    if d2 <= radius**2:
                        hh = radius - math.sqrt(radius**2 - d2)
                        cl = np.maximum(cl, big[r + a:r + a + my, r + b:r + b + mx] - hh)
            cp = np.full((my + 2 * r, mx + 2 * r), np.inf)
            cp[r:-r, r:-r] = cl
            for a in range(-r, r + 1):  # position (p - a, p - b) + (fu, fv)
                for b in range(-r, r + 1):
                    d2 = ((a - fu) * h) ** 2 + ((b - fv) * h) ** 2
                    if d2 <= radius**2:
                        hh = radius - math.sqrt(radius**2 - d2)
                        sl = cp[r - a:r - a + my, r - b:r - b + mx] + hh
                        out = np.minimum(out, sl[r + 1:r + 1 + ny, r + 1:r + 1 + nx])
    return np.maximum(out - z, 0.0)


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), radius=st.floats(0.3, 1.2), step=st.booleans())
def test_reach_band_misses_no_rest(seed: int, radius: float, step: bool) -> None:
    # Smooth bumps and valleys (and a step): outside the band around nodes sharper than
    # the ball, balls between the nodes leave at most the tolerance; inside it the reach
    # is the node-position closing, lowered only by balls between nodes (never below 0).
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:30, 0:30] * 0.2
    z = np.zeros_like(x)
    for _ in range(4):
        cx, cy, w = rng.uniform(0, 6, 3)
        z += rng.uniform(-3, 3) * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (0.5 + w))
    if step:
        z += np.where(x > rng.uniform(2, 4), rng.uniform(-4, 4), 0.0)
    tol = 0.01
    got = ball_reach(z, 0.2, 0.2, radius, tol)
    ref = subnode_rest(z, radius, 0.2)
    # (the grid's edge rows: heights continued flat outwards make a kink that is not
    # the part's; the band leaves them out)
    inner = np.zeros(z.shape, dtype=bool)
    e = int(radius // 0.2) + 1
    inner[e:-e, e:-e] = True
    assert (ref[~got.band & inner] <= tol).all()
    nodes = np.maximum(brute_closing(z, radius, 0.2, 0.2, pad=True) - z, 0.0)
    assert (got.rest >= 0.0).all()
    assert (got.rest <= nodes + 1e-9).all()
    low = nodes <= tol  # not refined there: the closing itself, to the search's stop
    np.testing.assert_allclose(got.rest[low & got.band], nodes[low & got.band],
                               atol=1e-3 * tol)


def test_refined_rest_is_reached_by_a_ball_between_nodes() -> None:
    # A ball of R 3 in a bowl of R 3.5: node positions leave cusps of about 0.1 mm
    # (contacts spread by 3.5 / 0.5); the ball along each node's normal reaches it.
    h = 0.4
    x = np.arange(-2.0, 2.0 + 1e-9, h)
    xx, yy = np.meshgrid(x, x)
    z = 3.5 - np.sqrt(3.5**2 - xx**2 - yy**2)
    rest = np.maximum(brute_closing(z, 3.0, h, h, pad=True) - z, 0.0)
    assert rest.max() > 0.05
    refined = refine_rest(z, h, h, 3.0, rest.copy(), rest > 0.0, 0.01)
    assert (refined <= rest).all() and (refined >= 0.0).all()
    assert refined.max() < 0.01


# --------------------------------------------------------------------------
# Known answers
# --------------------------------------------------------------------------


def _pocket() -> ZMap:
    x = (np.arange(129) - 64) * 0.25
    xx, yy = np.meshgrid(x, x)
    r = np.hypot(xx, yy)
    return ZMap(np.where(r < 8.0, 8.0 - np.sqrt(np.maximum(64.0 - r * r, 0.0)), 8.0),
                dx=0.25, dy=0.25)


def _finishing(plan: object) -> list:
    # one entry per finishing ball (its first pass; more follow where its flutes need them)
    return [s for s in plan.stages  # type: ignore[attr-defined]
            if s.level == plan.depth and s.pass_index == 1]  # type: ignore[attr-defined]


def test_r8_pocket_d16_main_and_a_smaller_ball_where_it_is_held_up() -> None:
    """On the bilinear z-map of the R 8 pocket the rim chords hold the Ø16 ball about 0.5
    mm above the floor (docs/simulation.md), although its nodal closing is the part: Ø16
    stays the main ball, a smaller one machines only around the pocket where the
    simulated stock shows Ø16's rest, and what no ball reaches is reported as left."""
    zmap = _pocket()
    assert (brute_closing(zmap.z, 8.0, 0.25, 0.25, pad=True) - zmap.z).max() < 1e-9
    plan = plan_scanline(zmap)
    assert plan.checks.ok
    fin = _finishing(plan)
    assert fin[0].tool.id == "BEM-D16" and fin[0].region is None
    d16 = [s for s in plan.stages if s.tool.id == "BEM-D16"][-1]
    assert d16.sim_left_over_part_max >= 0.4  # held up by the rim chords
    assert len(fin) >= 2
    x = (np.arange(129) - 64) * 0.25
    r = np.hypot(*np.meshgrid(x, x))
    for s in fin[1:]:
        assert s.region is not None and s.region.any()
        # within_distance covers the exact growth, widened by up to two block diagonals
        # (blocks of R/4: 2 * sqrt(2) * R / 4) and the seed's rim cell
        assert r[s.region].max() <= 8.25 + s.tool.radius * (1 + 2**0.5 / 2) + 0.5
        assert s.region_area_fraction < 0.7
    # the plan reports what its last pass leaves
    assert plan.reach is not None
    left = plan.stages[-1].sim_left_over_part_max  # (0 reported when within tolerance)
    assert plan.reach.unreachable_max_height == pytest.approx(left if left > 0.01 else 0.0)
    if plan.reach.unreachable_area > 0.0:
        assert any("no tool reaches" in n for n in plan.notes)


def _fillet(wall_deg: float, r: float = 3.0, h: float = 0.2) -> tuple[ZMap, float, float]:
    al = math.radians(wall_deg)
    x = np.arange(0.0, 60.0 + 1e-9, h)
    x0 = 20.0
    xt = x0 + r * math.sin(al)
    zt = r - r * math.cos(al)
    prof = np.where(x < x0, 0.0,
                    np.where(x < xt, r - np.sqrt(np.maximum(r * r - (x - x0) ** 2, 0.0)),
                             zt + math.tan(al) * (x - xt)))
    prof = np.minimum(prof, 25.0)
    return ZMap(np.tile(prof, (round(24.0 / h) + 1, 1)), dx=h, dy=h), x0, xt


def test_fillet_gets_a_small_ball_only_along_it() -> None:
    zmap, x0, xt = _fillet(45.0)
    plan = plan_scanline(zmap)
    assert plan.checks.ok
    fin = _finishing(plan)
    main = fin[0]
    assert main.region is None and main.tool.radius > 3.0  # a larger ball everywhere else
    assert fin[-1].tool.radius <= 3.0 and fin[-1].region is not None
    x = np.arange(zmap.shape[1]) * zmap.dx
    for prev, s in itertools.pairwise(fin):
        assert s.region is not None and s.region.any()
        cols = x[s.region.any(axis=0)]
        # the previous ball leaves material only within its radius of the fillet (it
        # touches the floor and the wall beyond), and the region grows by this ball's
        # (within_distance: plus up to two blocks of R/4)
        reach = prev.tool.radius + s.tool.radius * (1 + 2**0.5 / 2) + 2 * zmap.dx
        assert cols.min() >= x0 - reach and cols.max() <= xt + reach
        assert s.region_area_fraction < 0.5
        assert s.estimated_cut_length is not None and s.estimated_cut_length > 0
    # the last ball fits the fillet (brute force): nothing is left there for want of a
    # smaller ball; what the passes leave is reported as it is
    last = fin[-1].tool.radius
    rest = brute_closing(zmap.z, last, zmap.dx, zmap.dy, pad=True) - zmap.z
    # node-position cusps only (measured: R 3 0.003, R 2.5 0.021, R 2 0.008, R 1.5 0.013 mm:
    # a smaller ball would not leave less; the time ranking may pick any R <= 3)
    assert rest.max() <= 0.025
    assert plan.reach is not None
    left = plan.stages[-1].sim_left_over_part_max  # (0 reported when within tolerance)
    assert plan.reach.unreachable_max_height == pytest.approx(left if left > 0.01 else 0.0)
    assert plan.reach.needed_radius == math.inf  # no corner sharper than the last ball


@pytest.mark.parametrize("tools", [None, [Tool("A", "ball", 6.0, 12.0),
                                          Tool("B", "ball", 2.0, 4.0)]])
def test_convex_dome_is_finished_by_the_largest_ball_alone(tools: list[Tool] | None) -> None:
    h = 0.25
    x = np.arange(-30.0, 30.0 + 1e-9, h)
    xx, yy = np.meshgrid(x, x)
    plan = plan_scanline(ZMap(np.sqrt(50.0**2 - xx**2 - yy**2), dx=h, dy=h), tools,
                         tolerance=0.005)
    largest = (BALLS if tools is None else tools)[0]
    assert plan.reach is not None and plan.reach.finishing_tools == (largest.id,)
    assert all(s.region is None for s in plan.stages)
    assert plan.reach.finishing_cut_length < plan.reach.smallest_ball_cut_length


#: The rectangular pocket's node rows and columns: 30 x 20 mm, 5 mm deep, sharp edges.
_RECT = (40, 120, 40, 160)


def _rect_pocket(h: float = 0.25) -> ZMap:
    r0, r1, c0, c1 = _RECT
    z = np.zeros((161, 201))
    z[r0:r1 + 1, c0:c1 + 1] = -5.0
    return ZMap(z, dx=h, dy=h)


def test_rectangular_pocket_gets_the_smallest_ball_only_in_its_corners() -> None:
    h = 0.25
    r0, r1, c0, c1 = _RECT
    zmap = _rect_pocket(h)
    plan = plan_scanline(zmap)
    assert plan.checks.ok
    fin = _finishing(plan)
    assert fin[0].tool.radius > fin[-1].tool.radius
    assert fin[-1].tool.id == BALLS[-1].id
    # distance of every node to the pocket's floor-wall edges (the concave corners)
    ii, kk = np.indices(zmap.shape)
    inside_r = np.clip(ii, r0, r1)
    inside_c = np.clip(kk, c0, c1)
    to_wall = np.minimum.reduce([np.abs(ii - r0), np.abs(ii - r1), np.abs(kk - c0),
                                 np.abs(kk - c1)]) * h
    outside = np.hypot(ii - inside_r, kk - inside_c) * h
    dist = np.where(outside > 0, outside, to_wall)
    prev, last = fin[-2], fin[-1]
    assert last.region is not None
    reach = prev.tool.radius + last.tool.radius + 2 * h
    assert dist[last.region].max() <= reach
    middle = dist > reach  # the pocket's floor away from its edges, and the plate
    assert middle[r0:r1, c0:c1].any() and not last.region[middle].any()
    # a sharp corner is reached by no ball: reported, with the ball it would need
    assert plan.reach is not None and plan.reach.unreachable_area > 0
    assert any("no tool reaches" in n for n in plan.notes)


def _brute_envelope(cl: np.ndarray, positions: np.ndarray, radius: float, dx: float,
                    dy: float) -> np.ndarray:
    """What balls at the given positions only leave at every node: ``min over positions c
    within R of cl(c) + h(|p - c|)`` (+inf where none), by every node offset."""
    ny, nx = cl.shape
    ra, rb = int(radius // dy) + 1, int(radius // dx) + 1
    big = np.full((ny + 2 * ra, nx + 2 * rb), np.inf)
    big[ra:ra + ny, rb:rb + nx] = np.where(positions, cl, np.inf)
    out = np.full((ny, nx), np.inf)
    for a in range(-ra, ra + 1):
        for b in range(-rb, rb + 1):
            d2 = (a * dy) ** 2 + (b * dx) ** 2
            if d2 <= radius**2:
                h = radius - math.sqrt(radius**2 - d2)
                out = np.minimum(out, big[ra + a:ra + a + ny, rb + b:rb + b + nx] + h)
    return out


def test_rest_regions_cover_where_the_passes_before_leave_material() -> None:
    """Each rest ball's region holds, for every node where the brute-force re-simulation of
    the plan's passes before it leaves more than the tolerance and this ball's closing
    (zwcore.sim, bilinear, on the whole grid) is lower by more than it, positions that cut
    it as deep as every position does: the ball's envelope over the region's positions
    alone equals its envelope over every position there (both brute force, from its
    drop-cutter CL). Positions whose
    ball cuts none of that material are left out: the region is smaller than the nodes
    within the ball's radius of those nodes."""
    # The test needs a rest ball after a main ball. On the r = 3 fillet Ø4 fits the fillet
    # and alone is the fastest program (14.3 min, Ø8 > Ø2 21.9), so the ranking takes it;
    # with r = 1.5 no ball but Ø2 fits, and Ø4 > Ø2 is the fastest program of the
    # library's chains (15.0 min; Ø2 alone 17.7, Ø8 > Ø2 21.8: scanline_toolpaths, no
    # verification), the chain the ranking takes.
    zmap, _, _ = _fillet(60.0, r=1.5)
    plan = plan_scanline(zmap, [Tool("A", "ball", 8.0, 16.0), Tool("B", "ball", 4.0, 8.0),
                                Tool("C", "ball", 2.0, 4.0)])
    fin = _finishing(plan)
    assert len(fin) >= 2
    dx, dy = zmap.dx, zmap.dy
    for s in fin[1:]:
        n = plan.stages.index(s)
        before = dataclasses.replace(plan, stages=plan.stages[:n])
        final: list[np.ndarray] = []
        _resimulate(zmap, before, final)
        left = final[0] - zmap.z
        # the plan's own drop-cutter (the per-cell bound where its tolerance wants it)
        cl = drop_cutter(zmap, s.tool, "bilinear", cell_bound=plan.cell_bound)
        mine = envelope(cl, s.tool, dx, dy, "bilinear") - zmap.z
        tol = plan.scallop_tolerance + 1e-6
        gain = (left > tol) & (left - mine > tol)
        assert s.region is not None and gain.any()
        everywhere = _brute_envelope(cl, np.ones(cl.shape, dtype=bool), s.tool.radius, dx, dy)
        region_only = _brute_envelope(cl, s.region, s.tool.radius, dx, dy)
        np.testing.assert_array_equal(region_only[gain], everywhere[gain])
        r = s.tool.radius
        within = ndimage.distance_transform_edt(~gain, sampling=(dy, dx)) <= r
        assert s.region.sum() < within.sum()


# --------------------------------------------------------------------------
# Over HTTP
# --------------------------------------------------------------------------


def test_plan_response_reports_regions(client) -> None:  # type: ignore[no-untyped-def]
    zmap, _x0, _xt = _fillet(45.0, h=0.25)
    grid = {"x0": 5.0, "y0": -2.0, "dx": 0.25, "dy": 0.25, "z": zmap.z.tolist()}
    r = client.post("/v1/plans/scanline", json={"grid": grid, "include_models": True})
    assert r.status_code == 200, r.text
    body = r.json()
    plan = ScanlinePlanResult.model_validate(body)
    assert plan.reach is not None
    assert plan.reach.finishing_tools[-1] == plan.tool_sequence[-1]
    # finishing the whole part with the smallest ball is one of the chains the choice
    # weighs, so the chosen one is never longer
    assert plan.reach.finishing_cut_length <= plan.reach.smallest_ball_cut_length * (1 + 1e-12)
    assert plan.reach.cut_length_factor >= 1.0 - 1e-12
    regions = [s for s in plan.stages if s.region is not None]
    assert regions
    for s in plan.stages:
        if s.region is None:
            assert s.region_area_fraction == 1.0 and s.region_boxes == []
            continue
        mask = grid_array(s.region.model_dump())
        assert s.model is not None and mask.shape == (s.model.ny, s.model.nx)
        assert set(np.unique(mask)) <= {0.0, 1.0}
        assert s.region_area_fraction == pytest.approx(mask.mean())
        assert sum(b.area for b in s.region_boxes) == pytest.approx(
            mask.sum() * 0.25 * 0.25)
        ys, xs = np.nonzero(mask)
        assert min(b.x_min for b in s.region_boxes) == pytest.approx(5.0 + xs.min() * 0.25)
        assert max(b.y_max for b in s.region_boxes) == pytest.approx(-2.0 + ys.max() * 0.25)
    r = client.post("/v1/plans/scanline", json={"grid": grid})
    assert all(s["region"] is None for s in r.json()["stages"])


def test_r8_pocket_program_end_to_end_with_rest_regions() -> None:
    """Plan with tool paths on the R 8 pocket, the program parsed by the line-by-line NC
    reader and simulated: no gouge; wherever the brute-force re-simulation of the plan
    leaves the part within the tolerance, so does the program; and the rest balls' cutting
    moves stay inside their regions (grown by a cell: a stretch is kept when any node
    around it is in the region)."""
    from tests.nc_modal_reader import read_program
    from tests.test_toolpath import brute_cl, hemisphere_pocket
    from zwcore.toolpath import scanline_toolpaths

    part = hemisphere_pocket()
    plan = plan_scanline(part, BALLS, tolerance=0.01)
    fin = _finishing(plan)
    assert fin[0].tool.id == "BEM-D16" and len(fin) >= 2
    tp = scanline_toolpaths(part, plan, brute_cl)  # each stage's region by default
    chk = tp.check
    assert chk is not None
    assert chk.gouge <= 1e-9 and chk.below_part_moves == 0 and chk.rapid_in_material == 0.0
    final: list[np.ndarray] = []
    _resimulate(part, plan, final)
    reached = final[0] - part.z <= plan.scallop_tolerance
    assert reached.mean() > 0.7  # all but the pocket's steep rim ring (reported)
    assert plan.reach is not None
    assert float((~reached).sum()) * part.dx * part.dy <= plan.reach.unreachable_area + 1e-9
    left = chk.machined - part.z
    assert left[reached].max() <= plan.tolerance + 1e-6
    prog = read_program(tp.program)
    for path, stage in zip(tp.stages, plan.stages, strict=True):
        if stage.region is None:
            continue
        cutting = (prog.tool == path.cutting.tool_number) & (prog.motion >= 1)
        assert cutting.any()
        grown = ndimage.binary_dilation(stage.region, np.ones((3, 3), dtype=bool))
        for ends in (prog.start[cutting], prog.end[cutting]):
            inside = ends[:, 2] < plan.stock_top  # in material, not the approach
            col = np.clip(np.rint(ends[inside, 0] / part.dx).astype(int), 0, part.shape[1] - 1)
            row = np.clip(np.rint(ends[inside, 1] / part.dy).astype(int), 0, part.shape[0] - 1)
            assert grown[row, col].all(), stage.tool.id


def test_read_only_grids_are_accepted() -> None:
    # A stored z-map (grid_task) arrives read-only; the compiled kernels take copies.
    zmap, _, _ = _fillet(45.0, h=0.5)
    z = zmap.z.copy()
    z.flags.writeable = False
    cl, _ = nodal_drop_cutter(z, 2.0, 0.5, 0.5)
    cl.flags.writeable = False
    out = nodal_closing(z, cl, 2.0, 0.5, 0.5, np.ones(z.shape, dtype=bool))
    np.testing.assert_allclose(out, brute_closing(zmap.z, 2.0, 0.5, 0.5), atol=1e-9)
    assert plan_scanline(ZMap(z, dx=0.5, dy=0.5)).checks.ok


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), small=st.sampled_from([0.5, 1.0, 1.5]),
       left=st.floats(0.0, 2.0))
def test_rest_region_stays_near_the_material_left(seed: int, small: float, left: float) -> None:
    """A rest ball's region lies within its (conservatively grown) radius of nodes where
    the stock stands more than the tolerance above the part, and is empty when nothing
    is left (brute-force distances)."""
    from zwcore.scanline._rest import RestRegion, RestShared

    rng = np.random.default_rng(seed)
    n, h = 41, 0.25
    y, x = np.mgrid[0:n, 0:n] * h
    z = np.zeros((n, n))
    for _ in range(3):  # pits and grooves: concave detail for the balls
        cx, cy, r = rng.uniform(0, 10, 3)
        z -= rng.uniform(0.5, 3.0) * (np.hypot(x - cx, y - cy) < 0.5 + r / 3)
    part = ZMap(z, dx=h, dy=h)
    stock = z + left * (rng.random(z.shape) < 0.3)
    big, tool = Tool("big", "ball", 8.0, 16.0), Tool("s", "ball", 2 * small, 8.0)
    rule = RestRegion(part, tool, 0.01, RestShared([big]), last=True)
    region = rule(stock)
    above = np.argwhere(stock - z > 0.01) * h
    if above.size == 0:
        assert not region.any()
        return
    nodes = np.argwhere(region) * h
    if nodes.size:
        d = np.min(np.hypot(*(nodes[:, None, :] - above[None, :, :]).transpose(2, 0, 1)),
                   axis=1)
        assert d.max() <= small * (1 + 2**0.5 / 2) + 2 * h + 1e-9


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), small=st.sampled_from([0.5, 1.0, 1.5]),
       left=st.floats(0.05, 2.0))
def test_rest_region_work_bounds_only_grow_it(seed: int, small: float, left: float) -> None:
    """The rest rule's cost cuts never shrink a region: closings on clustered windows give
    the same region as on one box over the seed; this ball's closing on its tight band
    only (``MINE_WORK`` 0) or not at all (``REST_CLOSING_WORK`` 0 too) and the cutting
    test skipped on its sampled bound (``CUT_WORK`` 0) give supersets of it."""
    from zwcore.scanline import _rest
    from zwcore.scanline._rest import RestRegion, RestShared

    rng = np.random.default_rng(seed)
    n, h = 61, 0.25
    y, x = np.mgrid[0:n, 0:n] * h
    z = 0.02 * (x - 7.5) ** 2
    for _ in range(4):  # separate pits and grooves: several windows
        cx, cy, r = rng.uniform(0, 15, 3)
        z -= rng.uniform(0.5, 3.0) * (np.hypot(x - cx, y - cy) < 0.5 + r / 3)
    part = ZMap(z, dx=h, dy=h)
    big, tool = Tool("big", "ball", 6.0, 16.0), Tool("s", "ball", 2 * small, 8.0)
    # a stock the big ball could have left: never below its closing (as the rule's, over
    # the part continued by odd reflection), so the stock bounds that closing's rest
    g = math.ceil(2 * big.radius / h) + 2
    padded = ZMap(np.pad(z, g, mode="reflect", reflect_type="odd"), dx=h, dy=h)
    closed = envelope(drop_cutter(padded, big, "bilinear"), big, h, h, "bilinear")[g:-g, g:-g]
    stock = np.maximum(z + left * (rng.random(z.shape) < 0.4), closed)

    def region(**bounds: int) -> np.ndarray:
        with pytest.MonkeyPatch.context() as mp:
            for name, value in bounds.items():
                mp.setattr(_rest, name, value)
            return RestRegion(part, tool, 0.01, RestShared([big]), last=True)(stock)

    exact = region()
    np.testing.assert_array_equal(region(MAX_WINDOWS=0), exact)
    for bounds in ({"MINE_WORK": 0}, {"MINE_WORK": 0, "REST_CLOSING_WORK": 0},
                   {"CUT_WORK": 0}):
        wider = region(**bounds)
        assert (wider | ~exact).all(), bounds


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), ny=st.integers(1, 30), nx=st.integers(1, 30),
       density=st.sampled_from([0.005, 0.05, 0.3]),
       sy=st.sampled_from([0.1, 0.25, 1 / 3]), sx=st.sampled_from([0.1, 0.25, 1 / 3]),
       reach=st.one_of(st.sampled_from([0.0, 0.1, 0.25, 0.5]), st.floats(0.0, 4.0)))
def test_near_kernel_is_the_brute_distance_test(seed: int, ny: int, nx: int, density: float,
                                                sy: float, sx: float, reach: float) -> None:
    """``_near_kernel`` (largest gap per row offset, integer compares) against every seed
    node tried by the same rounded test, ``sqrt((dk sx)² + (di sy)²) <= reach``: equal,
    ties on the reach included."""
    from zwcore.scanline._reach import _near_kernel

    rng = np.random.default_rng(seed)
    mask = rng.random((ny, nx)) < density
    out = np.empty((ny, nx), dtype=bool)
    _near_kernel(mask, float(sy), float(sx), float(reach), out)
    seeds = np.argwhere(mask)
    brute = np.zeros((ny, nx), dtype=bool)
    for i in range(ny):
        for k in range(nx):
            brute[i, k] = any(math.sqrt((abs(k - c) * sx) ** 2 + ((a - i) * sy) ** 2) <= reach
                              for a, c in seeds)
    assert np.array_equal(out, brute)
