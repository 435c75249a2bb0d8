"""Where a closed chain starts (its seam), the request option ``seam`` (issue 15, the
counts): ``"first_point"`` (the default, design.md: the chain starts at the first point)
or ``"free"`` (a closed curve with corners from its first corner, each run fitted both
ways; a corner-free loop from other seams and in both directions), in the core and over
HTTP."""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import pytest
from fastapi.testclient import TestClient
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from tests.test_arcs import assert_valid, dedup, dist_to_segment, jagged, kinks, seg_points
from tests.test_service_errors import assert_problem
from zwcore.arcs import _runs
from zwcore.arcs.fit import ArcChain, Segment, fit_arcs
from zwcore.errors import InvalidInputError


def _from_start(chain: ArcChain, pts: np.ndarray) -> np.ndarray:
    """The closed polyline ``pts`` ``(N, 2)`` given from where ``chain`` starts (the same
    polyline: the start inserted on its edge when between two points), after checking
    that ``chain.seam_index`` names that point or edge."""
    i = chain.seam_index
    start = np.array(chain.segments[0].start)
    scale = max(1.0, float(np.abs(pts).max()))
    edge = Segment("line", tuple(pts[i]), tuple(pts[(i + 1) % len(pts)]))
    assert dist_to_segment(start[None], edge)[0] <= 1e-9 * scale
    rolled = np.roll(pts, -i, axis=0)
    if math.dist(start, pts[i]) <= 1e-9 * scale:
        return rolled
    # (strictly inside the edge: the next point would have been named)
    assert math.dist(start, pts[(i + 1) % len(pts)]) > 1e-9 * scale
    return np.vstack([start, rolled[1:], rolled[:1]])


def _signed_area(poly: np.ndarray) -> float:
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def _chain_area(chain: ArcChain, step: float) -> float:
    return _signed_area(np.vstack([seg_points(s, step)[:-1] for s in chain.segments]))


def assert_valid_free(chain: ArcChain, pts: np.ndarray, tol: float) -> None:
    """A closed chain of ``seam="free"``: valid (tests/test_arcs.py's checks on the
    polyline given from its start) and running in the input's direction (its signed
    area has the input's sign, where the band cannot turn it: the areas differ by at
    most about the tolerance times both lengths)."""
    assert_valid(chain, _from_start(chain, pts), tol, True)
    area = _signed_area(pts)
    perimeter = float(np.hypot(*np.diff(np.vstack([pts, pts[:1]]), axis=0).T).sum())
    if abs(area) > 4.0 * tol * perimeter:
        assert _chain_area(chain, tol / 4.0) * area > 0.0


def _d_shape(n_arc: int, n_edge: int, roll: int) -> tuple[np.ndarray, np.ndarray]:
    """A "D": a half circle of radius 20 and its diameter, ``(N, 2)``, rolled by ``roll``
    points, and its two corners ``(2, 2)`` (where the diameter meets the arc)."""
    th = np.linspace(-0.5 * math.pi, 0.5 * math.pi, n_arc)
    arc = np.c_[20.0 * np.cos(th), 20.0 * np.sin(th)]
    y = np.linspace(20.0, -20.0, n_edge)[1:-1]
    edge = np.c_[np.zeros_like(y), y]
    pts = np.vstack([arc, edge])
    return np.roll(pts, -roll, axis=0), np.array([[0.0, -20.0], [0.0, 20.0]])


