"""Slab-volume function, equal-volume placement and terraces, against brute force."""

from __future__ import annotations

import itertools

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from zwcore.contour_heights import (
    QUANTUM,
    SlabVolumes,
    ceil_units,
    even_heights,
    floor_units,
    place_equal_volume,
    removed_between,
    volume_spread,
)
from zwcore.terraces import cell_weights, terrace


@st.composite
def cut_cells(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cells with level model L below a terraced previous model P (few distinct values)."""
    m = draw(st.integers(1, 40))
    tops = np.array(sorted(set(draw(st.lists(st.integers(0, 40), min_size=1, max_size=5)))),
                    dtype=float)
    p = tops[draw(hnp.arrays(np.int64, m, elements=st.integers(0, tops.size - 1)))]
    depth = draw(hnp.arrays(np.float64, m, elements=st.floats(0.01, 30)))
    if draw(st.booleans()):  # plateaus: many cells on the same height
        depth = np.round(depth)
        depth[depth == 0] = 1.0
    w = draw(hnp.arrays(np.float64, m, elements=st.sampled_from([0.25, 1.0, 2.0])))
    return p - depth, p, w


def _brute_w(lower: np.ndarray, upper: np.ndarray, w: np.ndarray, a: float, b: float) -> float:
    """W(a, b) by its definition: cells the tool reaches at b, cut from min(P, a) to b."""
    reach = lower <= b
    return float((w * reach * np.clip(np.minimum(upper, a) - b, 0, None)).sum())


@given(cells=cut_cells(), data=st.data())
def test_slab_volume_function_matches_its_definition(
        cells: tuple[np.ndarray, np.ndarray, np.ndarray], data: st.DataObject) -> None:
    lower, upper, w = cells
    sv = SlabVolumes(lower, upper, w)
    a = data.draw(st.floats(float(lower.min()), float(upper.max()) + 1))
    bs = np.concatenate((np.linspace(float(lower.min()) - 1, a, 17), lower, upper))
    bs = bs[bs < a]
    got = sv.volume(a, bs)
    want = [_brute_w(lower, upper, w, a, b) for b in bs]
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-9)


@given(cells=cut_cells(), data=st.data())
def test_crossing_is_exact(cells: tuple[np.ndarray, np.ndarray, np.ndarray],
                           data: st.DataObject) -> None:
    lower, upper, w = cells
    sv = SlabVolumes(lower, upper, w)
    a = float(upper.max())
    lo = float(lower.min())
    peak = max(_brute_w(lower, upper, w, a, b) for b in np.concatenate((lower, [lo])))
    target = data.draw(st.floats(1e-3, 1.5)) * max(peak, 1e-3)
    b = sv.crossing(a, target, lo)
    if b is None:
        # Nothing reaches the target (checked at every breakpoint, where W peaks).
        assert target > peak * (1 - 1e-12)
    else:
        assert lo <= b < a
        assert abs(_brute_w(lower, upper, w, a, b) - target) <= 1e-9 * max(1.0, target)


@given(cells=cut_cells(), n=st.integers(1, 8), cap=st.floats(0.5, 40))
def test_placement_respects_cap_and_reports_real_volumes(
        cells: tuple[np.ndarray, np.ndarray, np.ndarray], n: int, cap: float) -> None:
    lower, upper, w = cells
    sv = SlabVolumes(lower, upper, w)
    top_u, bottom_u = floor_units(float(upper.max())), ceil_units(float(lower.min()))
    cap_u = floor_units(cap)
    res = place_equal_volume(sv, top_u, bottom_u, cap_u, n)
    h = res.heights
    assert h[0] == top_u and h[-1] == bottom_u
    assert all(x > y and x - y <= cap_u for x, y in itertools.pairwise(h))
    assert len(res.capped) == len(h) - 1


def test_constant_area_gives_even_equal_volume_slabs() -> None:
    # A pocket floor at 0 under a flat top at 12: the area cut is the same at every height.
    lower = np.zeros(10)
    upper = np.full(10, 12.0)
    sv = SlabVolumes(lower, upper, np.ones(10))
    res = place_equal_volume(sv, floor_units(12.0), 0, floor_units(100.0), 4)
    assert [x * QUANTUM for x in res.heights] == [12.0, 9.0, 6.0, 3.0, 0.0]
    assert res.capped == [False] * 4
    # A flute of 2.5 mm splits every slab: 5 even slabs, all set by the cap.
    res = place_equal_volume(sv, floor_units(12.0), 0, floor_units(2.5), 4)
    assert max(np.diff(res.heights) * -QUANTUM) <= 2.5
    assert len(res.capped) >= 5  # ceil(12 / 2.5)


@given(cells=cut_cells(), data=st.data())
def test_removed_between_matches_brute_force(
        cells: tuple[np.ndarray, np.ndarray, np.ndarray], data: st.DataObject) -> None:
    lower, upper, w = cells
    mid = lower + data.draw(st.floats(0, 1)) * (upper - lower)
    z = np.sort(np.concatenate((data.draw(hnp.arrays(np.float64, 5, elements=st.floats(
        float(lower.min()) - 2, float(upper.max()) + 2))), [lower.min(), upper.max()])))[::-1]
    got = removed_between(upper, mid, w, z)
    want = [float((w * np.clip(np.minimum(upper, a) - np.maximum(mid, b), 0, None)).sum())
            for a, b in itertools.pairwise(z)]
    np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-9)


def test_units_and_even_heights() -> None:
    assert ceil_units(1.0) * QUANTUM == 1.0 and floor_units(1.0) * QUANTUM == 1.0
    assert ceil_units(0.1) * QUANTUM >= 0.1 > floor_units(0.1) * QUANTUM
    assert ceil_units(0.1) - floor_units(0.1) == 1
    h = even_heights(100, 0, 3)
    assert h[0] == 100 and h[-1] == 0 and max(-np.diff(h)) - min(-np.diff(h)) <= 1
    assert volume_spread([1.0, 1.2, 9.0], [False, False, True]) == np.float64(1.2) - 1
    assert volume_spread([5.0], [False]) == 0.0


def test_terrace_rounds_up_to_the_next_height_and_never_above_previous() -> None:
    level = np.array([[0.0, 1.0], [2.5, 7.0]])
    prev = np.array([[9.0, 9.0], [3.0, 7.0]])
    out = terrace(level, prev, np.array([8.0, 4.0, 2.0, 1.0]))
    np.testing.assert_array_equal(out, [[1.0, 1.0], [3.0, 7.0]])
    np.testing.assert_array_equal(terrace(level, prev, np.array([])), prev)


def test_cell_weights_cover_the_input_once() -> None:
    w = cell_weights((3, 2), 4, (9, 7), 0.5)
    np.testing.assert_array_equal(w, [[8.0, 6.0], [8.0, 6.0], [2.0, 1.5]])
    assert w.sum() == 9 * 7 * 0.5
