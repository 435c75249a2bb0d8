"""Cutting simulation: drop-cutter CL and machined envelope against independent references.

The references sample the continuous surface densely (exact points of the bilinear
surface, so they bound the true drop-cutter height from below) or use closed forms
(planes, spheres); none of them uses the code under test.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from zwcore import Tool, ZMap, bilinear_at_fine_nodes
from zwcore.errors import InvalidInputError
from zwcore.sim import (
    closing,
    depth_of_cut,
    drop_cutter,
    envelope,
    rest_regions,
    simulate_pass,
)


def h(kind: str, r: float, d: np.ndarray) -> np.ndarray:
    return r - np.sqrt(np.maximum(r * r - d * d, 0.0)) if kind == "ball" else 0.0 * d


def reference_cl(z: np.ndarray, dx: float, r: float, kind: str, m: int = 6) -> np.ndarray:
    """Tool placed at each node over m x m samples per cell of the bilinear surface: a
    lower bound of the true drop-cutter height (every sample is a surface point)."""
    ny, nx = z.shape
    f = bilinear_at_fine_nodes(z, m, ((ny - 1) * m + 1, (nx - 1) * m + 1))
    fd = dx / m
    w = int(np.ceil(r / fd))
    out = np.empty(z.shape)
    for i in range(ny):
        for k in range(nx):
            i0, i1 = max(0, i * m - w), min(f.shape[0], i * m + w + 1)
            k0, k1 = max(0, k * m - w), min(f.shape[1], k * m + w + 1)
            yy = (np.arange(i0, i1) - i * m) * fd
            xx = (np.arange(k0, k1) - k * m) * fd
            d = np.hypot(yy[:, None], xx[None, :])
            out[i, k] = (f[i0:i1, k0:k1] - h(kind, r, d))[d <= r].max()
    return out


def reference_envelope(cl: np.ndarray, dx: float, r: float, kind: str) -> np.ndarray:
    """Tool tip on every node, lowest tool surface over each node, by a plain loop."""
    ny, nx = cl.shape
    w = int(np.floor(r / dx))
    out = np.full(cl.shape, np.inf)
    for a in range(-w, w + 1):
        for b in range(-w, w + 1):
            d = np.hypot(a * dx, b * dx)
            if d > r or abs(a) >= ny or abs(b) >= nx:
                continue
            src = cl[max(0, -a):ny - max(0, a), max(0, -b):nx - max(0, b)]
            dst = out[max(0, a):ny - max(0, -a), max(0, b):nx - max(0, -b)]
            np.minimum(dst, src + h(kind, r, np.array(d)), out=dst)
    return out


@st.composite
def surfaces(draw: st.DrawFn) -> tuple[np.ndarray, float]:
    ny, nx = draw(st.integers(3, 11)), draw(st.integers(3, 11))
    dx = draw(st.sampled_from([0.1, 0.25, 0.5]))
    seed = draw(st.integers(0, 2**32 - 1))
    rough = draw(st.sampled_from([0.0, 0.2, 1.0, 4.0]))
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:ny, 0:nx] * dx
    z = 2.0 * np.sin(x * rng.uniform(0.2, 2)) * np.cos(y * rng.uniform(0.2, 2))
    return z + rough * dx * rng.standard_normal((ny, nx)), dx


@given(surfaces(), st.sampled_from(["ball", "flat"]), st.floats(0.05, 2.0))
def test_cl_is_never_below_the_dense_reference_and_the_tool_never_gouges(
        surf: tuple[np.ndarray, float], kind: str, radius: float) -> None:
    z, dx = surf
    part = ZMap(z, dx=dx, dy=dx)
    tool = Tool("t", kind, 2 * radius, 10.0)
    cl = drop_cutter(part, tool)
    ref = reference_cl(z, dx, radius, kind, m=4)
    assert (cl - ref).min() >= 0.0
    machined = envelope(cl, tool, dx, dx)
    assert (machined - z).min() >= 0.0, "the tool at its CL cut below the part"
    gap = machined - reference_envelope(cl, dx, radius, kind)
    assert 0.0 <= gap.min() and gap.max() <= 1e-4, "envelope not the tools' lowest surface"


@pytest.mark.parametrize("kind", ["ball", "flat"])
@pytest.mark.parametrize(("radius", "dx"), [(0.5, 0.1), (1.0, 0.25), (1.5, 0.1), (3.0, 0.5)])
@pytest.mark.parametrize("along_y", [False, True])
def test_a_tool_whose_rim_touches_a_walls_foot_sits_on_the_floor(kind: str, radius: float,
                                                                  dx: float, along_y: bool
                                                                  ) -> None:
    """A floor at 0 and a 20 mm wall from one column on: the bilinear ramp between the
    last floor node and the wall starts exactly at the rim of a tool whose axis is ``R``
    from that node, so the tool sits on the floor (true CL 0). Each cell's bound once
    counted the wall's top corner as if the tool touched it (CL 19.5 mm for a Ø1 ball at
    0.1 mm); the corners outside the disc now weigh what the disc gives them."""
    n = round(radius / dx)
    foot = n + 6  # the last floor column
    z = np.zeros((2 * n + 9, foot + n + 6))
    z[:, foot + 1:] = 20.0
    z = z.T.copy() if along_y else z
    tool = Tool("t", kind, 2 * radius, 30.0)
    cl = drop_cutter(ZMap(z, dx=dx, dy=dx), tool)
    cl = cl.T if along_y else cl
    row = n + 4
    assert 0.0 <= cl[row, foot - n] <= 1e-4
    assert np.all(cl[row, : foot - n] <= 1e-4)  # farther from the wall: the floor too
    ref = reference_cl(z, dx, radius, kind, m=4)
    assert (cl - (ref.T if along_y else ref)).min() >= 0.0  # nearer: held up, never below
    assert cl[row, foot - n + 1] > 1.0


@st.composite
def cliffs(draw: st.DrawFn) -> tuple[np.ndarray, float]:
    """A floor with a random step (up to 30 mm) across a random line, some noise."""
    ny, nx = draw(st.integers(4, 12)), draw(st.integers(4, 12))
    dx = draw(st.sampled_from([0.1, 0.25, 0.5]))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    y, x = np.mgrid[0:ny, 0:nx] * dx
    angle = rng.uniform(0, 2 * np.pi)
    side = x * np.cos(angle) + y * np.sin(angle) > rng.uniform(0, max(nx, ny) * dx)
    z = draw(st.floats(0.5, 30.0)) * side + 0.05 * rng.standard_normal((ny, nx))
    return z, dx


@settings(max_examples=60, deadline=None)
@given(cliffs(), st.sampled_from(["ball", "flat"]), st.floats(0.05, 2.0))
def test_cl_beside_cliffs_is_never_below_the_dense_reference(
        surf: tuple[np.ndarray, float], kind: str, radius: float) -> None:
    """The raised outside corners are safe where it matters most: steep steps at every
    distance from the rim."""
    z, dx = surf
    tool = Tool("t", kind, 2 * radius, 40.0)
    cl = drop_cutter(ZMap(z, dx=dx, dy=dx), tool)
    assert (cl - reference_cl(z, dx, radius, kind, m=6)).min() >= 0.0
    pruned = drop_cutter(ZMap(z, dx=dx, dy=dx), tool, method="pruned") if kind == "ball" else cl
    assert (pruned - reference_cl(z, dx, radius, kind, m=6)).min() >= 0.0


@given(st.integers(0, 2**32 - 1), st.sampled_from(["ball", "flat"]), st.floats(0.1, 1.6),
       st.sampled_from([0.25, 0.5]), st.sampled_from(["cell", "bilinear"]))
def test_cell_meaning_is_exact_against_a_square_by_square_reference(
        seed: int, kind: str, r: float, dx: float, meaning: str) -> None:
    rng = np.random.default_rng(seed)
    z = rng.uniform(-3, 3, (int(rng.integers(2, 8)), int(rng.integers(2, 9))))
    tool = Tool("t", kind, 2 * r, 5)
    cl = drop_cutter(ZMap(z, dx=dx, dy=dx), tool, "cell")
    ref = np.full(z.shape, -np.inf)
    for i, k in np.ndindex(z.shape):
        for j, m in np.ndindex(z.shape):  # nearest point of square (j, m) to node (i, k)
            d = np.hypot(max(abs(m - k) * dx - dx / 2, 0), max(abs(j - i) * dx - dx / 2, 0))
            if d <= r:
                ref[i, k] = max(ref[i, k], z[j, m] - float(h(kind, r, np.array(d))))
    assert (cl - ref).min() >= 0.0
    assert (cl - ref).max() <= 3e-5
    if meaning == "cell":
        # the envelope over each square: the highest point any tool leaves there
        env = envelope(cl, tool, dx, dx, "cell")
        assert (env - z).min() >= 0.0


def test_rest_regions_grow_a_seed_by_the_radius_and_box_it() -> None:
    z = np.zeros((41, 61))
    surface = z.copy()
    surface[20, 30] = 1.0
    part = ZMap(z, x0=10.0, y0=-5.0, dx=0.1, dy=0.1)
    regions = rest_regions(surface, part, tolerance=0.5, grow_radius=0.75)
    yy, xx = np.mgrid[0:41, 0:61]
    disc = np.hypot((yy - 20) * 0.1, (xx - 30) * 0.1) <= 0.75 + 1e-9
    assert (regions.mask == disc).all() and regions.count == 1
    box = regions.boxes[0]
    assert (box.x_min, box.x_max) == pytest.approx((10.0 + 2.3, 10.0 + 3.7))
    assert (box.y_min, box.y_max) == pytest.approx((-5.0 + 1.3, -5.0 + 2.7))
    assert box.area == pytest.approx(disc.sum() * 0.01)
    assert regions.area_fraction == pytest.approx(disc.mean())


@pytest.mark.parametrize("slope", [0.0, 0.5, 1.0, 2.0])
def test_ball_on_a_plane_sits_at_the_closed_form_height(slope: float) -> None:
    dx, r = 0.1, 3.0
    y, x = np.mgrid[0:81, 0:81] * dx
    z = slope * x + 0.3 * y
    cl = drop_cutter(ZMap(z, dx=dx, dy=dx), Tool("b", "ball", 2 * r, 10))
    exact = z + r * (np.sqrt(1 + slope**2 + 0.09) - 1)  # ball on a plane of gradient g
    inner = (slice(35, 46), slice(35, 46))  # the contact point lies inside the grid
    err = (cl - exact)[inner]
    assert err.min() >= 0.0
    assert err.max() <= 0.01


def hemisphere(radius: float = 8.0, dx: float = 0.25, half: float = 10.0) -> ZMap:
    n = round(2 * half / dx) + 1
    y, x = (np.mgrid[0:n, 0:n] - (n - 1) / 2) * dx
    r2 = x * x + y * y
    z = np.where(r2 < radius**2, -np.sqrt(np.maximum(radius**2 - r2, 0.0)), 0.0)
    return ZMap(z, dx=dx, dy=dx)


def test_r8_pocket_ball_sizes() -> None:
    part = hemisphere()
    c = (part.shape[0] - 1) // 2
    # the bilinear rim chords stop even an R 8 ball above the bottom: the dense reference
    # says how far (a lower bound of the true CL); the simulation may add its rim bound
    floor_ref = reference_cl(part.z[c - 33:c + 34, c - 33:c + 34], 0.25, 8.0, "ball", m=4)[33, 33]
    rests = {}
    for d in (15.0, 16.0, 18.0):
        rests[d] = closing(part, Tool("b", "ball", d, 40))[c, c] - part.z[c, c]
    assert floor_ref + 8.0 == pytest.approx(0.50, abs=0.02)
    assert floor_ref + 8.0 <= rests[16.0] <= floor_ref + 8.0 + 0.15
    assert rests[15.0] <= 0.02, "a ball inside R 8 with clearance reaches the bottom"
    # an R 9 ball rests on the rim circle: sqrt(81 - 64) - 9 above the floor at -8
    assert rests[18.0] >= 8.0 + np.sqrt(81 - 64) - 9 - 1e-9


def filleted_pocket(dx: float = 0.1) -> ZMap:
    """40 x 30 mm pocket, 4 deep, 45° walls blended into the floor by R 3 fillets, sharp
    in plan at the corners (the surface is the highest of the four wall profiles)."""
    depth, rho = 4.0, 3.0
    sc = depth - rho + rho * np.sqrt(2)  # fillet centre, distance from the wall's top edge
    st_ = sc - rho / np.sqrt(2)

    def wall(s: np.ndarray) -> np.ndarray:
        arc = -depth + rho - np.sqrt(np.maximum(rho**2 - (s - sc) ** 2, 0.0))
        return np.where(s <= 0, 0.0, np.where(s <= st_, -s, np.where(s < sc, arc, -depth)))

    y, x = np.mgrid[0:401, 0:501] * dx
    walls = [wall(x - 5), wall(45 - x), wall(y - 5), wall(35 - y)]
    return ZMap(np.maximum.reduce(walls), dx=dx, dy=dx)


def test_rect_pocket_leaves_rest_only_in_its_corners() -> None:
    part = filleted_pocket()
    out = simulate_pass(part, Tool("b", "ball", 4.0, 12), 1.0)
    assert out.gouge == 0.0
    regions = rest_regions(out.stock, part, tolerance=0.02)
    assert regions.count == 4
    corners = [(5, 5), (45, 5), (5, 35), (45, 35)]
    for box in regions.boxes:
        cx, cy = (box.x_min + box.x_max) / 2, (box.y_min + box.y_max) / 2
        assert min(np.hypot(cx - a, cy - b) for a, b in corners) < 4.0
        assert box.x_max - box.x_min < 6.0 and box.y_max - box.y_min < 6.0


@pytest.mark.parametrize("diameter", [2.0, 6.0, 12.0])
def test_convex_dome_is_left_as_it_is(diameter: float) -> None:
    dx = 0.1
    y, x = (np.mgrid[0:161, 0:161] - 80) * dx
    z = -(x * x + y * y) / 40.0 + 0.5 * np.sin(x / 3)
    part = ZMap(z, dx=dx, dy=dx)
    rest = closing(part, Tool("b", "ball", diameter, 30)) - z
    inner = slice(70, 91)
    assert rest.min() >= 0.0
    assert rest[inner, inner].max() <= 0.005


def test_depth_of_cut_is_the_stock_inside_the_cylinder_above_the_tip() -> None:
    dx = 0.25
    z = np.zeros((41, 41))
    z[:, 21:] = -5.0  # a 5 mm step: a ball beside it meets the upper level
    part = ZMap(z, dx=dx, dy=dx)
    tool = Tool("b", "ball", 4.0, 3.0)
    out = simulate_pass(part, tool, 2.0)
    # a ball centred at the step's foot meets the stock top (2) over its whole cylinder
    assert out.depth.max == pytest.approx(7.0, abs=1e-4)
    assert not out.depth.flute_length_ok
    # a grid stock equal to the part: away from the step the cylinder holds nothing above
    # the tip; beside it, the 5 mm step the ball rests against (counted: the flutes touch it)
    none = depth_of_cut(z, out.cl, tool, dx, dx)
    assert none.per_position[:, 31:].max() == pytest.approx(0.0, abs=1e-4)
    assert none.per_position[:, :11].max() == pytest.approx(0.0, abs=1e-4)
    assert none.max <= 5.0 + 1e-4


def test_bad_input_names_the_field() -> None:
    part = ZMap(np.zeros((5, 5)))
    tool = Tool("b", "ball", 2.0, 4.0)
    with pytest.raises(InvalidInputError) as e:
        simulate_pass(part, tool, np.zeros((4, 5)))
    assert e.value.field == "stock"
    with pytest.raises(InvalidInputError) as e:
        simulate_pass(part, tool, np.full((5, 5), -1.0))
    assert e.value.field == "stock"
    with pytest.raises(InvalidInputError) as e:
        simulate_pass(part, tool, 1.0, cl=np.zeros((5, 4)))
    assert e.value.field == "cl"


def test_given_cl_below_the_surface_reports_the_gouge() -> None:
    z = np.zeros((9, 9))
    part = ZMap(z, dx=0.5, dy=0.5)
    out = simulate_pass(part, Tool("f", "flat", 2.0, 4.0), 1.0, cl=np.full((9, 9), -0.3))
    assert out.gouge == pytest.approx(0.3, abs=1e-4)


def test_cl_against_opencamlib_on_a_surface_both_represent_exactly() -> None:
    """A valley profile z = f(x), piecewise linear between nodes: its bilinear cells are
    planar, so opencamlib's drop cutter on the triangulated grid is an independent oracle."""
    ocl = pytest.importorskip("opencamlib")
    dx, r = 0.1, 1.5
    x = np.arange(81) * dx
    f = np.where(x < 3, 3 - x, np.where(x < 4.5, 0.0, 1.5 * (x - 4.5))) + 0.2 * np.sin(3 * x)
    z = np.tile(f, (41, 1))
    surf = ocl.STLSurf()
    for i, k in np.ndindex(40, 80):
        p = [ocl.Point(float((k + b) * dx), float((i + a) * dx), float(z[i + a, k + b]))
             for a, b in ((0, 0), (0, 1), (1, 1), (1, 0))]
        surf.addTriangle(ocl.Triangle(p[0], p[1], p[2]))
        surf.addTriangle(ocl.Triangle(p[0], p[2], p[3]))
    cutter = ocl.BallCutter(2 * r, 10.0)  # the batch keeps a pointer: keep it alive
    bdc = ocl.BatchDropCutter()
    bdc.setSTL(surf)
    bdc.setCutter(cutter)
    nodes = [(20, k) for k in range(15, 66, 2)]  # mid rows: the ball stays over the surface
    for i, k in nodes:
        bdc.appendPoint(ocl.CLPoint(k * dx, i * dx, -100.0))
    bdc.run()
    oracle = np.array([p.z for p in bdc.getCLPoints()])
    cl = drop_cutter(ZMap(z, dx=dx, dy=dx), Tool("b", "ball", 2 * r, 10))
    ours = np.array([cl[i, k] for i, k in nodes])
    assert (ours - oracle).min() >= -1e-6
    assert (ours - oracle).max() <= 0.03  # the bound's gap at a 56° wall, dx = R / 15


