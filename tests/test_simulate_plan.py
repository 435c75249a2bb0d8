"""``POST /v1/simulate`` with a scan-line plan's task id: the plan simulated again on its part.

Judged against independent computations: the plan's NC program read with the tests' own
regex reader (tests/nc_modal_reader.py) and every feed move swept by brute force (the exact
lowest ball position over each node along the move, by golden-section search on its convex
height), and the plan's passes re-simulated in plain numpy from what the plan reports
(its scan lines, models and position spacing).
"""

from __future__ import annotations

import math
import time

import numpy as np
import orjson
import pytest
from fastapi.testclient import TestClient
from hypothesis import given, settings

from service.schemas.simulate import SimulateResult
from service.toolpaths import plan_inputs_key
from tests.conftest import make_client
from tests.nc_modal_reader import read_program
from tests.test_scanline_stock import _cl_model, _parts, _positions
from tests.test_service_errors import assert_problem
from tests.test_service_mrr import grid_array, rows_grid
from zwcore import Tool, ZMap
from zwcore.errors import InvalidInputError
from zwcore.scanline import plan_scanline
from zwcore.scanline.replay import replay_passes
from zwcore.toolpath import scanline_toolpaths
from zwcore.toolpath.verify_plan import replay_program

DX = 0.25


def part_heights(n: int = 33) -> np.ndarray:
    """A bump and a dimple on a gentle slope (several stages with the default balls)."""
    y, x = np.mgrid[0:n, 0:n] * DX
    return (2.5 * np.exp(-((x - 5.0) ** 2 + (y - 4.0) ** 2) / 6.0)
            - 1.5 * np.exp(-((x - 2.5) ** 2 + (y - 5.5) ** 2) / 2.0) + 0.05 * x)


def _plan(client: TestClient, z: np.ndarray, toolpaths: bool) -> dict:
    r = client.post("/v1/plans/scanline", json={"grid": rows_grid(z, dx=DX, dy=DX),
                                                "tolerance": 0.05, "toolpaths": toolpaths})
    assert r.status_code == 200, r.text
    return r.json()


def _simulate(client: TestClient, z: np.ndarray, task_id: str, **extra: object):  # type: ignore[no-untyped-def]
    return client.post("/v1/simulate", json={"grid": rows_grid(z, dx=DX, dy=DX),
                                             "task_id": task_id, **extra})


# ---------------------------------------------------------------- oracles (tests only)

def _capsule_floor(q: np.ndarray, p0: np.ndarray, p1: np.ndarray, r: float) -> np.ndarray:
    """Lowest tip height of a ball of radius ``r`` whose tip runs from ``p0`` to ``p1`` over
    the nodes ``q`` ((m, 2)); ``inf`` where the ball never covers a node. The height
    ``z(t) + r - sqrt(r² - d(t)²)`` is convex in ``t`` (a convex increasing profile of a
    convex distance, plus a linear term): golden-section search on the interval where the
    node is within ``r``."""
    u = p1[:2] - p0[:2]
    w = q - p0[:2]
    a, b, c = u @ u, w @ u, (w * w).sum(axis=1) - r * r
    if a == 0.0:
        lo, hi = np.where(c <= 0, 0.0, 1.0), np.where(c <= 0, 1.0, 0.0)
    else:
        disc = b * b - a * c
        root = np.sqrt(np.maximum(disc, 0.0))
        lo = np.where(disc >= 0, np.maximum((b - root) / a, 0.0), 1.0)
        hi = np.where(disc >= 0, np.minimum((b + root) / a, 1.0), 0.0)
    ok = lo <= hi

    def height(t: np.ndarray) -> np.ndarray:
        cx, cy = p0[0] + t * u[0], p0[1] + t * u[1]
        d2 = (q[:, 0] - cx) ** 2 + (q[:, 1] - cy) ** 2
        return p0[2] + t * (p1[2] - p0[2]) + r - np.sqrt(np.maximum(r * r - d2, 0.0))

    g = (math.sqrt(5.0) - 1.0) / 2.0
    x0, x1 = lo.copy(), np.where(ok, hi, lo)
    for _ in range(90):
        m1, m2 = x1 - g * (x1 - x0), x0 + g * (x1 - x0)
        left = height(m1) <= height(m2)
        x1 = np.where(left, m2, x1)
        x0 = np.where(left, x0, m1)
    best = np.minimum(np.minimum(height(x0), height(x1)),
                      np.minimum(height(np.where(ok, lo, 0.0)), height(np.where(ok, hi, 0.0))))
    # the ends of the interval are on the ball's rim only where they are not the segment's ends
    return np.where(ok, best, np.inf)


