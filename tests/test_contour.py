"""Contour plan (design section 4): invariants on random surfaces, coefficient
editing, slab volumes, known answers, real data, bad input."""

from __future__ import annotations

import itertools
import math
import pathlib

import numpy as np
import pytest
from hypothesis import example, given
from hypothesis import strategies as st

from tests.conftest import height_grids
from zwcore.contour.heights import QUANTUM, ceil_units
from zwcore.contour.planner import (
    STRATEGIES,
    VOLUME_SPREAD_LIMIT,
    ContourPlan,
    level_for_tool,
    plan_contour,
)
from zwcore.errors import InvalidInputError
from zwcore.grid.sampling import cells_at_fine_nodes
from zwcore.grid.tools import Tool, default_tools
from zwcore.grid.zmap import ZMap
from zwcore.mrr.terraces import edit_coefficients
from zwcore.mrr.wavelets import analyse

DATA = pathlib.Path(__file__).resolve().parents[2] / "shared" / "data"
RUSHMORE = DATA / "mount_rush_zmap_0.1mm.npy"


# --------------------------------------------------------------------------
# Strategies
# --------------------------------------------------------------------------


@st.composite
def pockets(draw: st.DrawFn) -> np.ndarray:
    """A plate with rectangular pockets, some deeper than any flute drawn below."""
    ny, nx = draw(st.integers(4, 24)), draw(st.integers(4, 24))
    z = np.full((ny, nx), draw(st.floats(-20, 20)))
    for _ in range(draw(st.integers(1, 3))):
        i0, k0 = draw(st.integers(0, ny - 2)), draw(st.integers(0, nx - 2))
        i1, k1 = draw(st.integers(i0 + 1, ny)), draw(st.integers(k0 + 1, nx))
        z[i0:i1, k0:k1] -= draw(st.floats(0.5, 80))
    return z


@st.composite
def surfaces(draw: st.DrawFn) -> np.ndarray:
    return draw(st.one_of(height_grids(max_side=12), pockets()))


@st.composite
def libraries(draw: st.DrawFn) -> list[Tool]:
    """1-4 flat end mills spread over a few levels, flutes from tight to generous."""
    n = draw(st.integers(1, 4))
    return [Tool(f"T{i}", "flat", draw(st.floats(0.3, 12)), draw(st.floats(0.7, 30)))
            for i in range(n)]


# --------------------------------------------------------------------------
# Helpers: independent re-computation of the invariants at the input nodes
# --------------------------------------------------------------------------


def _node_models(plan: ContourPlan, shape: tuple[int, int]) -> list[np.ndarray]:
    return [cells_at_fine_nodes(s.model, s.scale, shape) for s in plan.stages]


def _brute_slabs(prev: np.ndarray, cur: np.ndarray, z_levels: tuple[float, ...],
                 area: float) -> np.ndarray:
    """Per slab, the volume between ``prev`` and ``cur`` inside it, node by node."""
    out = []
    for a, b in itertools.pairwise(z_levels):
        inside = np.clip(np.minimum(prev, a) - np.maximum(cur, b), 0.0, None)
        out.append(inside.sum() * area)
    return np.array(out)