@pytest.mark.parametrize("roll", [0, 37, 90, 150])
def test_closed_curve_with_corners_starts_at_its_first_corner(roll):
    pts, corners = _d_shape(120, 40, roll)
    chain = fit_arcs(pts, 0.05, closed=True, seam="free")
    assert_valid_free(chain, pts, 0.05)
    # both corners kept sharp (about 90 degrees at the junctions the chain names)
    k = kinks(chain)
    assert len(chain.corners) == 2
    assert all(abs(k[c] - 0.5 * math.pi) < 0.1 for c in chain.corners)
    # the first corner met going round from the first point (by index in the input)
    first = min(int(np.argmin(np.hypot(*(pts - c).T))) for c in corners)
    assert chain.seam_index == first and not chain.seam_reversed
    assert math.dist(chain.segments[0].start, pts[first]) < 1e-9
    # the same count as the fit of the curve given from that corner on
    rolled = fit_arcs(np.roll(pts, -first, axis=0), 0.05, closed=True, seam="free")
    assert len(chain.segments) == len(rolled.segments)
    # the default still starts at the first point
    plain = fit_arcs(pts, 0.05, closed=True)
    assert plain.seam_index == 0 and not plain.seam_reversed
    assert math.dist(plain.segments[0].start, pts[0]) < 1e-9


def _loop(seed: int, n: int) -> np.ndarray:
    """A smooth star-ish loop ``(n, 2)`` (radius 15 with two harmonics), seeded."""
    rng = np.random.default_rng(seed)
    a2, a3 = rng.uniform(0.0, 2.0, 2)
    p2, p3 = rng.uniform(0.0, 2.0 * math.pi, 2)
    th = np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
    r = 15.0 + a2 * np.cos(2.0 * th + p2) + a3 * np.cos(3.0 * th + p3)
    return np.c_[r * np.cos(th), r * np.sin(th)]


@contextmanager
def _seams(seams: tuple[float, ...]) -> Iterator[None]:
    """:data:`zwcore.arcs._runs.LOOP_SEAMS` set to ``seams`` for a while."""
    old = _runs.LOOP_SEAMS
    _runs.LOOP_SEAMS = seams
    try:
        yield
    finally:
        _runs.LOOP_SEAMS = old


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 10_000), tol=st.sampled_from([0.05, 0.1]),
       backwards=st.booleans())
def test_free_loop_is_valid_and_never_longer(seed, tol, backwards):
    pts = _loop(seed, 300)
    if backwards:
        pts = pts[::-1].copy()
    chain = fit_arcs(pts, tol, closed=True, seam="free")
    assert chain.corners == ()
    assert_valid_free(chain, pts, tol)
    assert kinks(chain).max() <= 1e-9  # C1 at the seam too
    with _seams(()):
        first_point_only = fit_arcs(pts, tol, closed=True, seam="free")
    assert first_point_only.seam_index == 0
    # the other seams and the other direction only replace the chain by a shorter one
    assert len(chain.segments) <= len(first_point_only.segments)


def _glyph(label: str, sampling: str) -> np.ndarray:
    from glyphs import glyph_contours

    ((_label, pts, _corners),) = [
        c for c in glyph_contours(label[0])[sampling] if c[0] == label]
    return pts


def test_glyph_loop_from_another_seam_saves_segments():
    # the outer loop of DejaVu Sans "g" (no corners): its first point is a bad seam at
    # 0.05 (the first fit closes with a short biarc); another seam needs fewer segments
    pts = _glyph("g0", "even")
    chain = fit_arcs(pts, 0.05, closed=True, seam="free")
    with _seams(()):
        first_point_only = fit_arcs(pts, 0.05, closed=True, seam="free")
    assert math.dist(first_point_only.segments[0].start, pts[0]) < 1e-9
    assert len(chain.segments) < len(first_point_only.segments)
    assert math.dist(chain.segments[0].start, pts[0]) > 1.0
    assert chain.corners == ()
    assert_valid_free(chain, pts, 0.05)
    assert kinks(chain).max() <= 1e-9


def test_glyph_loop_fitted_backwards_is_returned_forwards():
    # the counter of "d" sampled chordally at 0.05: the reversed fit saves a segment
    pts = _glyph("d1", "chordal")
    chain = fit_arcs(pts, 0.05, closed=True, seam="free")
    # (the reversed curve from the same first point)
    back = fit_arcs(np.roll(pts[::-1], 1, axis=0), 0.05, closed=True, seam="free")
    assert chain.seam_reversed and not back.seam_reversed
    assert len(chain.segments) == len(back.segments) < len(
        fit_arcs(pts, 0.05, closed=True).segments)
    assert_valid_free(chain, pts, 0.05)
    # the same chain as the reversed fit, run the other way
    assert chain.segments[0].start == back.segments[-1].end
    for s, b in zip(chain.segments, reversed(back.segments), strict=True):
        assert (s.kind, s.start, s.end, s.radius) == (b.kind, b.end, b.start, b.radius)
        if s.kind == "arc":
            assert s.sweep == -b.sweep and s.ccw != b.ccw