def _brute_program(text: str, radius_of: dict[int, float], z: np.ndarray,
                   stock_top: float) -> np.ndarray:
    """Every feed move of the program swept by brute force over a flat stock."""
    prog = read_program(text)
    assert not np.any(prog.motion >= 2), "scan-line programs are lines"
    ny, nx = z.shape
    yy, xx = np.mgrid[0:ny, 0:nx]
    nodes = np.stack([xx.ravel() * DX, yy.ravel() * DX], axis=1)
    out = np.full(z.size, stock_top)
    for k in np.flatnonzero(prog.motion == 1):
        p0, p1, r = prog.start[k], prog.end[k], radius_of[int(prog.tool[k])]
        if not np.isfinite(p0).all():
            continue
        near = ((nodes[:, 0] >= min(p0[0], p1[0]) - r) & (nodes[:, 0] <= max(p0[0], p1[0]) + r)
                & (nodes[:, 1] >= min(p0[1], p1[1]) - r) & (nodes[:, 1] <= max(p0[1], p1[1]) + r))
        idx = np.flatnonzero(near)
        out[idx] = np.minimum(out[idx], _capsule_floor(nodes[idx], p0, p1, r))
    return out.reshape(z.shape)


def _brute_passes(part: ZMap) -> tuple[np.ndarray, list[float]]:
    """The plan's passes re-simulated in numpy (as tests/test_scanline_stock.py specifies
    them): positions on the scan lines, CL = max(drop-cutter on the stage's target,
    brute-force drop against the part's nodes, highest stock within R minus the flute
    length), the ball's envelope at every node within R. Returns the stock after the last
    pass and each pass's largest stock left over the part."""
    plan = plan_scanline(part, tolerance=0.05)
    z = part.z
    ny, nx = z.shape
    stock = np.full(z.shape, plan.stock_top)
    targets = {(s.level, s.tool.id): s.model for s in plan.stages}
    left = []
    for s in plan.stages:
        assert s.sim_flute_rule_ok  # every pass ran with the flute lift
        r, flute = s.tool.radius, s.tool.flute_length
        x, y = _positions(s.lines, s.sim_position_spacing)
        if s.region is not None:  # a rest stage: positions whose nearest node is its
            my, mx = s.region.shape
            keep = s.region[np.clip(np.rint(y / s.spacing[1]).astype(int), 0, my - 1),
                            np.clip(np.rint(x / s.spacing[0]).astype(int), 0, mx - 1)]
            x, y = x[keep], y[keep]
        cl_target = _cl_model(s, targets[(s.level, s.tool.id)], x, y)
        a, b = math.ceil(r / DX) + 1, math.ceil(r / DX) + 1
        oy, ox = np.mgrid[-a:a + 1, -b:b + 1]
        before = stock.copy()
        rows = np.rint(y[:, None] / DX).astype(int) + oy.ravel()[None, :]
        cols = np.rint(x[:, None] / DX).astype(int) + ox.ravel()[None, :]
        d2 = (cols * DX - x[:, None]) ** 2 + (rows * DX - y[:, None]) ** 2
        inside = (d2 <= r * r) & (rows >= 0) & (rows < ny) & (cols >= 0) & (cols < nx)
        rows, cols = np.clip(rows, 0, ny - 1), np.clip(cols, 0, nx - 1)
        h = r - np.sqrt(np.maximum(r * r - d2, 0.0))
        cl = np.maximum(cl_target, np.where(inside, z[rows, cols] - h, -np.inf).max(axis=1))
        top = np.where(inside, before[rows, cols], -np.inf).max(axis=1)
        cl = np.maximum(cl, top - flute)
        np.minimum.at(stock, (rows.ravel(), cols.ravel()),
                      np.where(inside, cl[:, None] + h, np.inf).ravel())
        left.append(float((stock - z).max()))
    return stock, left