def _assert_invariants(plan: ContourPlan, zm: ZMap) -> None:
    z = zm.z
    top_q = ceil_units(plan.stock_top) * QUANTUM
    fines = _node_models(plan, z.shape)
    prev = np.full(z.shape, top_q)
    levels = [s.level for s in plan.stages]
    assert levels == sorted(set(levels)), "one stage per level, coarse to fine"
    for s, fine in zip(plan.stages, fines, strict=True):
        # Containment: every stage inside the previous one, the part inside all.
        assert (prev - fine).min() >= 0.0
        assert (fine - z).min() >= 0.0
        # No empty stage: every stage has a slab and lowers some input node.
        assert s.spacings and float((prev - fine).max()) > 0.0, f"{s.tool.id} removes nothing"
        # Spacings: positive, within the flute, consistent with the heights.
        assert all(sp > 0 for sp in s.spacings)
        assert all(sp <= s.tool.flute_length for sp in s.spacings)
        assert list(s.z_levels) == sorted(s.z_levels, reverse=True)
        np.testing.assert_array_equal(np.diff(s.z_levels), -np.array(s.spacings))
        assert len(s.slab_volumes) == len(s.spacings) == len(s.flute_cap_binds)
        # Terraces: every cell is on a contour height or kept from the previous model.
        on_level = np.isin(s.model, np.array(s.z_levels))
        prev_cells = prev[::s.scale, ::s.scale][: s.model.shape[0], : s.model.shape[1]]
        assert np.all(on_level | (s.model == prev_cells))
        # Slab volumes: what each slab really removes, and they add up.
        if s.z_levels:
            brute = _brute_slabs(prev, fine, s.z_levels, zm.cell_area)
            scale = max(1.0, float(np.abs(np.concatenate([prev, fine])).max()) * z.size
                        * zm.cell_area)
            np.testing.assert_allclose(s.slab_volumes, brute, rtol=1e-9, atol=1e-9 * scale)
            total = float((prev - fine).sum()) * zm.cell_area
            assert math.isclose(sum(s.slab_volumes), total, rel_tol=1e-9, abs_tol=1e-9 * scale)
        else:
            np.testing.assert_array_equal(fine, prev)
        # Honest flags: a slab flagged as set by the flute is exactly the flute
        # length thick (to the height quantum) and removes less than the
        # equal-volume slabs of its stage.
        free = [v for v, c in zip(s.slab_volumes, s.flute_cap_binds, strict=True) if not c]
        for sp, v, c in zip(s.spacings, s.slab_volumes, s.flute_cap_binds, strict=True):
            if c:
                assert abs(sp - s.tool.flute_length) <= QUANTUM, (sp, s.tool.flute_length)
                if free and s.spacing_rule == "equal_volume":
                    assert v <= max(free) * (1 + 1e-9)
        # The reported spread is the real one.
        if len(free) >= 2 and min(free) > 0:
            assert math.isclose(s.volume_spread, max(free) / min(free) - 1, rel_tol=1e-9,
                                abs_tol=1e-12)
        prev = fine
    assert plan.contour_spacings == tuple(sp for s in plan.stages for sp in s.spacings)
    c = plan.checks
    assert c.containment and c.spacings_positive and c.spacings_within_flute
    assert c.volumes_add_up and c.terraces_from_coefficients
    assert c.min_containment_margin >= 0.0


# --------------------------------------------------------------------------
# Invariants on random surfaces
# --------------------------------------------------------------------------


@given(z=surfaces(), tools=libraries(), strategy=st.sampled_from(STRATEGIES),
       dx=st.sampled_from([0.5, 1.0, 1.7]), extra=st.one_of(st.none(), st.floats(0, 60)))
def test_invariants_hold_on_random_surfaces(z: np.ndarray, tools: list[Tool], strategy: str,
                                            dx: float, extra: float | None) -> None:
    zm = ZMap(z, dx=dx, dy=dx * 0.75)
    top = None if extra is None else float(z.max()) + extra
    plan = plan_contour(zm, tools, stock_top=top, strategy=strategy)
    _assert_invariants(plan, zm)
    assert plan.stock_top_source == ("default" if top is None else "request")


def _pit_below_a_floor() -> np.ndarray:
    """Found by hypothesis: a one-node pit 39 mm deep in a floor with a tall spike. Every
    slab count next to the nominal one was skipped by a jump of the slab-count function
    (the slab crossing the floor's height takes a pit slab), and the placement kept a
    leftover bottom slab of 0.75 of the others (spread 0.33); even placements exist a
    dozen counts away."""
    z = np.zeros((11, 9))
    z[0, 0], z[9, 0], z[9, 2] = 53.6290386, 0.5, -39.0
    return z


@given(z=surfaces(), tools=libraries())
@example(z=_pit_below_a_floor(),
         tools=[Tool("T0", "flat", 5.0, 5.0), Tool("T1", "flat", 9.0, 1.0),
                Tool("T2", "flat", 0.375, 19.0), Tool("T3", "flat", 0.375, 1.0)])