def _dilation_brute(z: np.ndarray, s: np.ndarray) -> np.ndarray:
    """``min over v of max over offsets of z + s[v]`` in float64 by plain shifts (-inf off
    the grid): the exact value of the structuring functions, without ``_morph``."""
    nv, na, nb = s.shape
    A, B = na // 2, nb // 2
    ny, nx = z.shape
    zp = np.full((ny + 2 * A, nx + 2 * B), -np.inf)
    zp[A:A + ny, B:B + nx] = z
    out = np.full((nv, ny, nx), -np.inf)
    for v in range(nv):
        for a, b in zip(*np.nonzero(np.isfinite(s[v])), strict=True):
            np.maximum(out[v], zp[a:a + ny, b:b + nx] + s[v, a, b], out=out[v])
    return out.min(axis=0)


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(12, 48), st.sampled_from([0.1, 0.2, 0.35]),
       st.floats(0.5, 4.0), st.sampled_from(["smooth", "rough", "plateau", "steps"]),
       st.sampled_from(["ball", "flat"]))
def test_pruned_drop_cutter_is_the_exact_dilation(seed: int, n: int, dx: float, radius: float,
                                                  shape: str, kind: str) -> None:
    """The branch and bound (``method="pruned"``) against the plain float64 dilation by the
    same structuring functions: never below it (so never below the true drop-cutter
    height, which the functions bound), above it by float64 rounding only; and never below
    the dense sampling of the bilinear surface."""
    from zwcore.sim._profiles import drop_profile

    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:n, 0:n] * dx
    z = 2.0 * np.sin(x * rng.uniform(0.2, 2)) * np.cos(y * rng.uniform(0.2, 2)) + rng.uniform(
        -1, 1) * x
    if shape == "rough":
        z = z + 0.3 * rng.standard_normal(z.shape)
    elif shape == "plateau":
        z = np.maximum(z, np.quantile(z, 0.5))
    elif shape == "steps":
        z = np.round(z)
    tool = Tool("t", kind, 2 * radius, 10.0)
    part = ZMap(z, dx=dx, dy=dx)
    cl = drop_cutter(part, tool, method="pruned")
    s = np.asarray(drop_profile(tool, dx, dx, "bilinear"))
    exact = _dilation_brute(z, s if s.ndim == 3 else s[None])
    assert (cl - exact).min() >= 0.0
    assert (cl - exact).max() <= 1e-9
    if n <= 16:
        assert (cl - reference_cl(z, dx, radius, kind, m=3)).min() >= 0.0


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(12, 40), st.floats(0.5, 3.0),
       st.lists(st.integers(0, 39), min_size=1, max_size=8))