def _rounding(stock_top: float, z: np.ndarray) -> float:
    # zwcore.sim's float32 drop-cutter and envelope round up by a few 2**-22 of the span
    return 16.0 * 2.0 ** -22 * (stock_top - float(z.min()) + 1.0)


# ---------------------------------------------------------------- the plan, simulated again

def _plan_simulated(client: TestClient, z: np.ndarray, *, toolpaths: bool,
                    ) -> tuple[dict, SimulateResult, np.ndarray]:
    """A plan of ``z`` simulated by its task id: the plan, the result and the machined
    surface, which does not gouge the part (measured here)."""
    plan = _plan(client, z, toolpaths=toolpaths)
    r = _simulate(client, z, plan["task_id"])
    assert r.status_code == 200, r.text
    res = SimulateResult.model_validate(r.json())
    assert res.cl_source == ("plan_program" if toolpaths else "plan_passes")
    assert res.plan is not None and res.plan.task_id == plan["task_id"]
    machined = grid_array(r.json()["machined"])
    assert res.gouge == 0.0 and (machined - z).min() >= -1e-12
    return plan, res, machined


def test_a_plan_without_toolpaths_replays_its_passes(client: TestClient) -> None:
    z = part_heights()
    plan, res, machined = _plan_simulated(client, z, toolpaths=False)
    assert res.plan is not None and res.plan.source == "passes"
    assert res.tool is None and res.depth_of_cut is None
    # the machined surface is the numpy re-simulation's, to float rounding
    ref, left = _brute_passes(ZMap(z, dx=DX, dy=DX))
    tol = _rounding(plan["stock_top"], z)
    np.testing.assert_allclose(machined, ref, rtol=0, atol=tol)
    # one entry per pass, each within its flutes, its figures the reference's
    assert [s.stages for s in res.plan.stages] == [[i] for i in range(len(plan["stages"]))]
    for s, mine, stage in zip(res.plan.stages, left, plan["stages"], strict=True):
        assert s.depth_of_cut is not None and s.depth_of_cut.flute_length_ok
        assert s.depth_of_cut.max <= s.tool.flute_length
        assert s.left_over_part.max == pytest.approx(mine, abs=tol)
        assert s.gouge == 0.0 and s.tool.id == stage["tool"]["id"]
        # the planner's own figures: the same simulation, run again
        assert s.depth_of_cut.max == pytest.approx(stage["sim_max_depth_of_cut"], abs=tol)
        assert s.left_over_next.max == pytest.approx(stage["sim_left_over_next_max"], abs=tol)
    assert res.rest.max == pytest.approx(float((machined - z).max()), abs=1e-12)
    assert res.stock_top == plan["stock_top"]
    # rest area over the plan's tolerance unless the request gives one
    assert res.plan.tolerance == 0.05
    assert res.rest.area_fraction == pytest.approx(float(np.mean(machined - z > 0.05)))
    finer = SimulateResult.model_validate(_simulate(client, z, plan["task_id"],
                                                    tolerance=0.001).json())
    assert finer.rest.area_fraction == pytest.approx(float(np.mean(machined - z > 0.001)))
    # the same request again: the same task, from the store
    again = _simulate(client, z, plan["task_id"])
    assert again.headers["x-cache"] == "hit" and again.json()["task_id"] == res.task_id