def test_equal_volume_where_the_cap_does_not_bind(z: np.ndarray, tools: list[Tool]) -> None:
    plan = plan_contour(ZMap(z), tools)
    assert plan.checks.max_volume_spread <= VOLUME_SPREAD_LIMIT
    assert plan.checks.ok


def _block_max_at_nodes(z: np.ndarray, scale: int) -> np.ndarray:
    """At every input node, the part's maximum over its level cell (brute force)."""
    out = np.empty_like(z)
    for i in range(0, z.shape[0], scale):
        for k in range(0, z.shape[1], scale):
            out[i:i + scale, k:k + scale] = z[i:i + scale, k:k + scale].max()
    return out


def _terrace_rule(block_max: np.ndarray, prev: np.ndarray, z_levels: tuple[float, ...],
                  ) -> np.ndarray:
    """Every node raised to the lowest contour height at or above it, capped by ``prev``."""
    out = prev.copy()
    for idx, v in np.ndenumerate(block_max):
        above = [h for h in z_levels if h >= v]
        up = min(above) if above else math.inf  # above every height: keeps prev
        out[idx] = min(prev[idx], up)
    return out


@given(z=surfaces(), tools=libraries())
def test_edited_coefficients_synthesise_the_terraces(z: np.ndarray, tools: list[Tool]) -> None:
    zm = ZMap(z)
    plan = plan_contour(zm, tools)
    mrr = analyse(z, "haar")
    prev = np.full(z.shape, ceil_units(plan.stock_top) * QUANTUM)
    prev_cells = None
    fines = []
    for s in plan.stages:
        if prev_cells is None:
            previous = np.full(mrr.approximations[s.level].shape, prev[0, 0])
        else:
            previous = cells_at_fine_nodes(prev_cells[0], 1 << (s.level - prev_cells[1]),
                                           mrr.approximations[s.level].shape)
        edited = edit_coefficients(mrr, s.level, previous, np.array(s.z_levels))
        # The representation is the part's from the stage level up, edited: the
        # approximation raised onto the contour grid, the finer details zero.
        approx = mrr.approximations[s.level]
        assert (edited.approximation >= approx).all()
        assert np.all(np.isin(edited.approximation, np.array(s.z_levels))
                      | (edited.approximation == previous))
        assert len(edited.details) == mrr.depth - s.level
        assert all(b.count_nonzero() == 0 for b in edited.details)
        changed = int(np.count_nonzero(edited.approximation != approx)) + sum(
            b.count_nonzero() for b in mrr.details[s.level:])
        assert edited.edited == changed == s.edited_coefficients
        fine = edited.synthesize()
        # Synthesis equals the terrace rule applied independently at every input
        # node (cell semantics: the block maximum of the node's cell).
        want = _terrace_rule(_block_max_at_nodes(z, s.scale), prev, s.z_levels)
        np.testing.assert_array_equal(fine, want)  # bit for bit
        np.testing.assert_array_equal(edited.synthesize(to_level=s.level), s.model)
        assert (fine >= z).all()  # contains the part
        assert (prev >= fine).all()  # and is contained in the previous stage
        fines.append(fine)
        prev, prev_cells = fine, (s.model, s.level)
    assert plan.checks.terraces_from_coefficients


def test_stock_top_default_is_part_top_plus_first_flute() -> None:
    z = np.zeros((8, 8))
    z[2:6, 2:6] = 3.0
    tools = [Tool("a", "flat", 2.0, 5.0), Tool("b", "flat", 1.0, 4.0)]
    plan = plan_contour(ZMap(z), tools)
    assert plan.stock_top == 3.0 + 5.0
    assert plan.stock_top_source == "default"
    assert plan.stages[0].z_levels[0] == 8.0
    assert any("flute length" in n for n in plan.notes)


# --------------------------------------------------------------------------
# Level and tool selection
# --------------------------------------------------------------------------