def test_pruned_drop_cutter_on_some_rows_is_the_whole_grid_there(seed: int, n: int,
                                                                 radius: float,
                                                                 rows: list[int]) -> None:
    """``rows``: those rows exactly as in the whole grid (and the transposed surface's rows
    are the whole grid's columns), the others NaN."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:n, 0:n + 3] * 0.2
    z = 2.0 * np.sin(x * rng.uniform(0.2, 2)) * np.cos(y * rng.uniform(0.2, 2))
    tool = Tool("t", "ball", 2 * radius, 10.0)
    part = ZMap(z, dx=0.2, dy=0.25)
    whole = drop_cutter(part, tool, method="pruned")
    want = np.unique(np.asarray(rows) % n)
    some = drop_cutter(part, tool, method="pruned", rows=want)
    np.testing.assert_array_equal(some[want], whole[want])
    assert np.isnan(np.delete(some, want, axis=0)).all()
    cols = np.unique(np.asarray(rows) % (n + 3))
    tr = drop_cutter(ZMap(np.ascontiguousarray(z.T), dx=0.25, dy=0.2), tool, method="pruned",
                     rows=cols)
    np.testing.assert_allclose(tr[cols].T, whole[:, cols], rtol=0, atol=1e-12)
    with pytest.raises(ValueError):
        drop_cutter(part, tool, method="pruned", rows=np.array([n]))


def test_drop_cutter_methods_agree_and_a_bad_method_names_the_field() -> None:
    rng = np.random.default_rng(5)
    z = np.cumsum(rng.standard_normal((40, 40)), axis=1) * 0.05
    part = ZMap(z, dx=0.1, dy=0.1)
    tool = Tool("b", "ball", 5.0, 10.0)
    dil = drop_cutter(part, tool)
    # the dilation rounds up (float32 where the span allows): the pruned float64 result
    # lies under it by at most that rounding, never above it by more than float64 rounding
    for method in ("pruned", "auto"):
        cl = drop_cutter(part, tool, method=method)
        assert -1e-9 <= (dil - cl).min() and (dil - cl).max() <= 5e-5
    with pytest.raises(InvalidInputError) as e:
        drop_cutter(part, tool, method="fast")
    assert e.value.field == "method"


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 40), st.integers(1, 40), st.integers(0, 7),
       st.integers(0, 7), st.integers(1, 3), st.sampled_from([1.0, 1e4]))
def test_dilation_kernel_is_the_plain_dilation(seed: int, ny: int, nx: int, A: int, B: int,
                                               nv: int, scale: float) -> None:
    """The compiled strip kernel of :func:`zwcore.sim._morph.dilate` against the plain
    float64 dilation by shifts: a stack of mirror-symmetric functions sharing some offsets
    and not others, -inf outside their elements; float32 (small span) and float64 (large
    span, ``scale``) arithmetic. Never below the exact value, above it by at most the
    rounding bound; the erosion likewise (its mirror)."""
    from zwcore.sim._morph import _dilate_bounded, erode

    rng = np.random.default_rng(seed)
    base = rng.normal(size=(2 * A + 1, 2 * B + 1))
    stack = np.stack([base + (v > 0) * rng.normal(size=base.shape)
                      * (rng.random(base.shape) < 0.5) for v in range(nv)])
    stack[rng.random(stack.shape) < 0.15] = -np.inf
    # mirror-symmetric in both axes (-inf where any mirror is)
    stack = np.minimum(stack, stack[:, ::-1])
    stack = np.minimum(stack, stack[:, :, ::-1])
    z = scale * rng.normal(size=(ny, nx))
    out, delta = _dilate_bounded(z, stack)
    exact = _dilation_brute(z, stack)
    both = np.isfinite(exact)
    assert np.array_equal(both, np.isfinite(out))
    assert (out[both] - exact[both]).min(initial=0.0) >= 0.0
    assert (out[both] - exact[both]).max(initial=0.0) <= 2.0 * delta
    eroded = erode(z, -stack[0])
    low = -_dilation_brute(-z, stack[:1])
    fin = np.isfinite(low)
    assert (eroded[fin] - low[fin]).min(initial=0.0) >= 0.0