def test_a_plan_with_toolpaths_simulates_its_program(client: TestClient) -> None:
    z = part_heights()
    plan, res, machined = _plan_simulated(client, z, toolpaths=True)
    assert res.plan is not None
    assert res.plan.source == "program" and res.plan.program_ended
    assert res.plan.rapid_in_material == 0.0 and res.plan.below_part_moves == 0
    # the program, read by the tests' own reader and swept by brute force
    text = client.get(f"/v1/tasks/{plan['task_id']}/program").text
    tools = {s["tool"]["id"]: s["tool"] for s in plan["stages"]}
    radius_of = {s["tool_number"]: tools[s["tool_id"]]["diameter"] / 2
                 for s in plan["toolpaths"]["stages"]}
    ref = _brute_program(text, radius_of, z, plan["stock_top"])
    np.testing.assert_allclose(machined, ref, rtol=0, atol=1e-7)
    # one entry per tool change, covering every pass once, in order
    covered = [i for s in res.plan.stages for i in s.stages]
    assert covered == list(range(len(plan["stages"])))
    assert [s.tool.id for s in res.plan.stages] == plan["tool_sequence"]
    last = res.plan.stages[-1]
    assert last.left_over_part.max == pytest.approx(float((ref - z).max()), abs=1e-7)
    assert last.left_over_next.max == last.left_over_part.max
    # the plan's own verification of the same program agrees
    ver = plan["toolpaths"]["verification"]
    assert res.rest.max == pytest.approx(ver["final_over_part_max"], abs=1e-9)
    # the program on another stock (a lower blank): the same brute force from that stock
    r = _simulate(client, z, plan["task_id"], stock_top=6.0)
    assert r.status_code == 200, r.text
    low = SimulateResult.model_validate(r.json())
    assert low.stock_top == 6.0 and low.task_id != res.task_id
    np.testing.assert_allclose(grid_array(r.json()["machined"]),
                               _brute_program(text, radius_of, z, 6.0), rtol=0, atol=1e-7)
    assert low.plan is not None
    assert low.plan.stages[0].removed_volume < res.plan.stages[0].removed_volume


# ---------------------------------------------------------------- bad input

def _put(client: TestClient, key: str, doc: dict) -> None:
    client.app.state.store.put(key, orjson.dumps(doc))  # type: ignore[attr-defined]


def test_bad_task_ids_and_combinations_name_the_field(client: TestClient) -> None:
    z = part_heights(17)
    grid = rows_grid(z, dx=DX, dy=DX)
    plan = _plan(client, z, toolpaths=False)["task_id"]
    assert_problem(_simulate(client, z, "0" * 64), 404, "task_id")
    assert_problem(_simulate(client, z, "xyz"), 422, "task_id")
    contour = client.post("/v1/plans/contour", json={"grid": grid})
    assert contour.status_code == 200, contour.text
    assert_problem(_simulate(client, z, contour.json()["task_id"]), 422, "task_id",
                   "not a scan-line plan")
    ball = {"kind": "ball", "diameter": 2.0, "flute_length": 4.0}
    sim = client.post("/v1/simulate", json={"grid": grid, "tool": ball})
    assert_problem(_simulate(client, z, sim.json()["task_id"]), 422, "task_id")
    cases = [
        ({"cl": rows_grid(z, dx=DX, dy=DX), "tool": ball}, "cl"),
        ({"cl": rows_grid(z, dx=DX, dy=DX)}, "cl"),
        ({"tool": ball}, "tool"),
        ({"interpolation": "cell"}, "interpolation"),
        ({"stock_top": 10.0}, "stock_top"),  # a plan without tool paths: its own stock
    ]
    for extra, field in cases:
        assert_problem(_simulate(client, z, plan, **extra), 422, field)
    # a CL grid without its tool, no task id
    assert_problem(client.post("/v1/simulate", json={"grid": grid, "cl": grid}), 422, "tool")
    # another part than the plan's: heights, or spacing
    assert_problem(_simulate(client, z + 0.001, plan), 422, "grid")
    other = client.post("/v1/simulate", json={"grid": rows_grid(z, dx=0.5, dy=0.5),
                                              "task_id": plan})
    assert_problem(other, 422, "grid")


def test_unfinished_failed_and_unusable_plans(client: TestClient) -> None:
    z = part_heights(17)
    store = client.app.state.store  # type: ignore[attr-defined]
    now = time.time()
    for status, code, digit in (("pending", 409, "a"), ("running", 409, "b"),
                                ("failed", 422, "d")):
        tid = digit * 64
        error = {"type": "about:blank", "title": "x", "status": 422, "detail": "bad"}
        doc = {"task_id": tid, "operation": "plan_scanline", "status": status,
               "progress": 0.0, "created": now, "updated": now,
               "error": error if status == "failed" else None}
        store.put_state(tid, orjson.dumps(doc), 60)
        r = _simulate(client, z, tid)
        assert_problem(r, code, "task_id")
        if code == 409:
            assert r.headers["retry-after"] == "1"
    # a stored plan whose inputs are gone (evicted), or from another core build
    tid = "c" * 64
    _put(client, tid, {"task_id": tid, "operation": "plan_scanline", "stages": [],
                       "tool_sequence": []})
    assert_problem(_simulate(client, z, tid), 404, "task_id", "no longer stored")
    _put(client, plan_inputs_key(tid), {"operation": "plan_scanline", "core_build": "0+old",
                                        "params": {}})
    assert_problem(_simulate(client, z, tid), 409, "task_id", "core build")