def test_level_is_finest_with_cell_at_least_the_diameter() -> None:
    # J = 5 for 32 nodes; dx = 0.1: cells 0.1, 0.2, 0.4, 0.8, 1.6, 3.2 mm.
    for d, j in [(0.05, 5), (0.1, 5), (0.15, 4), (0.4, 3), (0.41, 2), (3.2, 0), (50.0, 0)]:
        level, _rule = level_for_tool(Tool("t", "flat", d, 1.0), 5, 0.1, 0.1)
        assert level == j, (d, level)
    assert "at least the tool diameter" in level_for_tool(Tool("t", "flat", 0.4, 1), 5, .1, .1)[1]
    assert "coarsest" in level_for_tool(Tool("t", "flat", 50.0, 1.0), 5, 0.1, 0.1)[1]
    # Anisotropic spacing: the narrower side decides.
    assert level_for_tool(Tool("t", "flat", 0.4, 1.0), 5, 0.1, 0.2)[0] == 3


def test_largest_tool_per_level_is_kept() -> None:
    z = np.random.default_rng(1).random((256, 256)) * 5
    plan = plan_contour(ZMap(z, dx=0.1, dy=0.1))
    ids = [s.tool.id for s in plan.stages]
    assert ids == ["FEM-D20", "FEM-D12", "FEM-D6", "FEM-D3"]
    for s in plan.stages:
        assert min(s.cell_size) >= s.tool.diameter
        assert min(s.cell_size) / 2 < s.tool.diameter  # the finest such level
        assert "FEM" in s.tool.id
    assert sum("not used" in n for n in plan.notes) == 5


# --------------------------------------------------------------------------
# Known answers
# --------------------------------------------------------------------------


