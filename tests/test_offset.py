"""Tool offset of a chain: stays C1 and at |d| from the original."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from zwcore.arcs.fit import ArcChain, fit_arcs
from zwcore.arcs.offset import offset_chain
from zwcore.errors import InvalidInputError

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from curves import BENCH_CURVES
from test_arcs import dist_to_segment, seg_points


def dist_to_chain(pts: np.ndarray, chain: ArcChain) -> np.ndarray:
    d = np.full(len(pts), np.inf)
    for s in chain.segments:
        d = np.minimum(d, dist_to_segment(pts, s))
    return d


@pytest.mark.parametrize(
    ("name", "dist"),
    # the airfoil only outwards: inside, its thin trailing edge is closer than 2 mm
    [("ellipse", 2.0), ("ellipse", -2.0), ("sine", 2.0), ("sine", -2.0),
     ("clothoid", 2.0), ("clothoid", -2.0), ("naca2412", -2.0)],
)
def test_offset_is_c1_and_at_distance(name, dist):
    pts, closed = BENCH_CURVES[name]()
    chain = fit_arcs(pts, 0.1, closed=closed)
    off, vanished, reversed_ = offset_chain(chain, dist)
    assert vanished == () and reversed_ == ()
    assert len(off.segments) == len(chain.segments)
    assert off.corners == ()
    assert off.max_kink_smooth <= 1e-9
    assert np.allclose(off.kinks(), 0.0, atol=1e-9)
    for a, b in zip(off.segments[:-1], off.segments[1:], strict=True):
        assert math.dist(a.end, b.start) < 1e-9
    # every offset point is at |d| from the original chain
    dense = np.vstack([seg_points(s, 0.05) for s in off.segments])
    d = dist_to_chain(dense, chain)
    assert np.allclose(d, abs(dist), atol=1e-6)


def test_left_is_positive():
    chain = fit_arcs([[0, 0], [10, 0]], 0.1)
    off, _, _ = offset_chain(chain, 1.5)
    assert off.segments[0].start == pytest.approx((0.0, 1.5))
    off, _, _ = offset_chain(chain, -1.5)
    assert off.segments[0].start == pytest.approx((0.0, -1.5))


def test_vanishing_arcs_are_reported():
    pts, closed = BENCH_CURVES["ellipse"]()
    chain = fit_arcs(pts, 0.1, closed=closed)
    rmin = min(s.radius for s in chain.segments if s.kind == "arc")
    off, vanished, _ = offset_chain(chain, rmin + 1.0)  # inside: ccw radii shrink
    expect = tuple(i for i, s in enumerate(chain.segments)
                   if s.kind == "arc" and s.ccw and s.radius <= rmin + 1.0)
    assert vanished == expect and len(vanished) > 0
    for a, b in zip(off.segments[:-1], off.segments[1:], strict=True):
        assert math.dist(a.end, b.start) < 1e-6


def test_die_edge_corners_are_rounded_outside_and_trimmed_inside():
    pts, closed = BENCH_CURVES["die_edge"]()
    chain = fit_arcs(pts, 0.1, closed=closed)
    for dist in (3.0, -3.0):
        off, vanished, reversed_ = offset_chain(chain, dist)
        assert vanished == () and reversed_ == ()
        for a, b in zip(off.segments[:-1], off.segments[1:], strict=True):
            assert math.dist(a.end, b.start) < 1e-6
        # one corner is outside (rounded, C1) and one inside (trimmed, sharp)
        assert len(off.corners) == 1
        dense = np.vstack([seg_points(s, 0.05) for s in off.segments])
        d = dist_to_chain(dense, chain)
        assert d.min() >= 3.0 - 1e-6


def test_bad_offset_is_rejected():
    chain = fit_arcs([[0, 0], [1, 0]], 0.1)
    with pytest.raises(InvalidInputError) as err:
        offset_chain(chain, float("nan"))
    assert err.value.field == "offset"


@pytest.mark.parametrize(("dist", "expect"), [(100.0, (0, 1)), (10.0, (0, 1)), (9.0, ()),
                                              (-100.0, ()), (5.0, ())])
def test_reversed_lines_are_reported(dist, expect):
    """An L of two 10 mm lines offset into its inner corner by more than 10 mm: the
    trimmed offset lines run backwards; they are reported, not silently emitted."""
    chain = fit_arcs([[0, 0], [10, 0], [10, 10]], 0.1)
    assert chain.n_lines == 2 and chain.corners == (0,)
    off, vanished, reversed_ = offset_chain(chain, dist)
    assert vanished == ()
    assert reversed_ == expect
    for i in range(2):
        seg = off.segments[0] if i == 0 else off.segments[-1]
        orig = chain.segments[i]
        back = float(np.subtract(seg.end, seg.start) @ np.subtract(orig.end, orig.start)) <= 0
        assert back == (i in expect)


@pytest.mark.parametrize("dist", [10.0, -10.0, 25.0, -25.0, 40.0, -40.0])
def test_die_edge_reversals_match_geometry(dist):
    """Every line of the die-edge offset that runs against its original is reported,
    and nothing else is."""
    pts, closed = BENCH_CURVES["die_edge"]()
    chain = fit_arcs(pts, 0.1, closed=closed)
    res = offset_chain(chain, dist)
    off = res.chain
    # map offset segments back: non-rounding pieces keep their order
    segs = list(off.segments)
    j = 0
    seen_back = []
    for i, orig in enumerate(chain.segments):
        # skip the rounding arcs at outer corners (centred on a corner point, radius |d|)
        while (segs[j].kind == "arc" and orig.kind == "line"
               and abs(segs[j].radius - abs(dist)) < 1e-9 and i - 1 in chain.corners):
            j += 1
        if orig.kind == "line" and segs[j].kind == "line":
            o = np.subtract(orig.end, orig.start)
            s = np.subtract(segs[j].end, segs[j].start)
            if float(o @ s) <= 0:
                seen_back.append(i)
        j += 1
    assert tuple(seen_back) == tuple(i for i in res.reversed
                                     if chain.segments[i].kind == "line")
    assert all(0 <= i < len(chain.segments) for i in res.reversed + res.vanished)
    if abs(dist) >= 25.0:
        assert seen_back