def test_too_large_a_grid_is_413(tmp_path) -> None:  # type: ignore[no-untyped-def]
    z = part_heights(17)
    with make_client(tmp_path) as c:
        plan = _plan(c, z, toolpaths=False)["task_id"]
    with make_client(tmp_path, max_grid_cells=100) as c:
        assert_problem(_simulate(c, z, plan), 413, "grid")


def test_the_planner_is_deterministic() -> None:
    """What simulating a stored plan rests on: planning again from its inputs gives the same
    plan, pass for pass (a library with a tool the plan may not use)."""
    z = part_heights(17)
    part = ZMap(z, dx=DX, dy=DX)
    tools = [Tool("A", "ball", 10.0, 20.0), Tool("B", "ball", 3.0, 6.0),
             Tool("C", "ball", 1.0, 2.0)]
    a = plan_scanline(part, tools, tolerance=0.05)
    b = plan_scanline(part, tools, tolerance=0.05)
    assert a.tool_sequence == b.tool_sequence and len(a.stages) == len(b.stages)
    for sa, sb in zip(a.stages, b.stages, strict=True):
        assert np.array_equal(sa.model, sb.model) and np.array_equal(sa.lines.offset,
                                                                     sb.lines.offset)


# ---------------------------------------------------------------- the core functions

@settings(max_examples=10, deadline=None)
@given(zmap=_parts())
def test_replayed_passes_are_the_planners_simulation(zmap: ZMap) -> None:
    """On random parts (pockets, trenches, bumps, slopes): the replay's figures are the
    plan's own sim_* figures (the same simulation, run again), and the program replayed
    stretch by stretch leaves what the whole program's verification left."""
    plan = plan_scanline(zmap, tolerance=0.05)
    rp = replay_passes(zmap, plan)
    tol = _rounding(plan.stock_top, zmap.z)
    for s, p in zip(plan.stages, rp.passes, strict=True):
        assert p.positions == s.sim_positions
        assert p.depth_max == pytest.approx(s.sim_max_depth_of_cut, abs=tol)
        assert p.left_over_next_max == pytest.approx(s.sim_left_over_next_max, abs=tol)
        assert p.left_over_part_p95 == pytest.approx(s.sim_left_over_part_p95, abs=tol)
        assert p.gouge <= 1e-9
    assert float((zmap.z - rp.machined).max()) <= 1e-9
    tp = scanline_toolpaths(zmap, plan)
    assert tp.check is not None
    numbers = {p.cutting.tool_number: p.tool for p in tp.stages}
    pr = replay_program(zmap, plan, tp.program, numbers)
    # stretch by stretch the block bounds are rebuilt at other moves, so other nodes are
    # swept by the run kernel instead of the single-node one: the same closed form, but
    # fused multiply-adds (fastmath "contract") may round it an ulp apart (5.6e-17 mm seen)
    np.testing.assert_allclose(pr.machined, tp.check.machined, rtol=0, atol=1e-12)
    assert sum(s.moves for s in pr.stretches) == pr.moves
    assert [i for s in pr.stretches for i in s.stages] == list(range(len(plan.stages)))


def test_a_program_that_does_not_follow_the_plan_is_refused() -> None:
    zmap = ZMap(part_heights(17), dx=DX, dy=DX)
    plan = plan_scanline(zmap, tolerance=0.05)
    tp = scanline_toolpaths(zmap, plan)
    numbers = {p.cutting.tool_number: p.tool for p in tp.stages}
    # the table gives the first tool another number than the program's T1
    table = {(9 if n == 1 else n): tool for n, tool in numbers.items()}
    with pytest.raises(InvalidInputError) as err:
        replay_program(zmap, plan, tp.program, table)
    assert err.value.field == "program" and "do not follow" in err.value.reason
