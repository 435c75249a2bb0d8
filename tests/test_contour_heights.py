"""Slab-volume function, equal-volume placement and terraces, against brute force."""

from __future__ import annotations

import itertools

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from zwcore.contour.heights import (
    QUANTUM,
    SlabVolumes,
    ceil_units,
    even_heights,
    floor_units,
    place_equal_volume,
    removed_between,
    volume_spread,
)
from zwcore.mrr.terraces import cell_weights, terrace


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
    # Honest flags: a capped slab is exactly the flute length and removes less
    # than the target, so no slab on its bottom height within the flute could
    # (W grows with the slab's top).
    vols = [_brute_w(lower, upper, w, a * QUANTUM, b * QUANTUM) for a, b in itertools.pairwise(h)]
    for (a, b), v, c in zip(itertools.pairwise(h), vols, res.capped, strict=True):
        if c:
            assert a - b == cap_u
            assert v < res.target
    # The reported spread is over every slab not flagged.
    free = [v for v, c in zip(vols, res.capped, strict=True) if not c]
    if len(free) >= 2 and min(free) > 0:
        assert abs(volume_spread(vols, res.capped) - (max(free) / min(free) - 1)) <= 1e-6


@given(cells=cut_cells(), data=st.data())
def test_rise_is_exact(cells: tuple[np.ndarray, np.ndarray, np.ndarray],
                       data: st.DataObject) -> None:
    lower, upper, w = cells
    sv = SlabVolumes(lower, upper, w)
    b = float(data.draw(st.sampled_from(sorted(set(lower.tolist())))))
    top = float(upper.max())
    peak = _brute_w(lower, upper, w, top, b)
    target = data.draw(st.floats(1e-3, 1.5)) * max(peak, 1e-3)
    a = sv.rise(b, target, top)
    if a is None:
        assert target > peak * (1 - 1e-12)
    else:
        assert b < a <= top
        assert abs(_brute_w(lower, upper, w, a, b) - target) <= 1e-9 * max(1.0, target)
        # The lowest such top: W grows with a, so just below it W is short.
        lower_a = b + (a - b) * (1 - 1e-6)
        assert _brute_w(lower, upper, w, lower_a, b) < target


def test_thin_tail_gets_flute_length_slabs_not_a_leftover() -> None:
    # 100 cells cut from 20 to 10 and one cell reaching 27 mm deeper: below 10
    # only that cell is cut, too little area for the slab volume within an 8 mm
    # flute. The tail must be covered by slabs of exactly 8 mm (flagged) and the
    # rest must be equal in volume; 37 mm is no multiple of 8, so the count and
    # the heights have to absorb the misfit. (The old placement ended with a
    # thinner bottom slab that it flagged as capped.)
    lower = np.concatenate((np.full(100, 10.0), [-27.0]))
    lower[:50] += np.linspace(0.0, 4.0, 50)  # some spread in the shelf
    upper = np.full(101, 20.0)
    sv = SlabVolumes(lower, upper, np.ones(101))
    res = place_equal_volume(sv, floor_units(20.0), ceil_units(-27.0), floor_units(8.0), 9)
    h = np.array(res.heights) * QUANTUM
    sp = -np.diff(h)
    vols = np.array([float(sv.volume(a, [b])[0]) for a, b in itertools.pairwise(h)])
    assert h[0] == 20.0 and h[-1] == -27.0
    capped = np.array(res.capped)
    assert capped.any()
    assert np.all(sp[capped] == 8.0)
    free = vols[~capped]
    assert free.size >= 2 and free.max() / free.min() - 1 <= 0.01, (h, vols, capped)


def test_constant_area_gives_even_equal_volume_slabs() -> None:
    # A pocket floor at 0 under a flat top at 12: the area cut is the same at every height.
    lower = np.zeros(10)
    upper = np.full(10, 12.0)
    sv = SlabVolumes(lower, upper, np.ones(10))
    res = place_equal_volume(sv, floor_units(12.0), 0, floor_units(100.0), 4)
    assert [x * QUANTUM for x in res.heights] == [12.0, 9.0, 6.0, 3.0, 0.0]
    assert res.capped == [False] * 4
    # A flute of 2.5 mm needs at least 5 slabs.
    res = place_equal_volume(sv, floor_units(12.0), 0, floor_units(2.5), 4)
    assert max(np.diff(res.heights) * -QUANTUM) <= 2.5
    assert len(res.capped) >= 5  # ceil(12 / 2.5)
    # Five equal 2.4 mm slabs fit the flute: none is capped.
    assert res.capped == [False] * 5
    np.testing.assert_allclose(np.array(res.heights) * QUANTUM, [12.0, 9.6, 7.2, 4.8, 2.4, 0.0],
                               rtol=0, atol=8 * QUANTUM)


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