def _pyramid(n: int, step: float, steps: int) -> np.ndarray:
    i, k = np.mgrid[0:n, 0:n]
    ring = np.minimum(np.minimum(i, k), np.minimum(n - 1 - i, n - 1 - k))
    return np.minimum(ring // (n // (2 * steps)), steps - 1) * step


def test_stepped_pyramid_on_the_contour_grid_comes_back_with_its_steps() -> None:
    z = _pyramid(32, 5.0, 4)  # plateaus at 0, 5, 10, 15
    tool = Tool("D1", "flat", 1.0, 5.0)  # level J: cells are nodes
    plan = plan_contour(ZMap(z), [tool])
    (s,) = plan.stages
    assert s.z_levels == (20.0, 15.0, 10.0, 5.0, 0.0)
    np.testing.assert_array_equal(s.model, z)
    assert s.max_stock_left == 0.0
    # Semi-finishing on a constant step-down (1 mm, the tool diameter) whose
    # grid holds the plateaus also gives them back exactly.
    rough = Tool("D64", "flat", 64.0, 30.0)
    plan2 = plan_contour(ZMap(z), [rough, tool], stock_top=15.0, strategy="even_step")
    # The rough tool's single cell is the part's top, the stock: it removes
    # nothing and is no stage.
    assert [s.tool.id for s in plan2.stages] == ["D1"]
    assert any(n.startswith("D64 not used") for n in plan2.notes)
    fine = plan2.stages[0]
    assert fine.z_levels == tuple(float(h) for h in range(15, -1, -1))
    np.testing.assert_array_equal(fine.model, z)
    assert plan2.checks.ok


def test_hemisphere_heights_crowd_towards_the_top() -> None:
    n, r = 128, 30.0
    y, x = (np.mgrid[0:n, 0:n] - (n - 1) / 2) * 0.5
    z = np.sqrt(np.clip(r * r - x * x - y * y, 0, None))
    face = Tool("face", "flat", 80.0, 40.0)  # level 0: faces the stock to the top
    mill = Tool("D2", "flat", 2.0, 40.0)
    plan = plan_contour(ZMap(z, dx=0.5, dy=0.5), [face, mill], stock_top=35.0)
    s = plan.stages[1]
    assert s.spacing_rule == "equal_volume"
    free = [sp for sp, c in zip(s.spacings, s.flute_cap_binds, strict=True) if not c]
    assert len(free) >= 5
    # The cut area shrinks with depth (the sphere widens), so equal volumes need
    # ever thicker slabs: spacings grow from the top down.
    assert all(b >= a for a, b in itertools.pairwise(free))
    assert free[-1] > 2 * free[0]
    assert s.volume_spread <= 0.01
    assert plan.checks.ok


@pytest.mark.parametrize("strategy", STRATEGIES)
def test_r8_bowl_lists_no_empty_stage(strategy: str) -> None:
    # A hemispherical pocket of radius 8 mm in a flat plate on a 0.25 mm grid:
    # the coarse Haar levels are flat at the plate (block maxima), so the tool
    # after heavy roughing has nothing left on its level. It is dropped and
    # named in the notes, not listed with no heights and 0 volume.
    x = np.arange(-20.0, 20.0 + 1e-9, 0.25)
    xx, yy = np.meshgrid(x, x)
    r2 = xx**2 + yy**2
    z = np.where(r2 < 64.0, -np.sqrt(np.clip(64.0 - r2, 0.0, None)), 0.0)
    zm = ZMap(z, dx=0.25, dy=0.25)
    plan = plan_contour(zm, strategy=strategy)
    _assert_invariants(plan, zm)
    assert plan.checks.ok
    used = {s.tool.id for s in plan.stages}
    dropped = [n for n in plan.notes if "would remove nothing" in n]
    assert dropped and all(n.split()[0] not in used for n in dropped)
    # Each listed stage removes material: its model lies below the previous one
    # somewhere (recomputed at the input nodes, not from the plan's volumes).
    prev = np.full(z.shape, ceil_units(plan.stock_top) * QUANTUM)
    for fine in _node_models(plan, z.shape):
        assert float(((prev - fine) * zm.cell_area).sum()) > 0.0
        prev = fine


def test_pocket_deeper_than_the_flute_gets_several_slabs() -> None:
    z = np.full((32, 32), 10.0)
    z[8:24, 8:24] = -20.0  # a 30 mm deep pocket
    tool = Tool("D2", "flat", 2.0, 8.0)
    plan = plan_contour(ZMap(z), [tool], stock_top=10.0)
    (s,) = plan.stages
    assert len(s.spacings) == 4  # ceil(30 / 8)
    assert s.spacings == (7.5, 7.5, 7.5, 7.5)
    np.testing.assert_array_equal(cells_at_fine_nodes(s.model, s.scale, z.shape), z)
    # A later stage in a pocket with a constant area: equal volumes mean equal spacing.
    face = Tool("face", "flat", 40.0, 12.0)
    plan2 = plan_contour(ZMap(z), [face, tool], stock_top=10.0)
    # The face mill's one cell is the plate's top, the stock: no stage.
    assert [s.tool.id for s in plan2.stages] == ["D2"]
    s2 = plan2.stages[0]
    assert len(s2.spacings) >= 4 and max(s2.spacings) <= 8.0
    assert s2.volume_spread <= 0.01
    assert plan2.checks.ok


@pytest.mark.parametrize("depth", [23.0, 30.0, 37.5])
def test_no_leftover_slab_under_a_narrow_well(depth: float) -> None:
    # A wide plate with a narrow well whose depth is no multiple of the flute:
    # below the plate only the well's cells are cut, so slabs there cannot
    # reach the stage's slab volume within the flute. They must be exactly the
    # flute length (flagged), and every other slab must remove the same volume;
    # the old placement left a thinner bottom slab and called it capped.
    # A tilted plate, so the stage has volume at many heights.
    z = 0.1 * np.mgrid[0:64, 0:64][0].astype(float)
    z[28:36, 28:36] = -depth
    face = Tool("face", "flat", 64.0, 60.0)
    mill = Tool("D2", "flat", 2.0, 8.0)
    plan = plan_contour(ZMap(z), [face, mill], stock_top=10.0)
    s = plan.stages[1]
    assert s.spacing_rule == "equal_volume"
    free = [v for v, c in zip(s.slab_volumes, s.flute_cap_binds, strict=True) if not c]
    assert len(free) >= 2
    assert max(free) / min(free) - 1 <= 0.01, (s.spacings, s.slab_volumes)
    for sp, c in zip(s.spacings, s.flute_cap_binds, strict=True):
        assert (not c) or sp == 8.0
    assert any(s.flute_cap_binds)
    assert s.volume_spread == max(free) / min(free) - 1
    _assert_invariants(plan, ZMap(z))


def test_even_step_strategy_spaces_evenly() -> None:
    z = _pyramid(32, 3.0, 4)
    tools = [Tool("big", "flat", 16.0, 20.0), Tool("small", "flat", 2.0, 10.0)]
    plan = plan_contour(ZMap(z), tools, strategy="even_step")
    s = plan.stages[1]
    assert s.spacing_rule == "even_step"
    assert max(s.spacings) - min(s.spacings) <= 2 * QUANTUM
    assert max(s.spacings) <= s.nominal_step
    assert plan.checks.containment


# --------------------------------------------------------------------------
# Real data
# --------------------------------------------------------------------------


@pytest.mark.skipif(not RUSHMORE.exists(), reason="shared data not available")
def test_mount_rushmore_plan() -> None:
    z = np.load(RUSHMORE).astype(np.float64)
    zm = ZMap(z, x0=-40.958, y0=-24.696, dx=0.1, dy=0.1)
    plan = plan_contour(zm)
    assert plan.checks.ok, plan.checks
    assert [s.tool.id for s in plan.stages] == ["FEM-D20", "FEM-D12", "FEM-D6", "FEM-D3"]
    assert plan.checks.max_volume_spread <= 0.01
    assert len(plan.contour_spacings) >= 8
    assert plan.stages[-1].mean_stock_left < plan.stages[0].mean_stock_left
    _assert_invariants(plan, zm)
    for s in plan.stages[1:]:
        # Every slab is either at the flute length (flagged) or an equal-volume
        # one: no leftover slab with little volume at the bottom.
        free = [v for v, c in zip(s.slab_volumes, s.flute_cap_binds, strict=True) if not c]
        assert len(free) >= 2 and max(free) / min(free) - 1 <= 0.01, s.slab_volumes
        for sp, c in zip(s.spacings, s.flute_cap_binds, strict=True):
            assert c == (abs(sp - s.tool.flute_length) <= QUANTUM), (s.tool.id, s.spacings)
    # The reviewed figures: FEM-D12 had a 23.246 mm slab (flute 26) removing
    # 1.43 cm3 against 15.44, FEM-D6 12.095 mm (flute 13) and FEM-D3 4.432 mm
    # (flute 8) slabs flagged as capped.
    d12 = plan.stages[1]
    assert d12.spacings[-1] == 26.0 and d12.flute_cap_binds[-1]
    assert all(sp < 26.0 for sp in d12.spacings[:-1])


# --------------------------------------------------------------------------
# Bad input
# --------------------------------------------------------------------------


@pytest.mark.parametrize("top", [float("nan"), float("inf"), 0.5, -1e9, 2e6, "high"])
def test_bad_stock_top(top: object) -> None:
    z = np.ones((4, 4))
    with pytest.raises(InvalidInputError) as e:
        plan_contour(ZMap(z), stock_top=top)  # type: ignore[arg-type]
    assert e.value.field == "stock_top"


def test_bad_strategy_and_tools() -> None:
    zm = ZMap(np.ones((4, 4)))
    with pytest.raises(InvalidInputError) as e:
        plan_contour(zm, strategy="fastest")
    assert e.value.field == "strategy" and "uniform_load" in e.value.reason
    with pytest.raises(InvalidInputError) as e:
        plan_contour(zm, [])
    assert e.value.field == "tools"
    with pytest.raises(InvalidInputError) as e:
        plan_contour(zm, [Tool("b", "ball", 2.0, 4.0)])
    assert e.value.field.startswith("tools[0]")
    with pytest.raises(InvalidInputError):
        plan_contour(zm, [Tool("f", "flat", 2.0, 0.0)])
    assert plan_contour(zm, strategy="Even-Step").strategy == "even_step"


def test_flat_part_at_stock_top_needs_no_slabs() -> None:
    zm = ZMap(np.full((8, 8), 2.0))
    plan = plan_contour(zm, default_tools("flat")[:2], stock_top=2.0)
    assert plan.contour_spacings == ()
    assert plan.checks.ok
    for s in plan.stages:
        assert s.removed_volume == 0.0
        np.testing.assert_array_equal(s.model, 2.0)