@pytest.mark.parametrize("label", ["d0", "@1", "R0"])
def test_runs_fitted_both_ways_are_valid_and_never_longer(label, monkeypatch):
    # glyph contours with corners: each run between corners also fitted backwards, the
    # fewer pieces kept, turned back to the input's direction
    pts = _glyph(label, "noisy")
    chain = fit_arcs(pts, 0.05, closed=True, seam="free")
    assert_valid_free(chain, pts, 0.05)
    assert chain.corners
    monkeypatch.setattr(_runs, "_reverse_runs", lambda *a: True)
    forwards = fit_arcs(pts, 0.05, closed=True, seam="free")
    assert len(chain.segments) <= len(forwards.segments)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(jagged())
def test_free_seam_never_fails_on_jagged_curves(case):
    # random polygons, walks with repeats, hairpins, exact reversals (test_arcs.py),
    # closed: valid chains from wherever they start, in the input's direction
    pts, tol, _closed = case
    assume(len(dedup(pts, True, tol)) >= 2)
    chain = fit_arcs(pts, tol, closed=True, seam="free")
    assert_valid_free(chain, pts, tol)


def test_open_curves_and_the_default_are_unchanged():
    th = np.linspace(0.0, 3.0, 200)
    pts = np.c_[30.0 * np.cos(th), 12.0 * np.sin(th)]
    assert fit_arcs(pts, 0.05, seam="free") == fit_arcs(pts, 0.05)
    loop = _loop(3, 300)
    assert fit_arcs(loop, 0.05, closed=True) == fit_arcs(
        loop, 0.05, closed=True, seam="first_point")


def test_bad_seam_is_refused():
    with pytest.raises(InvalidInputError) as exc:
        fit_arcs([[0, 0], [1, 1]], 0.1, seam="middle")  # type: ignore[arg-type]
    assert exc.value.field == "seam"


# ----------------------------------------------------------------------------
# over HTTP


def test_http_free_seam_is_reported(client: TestClient) -> None:
    pts, _corners = _d_shape(120, 40, 90)
    body = {"points": pts.tolist(), "tolerance": 0.05, "closed": True}
    plain = client.post("/v1/arcs", json=body)
    free = client.post("/v1/arcs", json={**body, "seam": "free"})
    assert plain.status_code == free.status_code == 200, (plain.text, free.text)
    p, f = plain.json(), free.json()
    # two tasks: a cached chain of one seam is never served for the other
    assert p["task_id"] != f["task_id"]
    assert p["seam"] == {"mode": "first_point", "index": 0, "start": pts[0].tolist(),
                         "reversed": False}
    assert p["segments"][0]["start"] == pts[0].tolist()
    # the free chain starts at the D's first corner (an input point), as the core's does
    chain = fit_arcs(pts, 0.05, closed=True, seam="free")
    assert f["seam"]["mode"] == "free" and f["seam"]["index"] == chain.seam_index
    assert f["seam"]["start"] == f["segments"][0]["start"] == list(pts[chain.seam_index])
    assert f["summary"]["n_segments"] == len(chain.segments) <= p["summary"]["n_segments"]
    assert f["segments"][-1]["end"] == f["segments"][0]["start"]


@pytest.mark.parametrize("seam", ["middle", 1, None, "FREE"])
def test_http_bad_seam_is_a_problem(client: TestClient, seam: object) -> None:
    body = {"points": [[0, 0], [1, 0], [1, 1]], "closed": True, "seam": seam}
    assert_problem(client.post("/v1/arcs", json=body), 422, "seam")
