"""Tests of the C1 arc fit (design section 5).

The two-sided tolerance is checked independently of the fitter: both the chain
and the input polyline are sampled densely and brute-force distances are taken
to the other side's exact geometry (segments, arcs).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, example, given, settings
from hypothesis import strategies as st

from zwcore.arcs.fit import ArcChain, Segment, fit_arcs
from zwcore.errors import InvalidInputError

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
import itertools

from curves import ARCWELDER_REFERENCE, BENCH_CURVES, coarse_ellipse
from glyphs import ARCWELDER_GLYPH_REFERENCE

# ----------------------------------------------------------------------------
# independent geometry helpers


def seg_points(seg: Segment, step: float) -> np.ndarray:
    s = np.array(seg.start)
    if seg.kind == "line":
        e = np.array(seg.end)
        n = max(int(np.ceil(np.hypot(*(e - s)) / step)), 1) + 1
        f = np.linspace(0, 1, n)[:, None]
        return s + f * (e - s)
    c = np.array(seg.center)
    n = max(int(np.ceil(abs(seg.sweep) * seg.radius / step)), 1) + 1
    a0 = math.atan2(s[1] - c[1], s[0] - c[0])
    ang = a0 + np.linspace(0, seg.sweep, n)
    return c + seg.radius * np.stack([np.cos(ang), np.sin(ang)], axis=1)


def dist_to_polyline(pts: np.ndarray, poly: np.ndarray) -> np.ndarray:
    a, b = poly[:-1], poly[1:]
    ab = b - a
    den = np.maximum((ab * ab).sum(1), 1e-300)
    out = np.full(len(pts), np.inf)
    chunk = max(1, int(4e6 // max(len(a), 1)))
    for i in range(0, len(pts), chunk):
        p = pts[i : i + chunk]
        ap = p[:, None, :] - a[None]
        t = np.clip((ap * ab[None]).sum(-1) / den[None], 0, 1)
        d = np.hypot(*(ap - t[..., None] * ab[None]).transpose(2, 0, 1))
        out[i : i + chunk] = d.min(1)
    return out


def dist_to_segment(pts: np.ndarray, seg: Segment) -> np.ndarray:
    s = np.array(seg.start)
    e = np.array(seg.end)
    if seg.kind == "line":
        ab = e - s
        t = np.clip(((pts - s) @ ab) / max(ab @ ab, 1e-300), 0, 1)
        return np.hypot(*(pts - s - t[:, None] * ab).T)
    c = np.array(seg.center)
    rel = pts - c
    a0 = math.atan2(s[1] - c[1], s[0] - c[0])
    ang = np.arctan2(rel[:, 1], rel[:, 0]) - a0
    ang = np.mod(ang, 2 * np.pi) if seg.sweep > 0 else -np.mod(-ang, 2 * np.pi)
    inside = np.abs(ang) <= abs(seg.sweep)
    d_circle = np.abs(np.hypot(*rel.T) - seg.radius)
    d_ends = np.minimum(np.hypot(*(pts - s).T), np.hypot(*(pts - e).T))
    return np.where(inside, np.minimum(d_circle, d_ends), d_ends)


def two_sided(chain: ArcChain, points: np.ndarray, closed: bool, tol: float) -> tuple[float, float]:
    poly = np.vstack([points, points[:1]]) if closed else points
    step = tol / 8
    # polyline -> chain
    seglen = np.hypot(*np.diff(poly, axis=0).T)
    dense = [poly[-1:]]
    for i in range(len(poly) - 1):
        n = max(int(np.ceil(seglen[i] / step)), 1)
        f = np.arange(n)[:, None] / n
        dense.append(poly[i] + f * (poly[i + 1] - poly[i]))
    dp = np.vstack(dense)
    d1 = np.full(len(dp), np.inf)
    for seg in chain.segments:
        d1 = np.minimum(d1, dist_to_segment(dp, seg))
    # chain -> polyline
    cp = np.vstack([seg_points(s, step) for s in chain.segments])
    d2 = dist_to_polyline(cp, poly)
    return float(d1.max()), float(d2.max())


def seg_tangent(seg: Segment, at_end: bool) -> np.ndarray:
    """Unit tangent from the segment's own geometry: a line's direction; for an arc the
    perpendicular of (end point - centre), turned the way the sweep goes."""
    if seg.kind == "line":
        d = np.subtract(seg.end, seg.start)
        return d / np.hypot(*d)
    r = np.subtract(seg.end if at_end else seg.start, seg.center)
    t = np.array([-r[1], r[0]]) if seg.sweep > 0 else np.array([r[1], -r[0]])
    return t / np.hypot(*t)


def _seg_scale(seg: Segment) -> float:
    """The length over which a rounding error of an end point or centre turns the
    tangent: the segment's length (its radius, if smaller)."""
    return min(seg.length, seg.radius) if seg.kind == "arc" else seg.length


def kinks(chain: ArcChain) -> np.ndarray:
    """Tangent turn at every junction, from the segments' geometry (not chain.kinks())."""
    segs = chain.segments
    n = len(segs)
    m = n if chain.closed else n - 1
    out = np.zeros(max(m, 0))
    for i in range(max(m, 0)):
        a = seg_tangent(segs[i], True)
        b = seg_tangent(segs[(i + 1) % n], False)
        out[i] = abs(math.atan2(a[0] * b[1] - a[1] * b[0], a @ b))
    return out


def kink_bounds(chain: ArcChain, coord_scale: float) -> np.ndarray:
    """What float64 allows at each junction: the end points and centres carry rounding
    errors of a few ulp of the coordinates (``coord_scale``), which turn a tangent by
    about that much over the segment's length. The junction is computed through a chain
    of operations on coordinates of that size: 47 ulp was the worst over 1,500 random
    polygons, then a random polygon hit 140, so the bound is 1024 ulp (still ~1e-13 rad
    on a unit-sized curve: numerical zero, orders below any machine's resolution)."""
    segs = chain.segments
    n = len(segs)
    m = n if chain.closed else n - 1
    ulp = np.finfo(float).eps * coord_scale
    out = np.zeros(max(m, 0))
    for i in range(max(m, 0)):
        a, b = segs[i], segs[(i + 1) % n]
        out[i] = 1024.0 * ulp * (1.0 / _seg_scale(a) + 1.0 / _seg_scale(b)) + 1e-14
    return out


def assert_valid(chain: ArcChain, points: np.ndarray, tol: float, closed: bool) -> None:
    pts = np.asarray(points, dtype=float)
    scale = max(1.0, float(np.abs(pts).max()))
    segs = chain.segments
    assert segs, "empty chain"
    assert chain.forced_corners == ()
    # starts at the first point, ends at the last (or closes)
    assert np.allclose(segs[0].start, pts[0], atol=1e-9 * scale, rtol=0)
    if closed:
        assert np.allclose(segs[-1].end, segs[0].start, atol=1e-9 * scale, rtol=0)
    else:
        assert np.allclose(segs[-1].end, pts[-1], atol=1e-9 * scale, rtol=0)
    # continuity and well-formed arcs
    for a, b in itertools.pairwise(segs):
        assert np.allclose(a.end, b.start, atol=1e-9 * scale, rtol=0)
    for s in segs:
        vals = [*s.start, *s.end]
        if s.kind == "arc":
            vals += [*s.center, s.radius, s.sweep]
            r0 = math.dist(s.start, s.center)
            r1 = math.dist(s.end, s.center)
            assert abs(r0 - s.radius) <= 1e-9 * max(scale, s.radius)
            assert abs(r1 - s.radius) <= 1e-9 * max(scale, s.radius)
            assert (s.sweep > 0) == s.ccw
        assert all(math.isfinite(v) for v in vals)
    # C1 except at corners: kinks measured from the segments' geometry, at the
    # rounding level of the coordinates (extent of the curve included: the fit works
    # relative to the first point)
    k = kinks(chain)
    extent = float(np.ptp(pts, axis=0).max())
    bound = kink_bounds(chain, float(np.abs(pts).max()) + extent)
    for jn, kv in enumerate(k):
        if jn not in chain.corners:
            assert kv <= bound[jn], (jn, kv, bound[jn])
    smooth = [jn for jn in range(len(k)) if jn not in chain.corners]
    if smooth:
        assert chain.max_kink_smooth <= 4.0 * max(bound[jn] for jn in smooth)
    # two-sided tolerance by dense sampling
    d1, d2 = two_sided(chain, pts, closed, tol)
    slack = 1e-9 * scale
    assert d1 <= tol + slack, ("polyline -> chain", d1)
    assert d2 <= tol + slack, ("chain -> polyline", d2)
    assert chain.max_deviation_points <= tol + slack
    assert chain.max_deviation_chain <= tol + slack


def dedup(points: np.ndarray, closed: bool, tol: float, *, widest: bool = True) -> np.ndarray:
    """The distinct points as fit_arcs documents them: closer than 1e-9 * tol (or
    1e-14 of the coordinates' magnitude) is a repeat. The magnitude fit_arcs uses
    lies between max|p| and 2 max|p|; ``widest`` takes the larger repeat radius (fewest
    distinct points), otherwise the smaller (most)."""
    mag = float(np.abs(points).max()) * (2.0 if widest else 1.0)
    eps = max(1e-9 * tol, 1e-14 * mag)
    keep = [0]
    for i in range(1, len(points)):
        if np.hypot(*(points[i] - points[keep[-1]])) > eps:
            keep.append(i)
    out = points[keep]
    if closed:
        while len(out) > 1 and np.hypot(*(out[-1] - out[0])) <= eps:
            out = out[:-1]
    return out


# ----------------------------------------------------------------------------
# the benchmark curves


@pytest.fixture(scope="module")
def bench_chains() -> dict[str, tuple[np.ndarray, bool, ArcChain]]:
    out = {}
    for name, make in BENCH_CURVES.items():
        pts, closed = make()
        out[name] = (pts, closed, fit_arcs(pts, 0.1, closed=closed))
    return out


@pytest.mark.parametrize("name", list(BENCH_CURVES))
def test_bench_curve_chain_is_valid(name, bench_chains):
    pts, closed, chain = bench_chains[name]
    assert_valid(chain, pts, 0.1, closed)


@pytest.mark.parametrize("name", [n for n, r in ARCWELDER_REFERENCE.items() if r[0] is not None])
def test_no_more_segments_than_arcwelder(name, bench_chains):
    _pts, _closed, chain = bench_chains[name]
    arcs, lines = ARCWELDER_REFERENCE[name]
    # Design target: no more segments than ArcWelder, whose arcs are fitted one by one
    # (not C1).
    assert len(chain.segments) <= arcs + (lines or 0)


@pytest.fixture(scope="module")
def glyph_sets() -> dict[str, list[tuple[str, np.ndarray, np.ndarray]]]:
    from glyphs import glyph_contours

    return glyph_contours()


#: glyph rows where the C1 fit still needs more segments than ArcWelder (issue 15: the
#: beam is 7-13 % above the asymptotic floor of joined chains, which C1 does not raise;
#: docs/arcs.md "Counts against ArcWelder"), per ``seam``: with ``"free"`` (the chain
#: of a closed curve may start elsewhere, runs fitted both ways) chordal 0.01 is at 562
#: of 563; chordal 0.05 (369 of 333) and noisy 0.05 (417 of 374) are still over (the local
#: model of bench/c1_floor.py: C1 chains need about 53 pieces more than C0 ones, 395 vs 342)
_GLYPH_ROWS_OVER = {
    "first_point": {("chordal", 0.05), ("noisy", 0.05), ("chordal", 0.01)},
    "free": {("chordal", 0.05), ("noisy", 0.05)},
}


@pytest.mark.parametrize(("seam", "row"), [
    pytest.param(seam, r, marks=pytest.mark.xfail(
        strict=True, reason="issue 15: more segments than ArcWelder on this row"))
    if r in _GLYPH_ROWS_OVER[seam] else (seam, r)
    for seam in ("first_point", "free") for r in ARCWELDER_GLYPH_REFERENCE],
    ids=lambda v: v if isinstance(v, str) else f"{v[0]}-{v[1]}")
def test_glyph_row_no_more_segments_than_arcwelder(seam, row, glyph_sets):
    # the target: at most ArcWelder's segments (measured with its binary and
    # stored) in every row of the glyph table, the total over the row's 34 contours
    name, tol = row
    total = sum(len(fit_arcs(pts, tol, closed=True, seam=seam).segments)
                for _label, pts, _corners in glyph_sets[name])
    assert total <= ARCWELDER_GLYPH_REFERENCE[row]


def test_circle_is_one_full_arc(bench_chains):
    _, _, chain = bench_chains["circle"]
    (seg,) = chain.segments
    assert seg.kind == "arc" and abs(seg.radius - 50.0) < 0.1
    assert abs(abs(seg.sweep) - 2 * math.pi) < 1e-9


def test_die_edge_keeps_its_two_sharp_corners(bench_chains):
    pts, _, chain = bench_chains["die_edge"]
    assert len(chain.corners) == 2
    k = kinks(chain)
    for c in chain.corners:
        assert k[c] > math.radians(60)
        # the corner sits on an input point (the vertex)
        corner_pt = np.array(chain.segments[c].end)
        assert np.min(np.hypot(*(pts - corner_pt).T)) < 1e-9
    assert chain.n_lines >= 3


# ----------------------------------------------------------------------------
# straight runs and corners


@pytest.mark.parametrize("seed", range(5))
def test_noisy_straight_line_is_one_line(seed):
    rng = np.random.default_rng(seed)
    x = np.sort(rng.uniform(0, 150, 400))
    ang = rng.uniform(-np.pi, np.pi)
    pts = np.stack([x, rng.uniform(-0.03, 0.03, x.size)], axis=1)
    rot = np.array([[np.cos(ang), -np.sin(ang)], [np.sin(ang), np.cos(ang)]])
    pts = pts @ rot.T + rng.uniform(-1000, 1000, 2)
    chain = fit_arcs(pts, 0.1)
    assert len(chain.segments) == 1 and chain.segments[0].kind == "line"
    assert_valid(chain, pts, 0.1, False)


def flat_arcs(chain: ArcChain, tol: float) -> list[int]:
    """Arcs of "huge radius": at least 20 tolerances long with a sagitta below a quarter
    tolerance (their chord, a line, lies within tol/4 of them: a line would do).

    Equivalently: radius > 2 length^2 / tol for small sweeps, e.g. radius > 800 mm for a
    20 mm arc at tol 0.1."""
    out = []
    for i, s in enumerate(chain.segments):
        if s.kind == "arc" and s.length >= 20 * tol:
            sag = s.radius * (1 - math.cos(0.5 * min(abs(s.sweep), math.pi)))
            if sag < 0.25 * tol:
                out.append(i)
    return out


def test_die_edge_straight_runs_are_lines(bench_chains):
    """The die edge is 7 lines and 5 tangent fillets: every line comes out as a line
    (no arc of huge radius over a straight run), the fillets as arcs of their radius."""
    _pts, _, chain = bench_chains["die_edge"]
    assert flat_arcs(chain, 0.1) == []
    assert chain.n_lines == 7 and chain.n_arcs == 5
    radii = sorted(s.radius for s in chain.segments if s.kind == "arc")
    assert radii == pytest.approx([8.0, 10.0, 15.0, 25.0, 25.0], abs=1.0)


def test_naca_rear_lower_surface_is_a_line(bench_chains):
    _, _, chain = bench_chains["naca2412"]
    assert flat_arcs(chain, 0.1) == []
    last = chain.segments[-1]
    assert last.kind == "line" and last.length > 40.0


def test_readme_example_has_no_huge_arc():
    pts = np.array([[0, 0], [10, 0], [20, 0], [27.07, 2.93], [30, 10]], dtype=float)
    chain = fit_arcs(pts, 0.05)
    assert flat_arcs(chain, 0.05) == []
    assert chain.n_lines == 3
    assert_valid(chain, pts, 0.05, False)


def lines_and_fillets_curve(
    lengths: list[float], turns: list[float], radii: list[float], step: float,
    noise: float, head: float, noise_seed: int, shift: np.ndarray,
) -> tuple[np.ndarray, list[tuple[np.ndarray, np.ndarray]], float]:
    """Lines (nominal ``lengths``) joined by tangent fillet arcs (signed ``turns`` in
    degrees, ``radii``), a die edge without corners, sampled every ``step`` mm, with
    uniform noise of amplitude ``noise`` and shifted by ``shift``.

    Returns the points, the straight parts' (start, end) and the noise amplitude."""
    n = len(lengths)
    pos = np.zeros(2)
    fine: list[np.ndarray] = [pos[None]]
    straight: list[tuple[np.ndarray, np.ndarray]] = []
    for i in range(n):
        # the straight part between the fillets' tangent points
        cut0 = radii[i - 1] * math.tan(math.radians(abs(turns[i - 1])) / 2) if i > 0 else 0.0
        cut1 = radii[i] * math.tan(math.radians(abs(turns[i])) / 2) if i < n - 1 else 0.0
        length = max(lengths[i] - cut0 - cut1, 5.0)
        d = np.array([math.cos(head), math.sin(head)])
        s = np.linspace(0, length, 400)[1:]
        straight.append((pos.copy(), pos + length * d))
        fine.append(pos + s[:, None] * d)
        pos = pos + length * d
        if i < n - 1:
            turn = math.radians(turns[i])
            sg = 1.0 if turn > 0 else -1.0
            c = pos + sg * radii[i] * np.array([-d[1], d[0]])
            a0 = head - sg * math.pi / 2
            ang = a0 + np.linspace(0, turn, 400)[1:]
            fine.append(c + radii[i] * np.stack([np.cos(ang), np.sin(ang)], 1))
            pos = fine[-1][-1].copy()
            head += turn
    xy = np.vstack(fine)
    cum = np.concatenate([[0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])
    at = np.linspace(0, cum[-1], max(int(cum[-1] / step), 2) + 1)
    pts = np.stack([np.interp(at, cum, xy[:, 0]), np.interp(at, cum, xy[:, 1])], 1)
    if noise:
        rng = np.random.default_rng(noise_seed)
        pts = pts + rng.uniform(-noise, noise, pts.shape)
    return pts + shift, [(a + shift, b + shift) for a, b in straight], noise


#: noise amplitudes of the lines-and-fillets curves (half of them noise-free)
LF_NOISES = (0.0, 0.0, 0.02, 0.03)


@st.composite
def lines_and_fillets(draw):
    """:func:`lines_and_fillets_curve` with hypothesis-drawn parameters."""
    n = draw(st.integers(2, 5))
    lengths = [draw(st.floats(12.0, 60.0)) for _ in range(n)]
    turns = [draw(st.floats(15.0, 150.0)) * draw(st.sampled_from([-1, 1]))
             for _ in range(n - 1)]
    radii = [draw(st.floats(2.0, 30.0)) for _ in range(n - 1)]
    step = draw(st.floats(0.2, 1.0))
    noise = draw(st.sampled_from(LF_NOISES))
    head = draw(st.floats(-3.2, 3.2))
    seed = draw(st.integers(0, 2**31)) if noise else 0
    shift = np.array([draw(st.floats(-1e4, 1e4)), draw(st.floats(-1e4, 1e4))])
    return lines_and_fillets_curve(lengths, turns, radii, step, noise, head, seed, shift)


def random_lines_and_fillets(rng: np.random.Generator):
    """:func:`lines_and_fillets_curve` with the distributions of :func:`lines_and_fillets`
    drawn from a numpy generator (uniform where hypothesis draws floats)."""
    n = int(rng.integers(2, 6))
    lengths = list(rng.uniform(12.0, 60.0, n))
    turns = list(rng.uniform(15.0, 150.0, n - 1) * rng.choice([-1.0, 1.0], n - 1))
    radii = list(rng.uniform(2.0, 30.0, n - 1))
    step = float(rng.uniform(0.2, 1.0))
    noise = float(rng.choice(LF_NOISES))
    head = float(rng.uniform(-3.2, 3.2))
    seed = int(rng.integers(0, 2**31))
    shift = rng.uniform(-1e4, 1e4, 2)
    return lines_and_fillets_curve(lengths, turns, radii, step, noise, head, seed, shift)


def assert_gives_lines(pts: np.ndarray, straight, tol: float = 0.1) -> None:
    """No arc of huge radius, and every straight part of 15 mm (150 tolerances) or more
    is followed by one chain line over at least half of it."""
    chain = fit_arcs(pts, tol, corner_angle_deg=179.0)
    assert flat_arcs(chain, tol) == [], [
        (s.length, s.radius) for s in chain.segments if s.kind == "arc"]
    lines = [s for s in chain.segments if s.kind == "line"]
    for a, b in straight:
        length = float(np.hypot(*(b - a)))
        if length < 15.0:
            continue
        d = (b - a) / length
        # the longest chain line lying along this straight part: within the tolerance
        # of it where they overlap (beyond its ends the fillets turn away, and a line
        # that runs on a little past an end may leave the part's line there)
        best = 0.0
        for s in lines:
            s0, s1 = np.array(s.start), np.array(s.end)
            f0, f1 = float(d @ (s0 - a)), float(d @ (s1 - a))
            lo, hi = max(0.0, min(f0, f1)), min(length, max(f0, f1))
            if not hi > lo or f1 == f0:
                continue
            ends = [s0 + (f - f0) / (f1 - f0) * (s1 - s0) for f in (lo, hi)]
            off = max(abs(float(d[0] * (q - a)[1] - d[1] * (q - a)[0])) for q in ends)
            if off > tol:
                continue
            best = max(best, hi - lo)
        assert best >= 0.5 * length, (length, best)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(lines_and_fillets())
def test_lines_and_fillets_are_valid(case):
    pts, _straight, _noise = case
    chain = fit_arcs(pts, 0.1, corner_angle_deg=179.0)
    assert_valid(chain, pts, 0.1, False)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(lines_and_fillets())
def test_lines_and_fillets_give_lines(case):
    """Lines joined by tangent fillets (noise up to 0.03 mm) give lines (see
    :func:`assert_gives_lines`)."""
    pts, straight, _noise = case
    assert_gives_lines(pts, straight)


#: seeded batch of lines-and-fillets curves: a deterministic check of the same property
LF_BATCH_SEED = 20261122
LF_BATCH_SIZE = 64


def test_lines_and_fillets_give_lines_batch():
    rng = np.random.default_rng(LF_BATCH_SEED)
    for i in range(LF_BATCH_SIZE):
        pts, straight, noise = random_lines_and_fillets(rng)
        try:
            assert_gives_lines(pts, straight)
        except AssertionError as exc:
            raise AssertionError(f"curve {i} (noise {noise}): {exc}") from exc


DATA = Path(__file__).resolve().parent / "data"


@pytest.mark.parametrize("name", [
    # noise 0.02 mm; the 42.6 mm last straight part was laid as an arc of radius 6800
    # (not flat by sagitta) because the refit's fillet missed the 5 mm line before it
    "noisy_straight_without_line",
    # no noise; the chain ended with a flat arc of radius 318 mm after a 92 degree
    # fillet: the refit's ending on the short last straight part had 9 pieces
    "short_last_straight_flat_arc",
    # no noise, 1 mm sampling; the 25.7 mm middle straight part was an arc of radius
    # 1,282: the refit along it laid a flat arc over the 8 mm end part instead and was
    # two segments longer, so it was dropped (a second round anchors that part too)
    "refit_new_flat_end_arc",
    # the chain's line along the 16.4 mm straight part runs 0.3 mm past its end, where it
    # is 0.1 mm off the part's line: the check measured the line's ends, not the overlap
    "line_past_straight_end",
    # no noise, 1 mm sampling: the 26.8 mm middle straight part is an arc of radius 767;
    # the refit along it split both fillets into two arcs and was two segments longer
    # (fixed with the first beam's scans at 0.97 of the tolerance, _runs.WORK)
    "refit_split_fillets",
    # found by a local (random) run on main 57274c8 and on arcs3 alike: the 17.0 mm
    # straight part between two fillets was an arc of radius 452 (sagitta 0.045 mm, not
    # flat) covering 12.7 mm of it (fixed with the first beam's scans at 0.97 of the
    # tolerance, _runs.WORK)
    "arc_over_short_straight",
])
def test_saved_lines_and_fillets_give_lines(name):
    """Lines-and-fillets curves hypothesis once found failing (points, straight parts)."""
    with np.load(DATA / f"{name}.npz") as z:
        pts, straight = z["points"], z["straight"]
    assert_gives_lines(pts, [(s[0], s[1]) for s in straight])
    assert_valid(fit_arcs(pts, 0.1, corner_angle_deg=179.0), pts, 0.1, False)


def test_square_keeps_four_sharp_corners():
    side = np.linspace(0, 40, 81)[:-1]
    pts = np.vstack([
        np.stack([side, 0 * side], 1), np.stack([40 + 0 * side, side], 1),
        np.stack([40 - side, 40 + 0 * side], 1), np.stack([0 * side, 40 - side], 1),
    ])
    chain = fit_arcs(pts, 0.1, closed=True)
    assert len(chain.segments) == 4 and chain.n_lines == 4
    assert sorted(chain.corners) == [0, 1, 2, 3]
    assert np.allclose(kinks(chain), np.pi / 2)
    assert_valid(chain, pts, 0.1, True)


def test_corner_angle_option_decides():
    # a 20 degree kink: a corner at corner_angle_deg=10, smoothed (C1) at 30
    a = np.stack([np.linspace(0, 50, 101), np.zeros(101)], 1)
    d = np.array([np.cos(np.radians(20)), np.sin(np.radians(20))])
    b = a[-1] + np.linspace(0, 50, 101)[1:, None] * d
    pts = np.vstack([a, b])
    sharp = fit_arcs(pts, 0.1, corner_angle_deg=10)
    assert len(sharp.corners) == 1 and sharp.n_lines == 2 and len(sharp.segments) == 2
    smooth = fit_arcs(pts, 0.1, corner_angle_deg=30)
    assert smooth.corners == ()
    assert_valid(smooth, pts, 0.1, False)
    assert_valid(sharp, pts, 0.1, False)


def test_max_radius_caps_arcs():
    pts, closed = BENCH_CURVES["ellipse"]()
    chain = fit_arcs(pts, 0.1, closed=closed, max_radius=120.0)
    assert all(s.radius <= 120.0 + 1e-9 for s in chain.segments if s.kind == "arc")
    assert_valid(chain, pts, 0.1, closed)


def test_closed_curve_closes_smoothly():
    th = np.linspace(0, 2 * np.pi, 700, endpoint=False)
    r = 30 + 6 * np.cos(3 * th)
    pts = np.stack([r * np.cos(th), r * np.sin(th)], 1)
    chain = fit_arcs(pts, 0.05, closed=True)
    assert chain.corners == ()
    assert kinks(chain)[-1] <= 1e-9
    assert_valid(chain, pts, 0.05, True)


def test_tiny_curves_within_tolerance():
    pts = np.array([[0.0, 0.0], [0.001, 0.002], [0.002, 0.0]])
    chain = fit_arcs(pts, 0.1)
    assert len(chain.segments) == 1
    assert_valid(chain, pts, 0.1, False)
    chain = fit_arcs(pts, 0.1, closed=True)
    assert_valid(chain, pts, 0.1, True)


# ----------------------------------------------------------------------------
# bad input


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"points": [[0, 0]]}, "points"),
        ({"points": [[0, 0], [0, 0], [0, 0]]}, "points"),
        ({"points": [[0, 0], [1, np.nan]]}, "points"),
        ({"points": [[0, 0], [1, np.inf]]}, "points"),
        ({"points": [[0, 0, 0], [1, 1, 1]]}, "points"),
        ({"points": [0, 1, 2]}, "points"),
        ({"points": [[0, 0], [1]]}, "points"),
        ({"points": [[0, 0], [1, 1]], "tolerance": 0.0}, "tolerance"),
        ({"points": [[0, 0], [1, 1]], "tolerance": -1.0}, "tolerance"),
        ({"points": [[0, 0], [1, 1]], "tolerance": float("nan")}, "tolerance"),
        ({"points": [[0, 0], [1, 1]], "corner_angle_deg": 0.0}, "corner_angle_deg"),
        ({"points": [[0, 0], [1, 1]], "corner_angle_deg": 200.0}, "corner_angle_deg"),
        ({"points": [[0, 0], [1, 1]], "max_radius": -5.0}, "max_radius"),
        ({"points": [[0, 0], [1, 1]], "max_radius": float("inf")}, "max_radius"),
    ],
)
def test_bad_input_is_rejected(kwargs, field):
    with pytest.raises(InvalidInputError) as err:
        fit_arcs(**kwargs)
    assert err.value.field == field


# ----------------------------------------------------------------------------
# never fails: generated curves


def smooth_curve(draw, closed: bool = False) -> np.ndarray:
    length = draw(st.floats(5.0, 150.0))
    n_modes = draw(st.integers(0, 3))
    k0 = draw(st.floats(-0.2, 0.2))
    amps = [draw(st.floats(-0.4, 0.4)) for _ in range(n_modes)]
    freqs = [draw(st.floats(0.01, 0.3)) for _ in range(n_modes)]
    phases = [draw(st.floats(0, 6.3)) for _ in range(n_modes)]
    s = np.linspace(0, length, 4001)
    modes = zip(amps, freqs, phases, strict=True)
    kap = k0 + np.zeros_like(s) + sum(a * np.sin(f * s + p) for a, f, p in modes)
    head = np.concatenate([[0.0], np.cumsum(0.5 * (kap[1:] + kap[:-1]) * np.diff(s))])
    x = np.concatenate([[0.0], np.cumsum(np.cos(head[:-1]) * np.diff(s))])
    y = np.concatenate([[0.0], np.cumsum(np.sin(head[:-1]) * np.diff(s))])
    # sampling: uniform or uneven
    spacing = draw(st.floats(0.05, 2.0))
    uneven = draw(st.booleans())
    m = max(int(length / spacing), 2)
    if uneven:
        rng = np.random.default_rng(draw(st.integers(0, 2**31)))
        at = np.sort(rng.uniform(0, length, m))
        at = np.concatenate([[0.0], at, [length]])
    else:
        at = np.linspace(0, length, m + 1)
    return np.stack([np.interp(at, s, x), np.interp(at, s, y)], axis=1)


@st.composite
def curves(draw):
    kind = draw(st.sampled_from(["smooth", "noisy", "repeated", "collinear", "hairpin"]))
    rng = np.random.default_rng(draw(st.integers(0, 2**31)))
    closed = False
    if kind in ("smooth", "noisy", "repeated"):
        pts = smooth_curve(draw)
        if kind == "noisy":
            pts = pts + rng.uniform(-0.03, 0.03, pts.shape)
        if kind == "repeated":
            idx = np.sort(np.concatenate([np.arange(len(pts)),
                                          rng.integers(0, len(pts), len(pts) // 3)]))
            pts = pts[idx]
    elif kind == "collinear":
        n = draw(st.integers(2, 300))
        t = np.sort(rng.uniform(0, draw(st.floats(0.5, 200.0)), n))
        t[0], t[-1] = 0.0, max(t[-1], 0.5)
        ang = rng.uniform(-np.pi, np.pi)
        pts = t[:, None] * np.array([np.cos(ang), np.sin(ang)])
    else:  # hairpin: out, a tight U-turn, back
        r = draw(st.floats(0.01, 5.0))
        leg = draw(st.floats(1.0, 60.0))
        h = draw(st.floats(0.05, 1.0))
        a = np.arange(0, leg, h)
        th = np.linspace(-np.pi / 2, np.pi / 2, max(int(np.pi * r / h), 2))
        pts = np.vstack([
            np.stack([a, -r + 0 * a], 1),
            np.stack([leg + r * np.cos(th), r * np.sin(th)], 1),
            np.stack([a[::-1], r + 0 * a], 1),
        ])
    if kind == "smooth" and draw(st.booleans()):
        # make it a loop by appending the way back along a circle-ish path
        closed = True
        c = pts.mean(axis=0)
        ang = np.arctan2(pts[:, 1] - c[1], pts[:, 0] - c[0])
        pts = pts[np.argsort(ang)]
    exp = draw(st.integers(-3, 3))
    scale = 10.0**exp
    shift = np.array([draw(st.floats(-1e5, 1e5)), draw(st.floats(-1e5, 1e5))])
    return pts * scale + shift * (scale if exp >= 0 else 1e-3), 0.1 * scale, closed


def assert_fits_validly(pts, tol, closed):
    """The fit of a generated curve is a valid chain (curves that collapse to fewer than
    two distinct points are bad input, covered by the random-polygon test)."""
    distinct = dedup(pts, closed, tol)
    assume(len(distinct) >= 2)
    chain = fit_arcs(pts, tol, closed=closed)
    assert_valid(chain, distinct, tol, closed)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(curves())
def test_never_fails_on_valid_curves(case):
    assert_fits_validly(*case)


@settings(max_examples=25, deadline=None)
@given(st.lists(st.tuples(st.floats(-5, 5), st.floats(-5, 5)), min_size=2, max_size=40),
       st.floats(0.01, 1.0), st.booleans())
# found by hypothesis: a closed curve of two points 1e-8 apart (there and back, far below
# the tolerance, so no corners) got a fallback chain whose closing junction kinked by
# 43 degrees; it is one full circle on the two points' segment
@example([(0.0, 0.0), (1e-8, 0.0)], 0.1, True)
@example([(4.9, 4.9), (4.9 + 1e-8, 4.9 + 7e-9)], 0.01, True)
@example([(0.0, 0.0), (0.15, 0.0)], 0.1, True)
def test_never_fails_on_random_polygons(raw, tol, closed):
    pts = np.array(raw, dtype=float)
    if len(dedup(pts, closed, tol, widest=False)) < 2:
        with pytest.raises(InvalidInputError):
            fit_arcs(pts, tol, closed=closed)
        return
    distinct = dedup(pts, closed, tol)
    # between the two repeat radii fit_arcs may see one point or two: not asserted
    assume(len(distinct) >= 2)
    chain = fit_arcs(pts, tol, closed=closed)
    # random polygons have real corners; smoothness holds wherever none was detected
    assert_valid(chain, distinct, tol, closed)


# ----------------------------------------------------------------------------
# the fallback (filleted polyline) is valid by construction


@pytest.fixture
def fallback_everywhere(monkeypatch):
    """Make the beam give up at once, so every run is the fallback chain."""
    from zwcore.arcs import _search as arcfit

    orig_run = arcfit.Fitter.run

    def run(self, a, b, loop, allow_forced, t_start=None, resume=None):
        if not allow_forced:
            raise arcfit.Stuck
        self._expand = lambda level, b: []
        self.use_bridge = False
        self.one_piece_runs = False
        return orig_run(self, a, b, loop, allow_forced, t_start, resume)

    monkeypatch.setattr(arcfit.Fitter, "run", run)


@st.composite
def jagged(draw):
    rng = np.random.default_rng(draw(st.integers(0, 2**31)))
    kind = draw(st.sampled_from(["random", "walk", "hairpin", "reversal"]))
    if kind == "random":
        pts = rng.uniform(-5, 5, (draw(st.integers(2, 40)), 2))
    elif kind == "walk":
        n = draw(st.integers(3, 60))
        pts = np.cumsum(rng.normal(0, 1, (n, 2)), axis=0)
        rep = rng.integers(0, n, n // 3)
        pts = np.vstack([pts, pts[rep]])[np.argsort(np.concatenate([np.arange(n), rep]),
                                                    kind="stable")]
    elif kind == "hairpin":
        r = draw(st.floats(0.001, 5.0))
        leg = draw(st.floats(1.0, 60.0))
        h = draw(st.floats(0.05, 1.0))
        a = np.arange(0, leg, h)
        th = np.linspace(-np.pi / 2, np.pi / 2, max(int(np.pi * r / h), 2))
        pts = np.vstack([np.stack([a, -r + 0 * a], 1),
                         np.stack([leg + r * np.cos(th), r * np.sin(th)], 1),
                         np.stack([a[::-1], r + 0 * a], 1)])
    else:  # exact reversals: back and forth along a line, collinear points
        n = draw(st.integers(3, 20))
        pts = np.stack([rng.uniform(0, 10, n), np.zeros(n)], 1) @ np.array([[0.6, 0.8],
                                                                          [-0.8, 0.6]])
    exp = draw(st.integers(-3, 3))
    scale = 10.0**exp
    shift = rng.uniform(-1e5, 1e5, 2) * (scale if exp >= 0 else 1e-3)
    tol = draw(st.floats(0.01, 1.0)) * scale
    return pts * scale + shift, tol, draw(st.booleans())


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(jagged())
# found by hypothesis: a closed curve all within 0.2 tolerances of its first point, the
# fallback's polyline of no length, gave one line of length zero; a small full circle now
@example((np.array([[61135.5703, -76333.9327], [61135.4928, -76334.0360],
                    [61135.5990, -76333.8945]]), 1.0, True))
def test_fallback_chain_is_valid_by_construction(fallback_everywhere, case):
    assert_fits_validly(*case)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(jagged())
def test_never_fails_on_jagged_curves(case):
    assert_fits_validly(*case)


# ----------------------------------------------------------------------------
# degenerate inputs: the reported figures are never NaN (an earlier schemathesis run
# saw ``max_deviation_points: NaN``); a curve is either fitted validly or rejected


def _finite_or_rejected(pts: np.ndarray, tol: float, closed: bool) -> None:
    try:
        chain = fit_arcs(pts, tol, closed=closed)
    except InvalidInputError:
        return
    for v in (chain.max_deviation_points, chain.max_deviation_chain, chain.max_kink_smooth):
        assert math.isfinite(v), v
    assert chain.max_deviation_points <= tol + 1e-9 * max(1.0, float(np.abs(pts).max()))
    assert chain.max_deviation_chain <= tol + 1e-9 * max(1.0, float(np.abs(pts).max()))


@pytest.mark.parametrize("closed", [False, True])
@pytest.mark.parametrize("big", [0.0, 1e6, -1e6, 1e8])
# (tolerances far below 1e-4 of the curve length are correct but slow: see the bench notes)
@pytest.mark.parametrize("tol", [1e-3, 0.1, 10.0])
def test_degenerate_inputs_never_give_nan(big, tol, closed):
    base = np.array([big, -0.7 * big])
    ulp = np.spacing(max(abs(big), 1.0))
    off = np.array([0.3, 0.2])
    cases = [
        np.array([base, base + np.array([1.0, 0.0])]),  # two points
        np.array([base, base + np.array([1e-7, 1e-7])]),  # two points, tiny
        np.vstack([np.repeat(base[None], 20, 0), base + off]),  # all but one repeated
        np.vstack([base + off, np.repeat(base[None], 20, 0)]),
        np.vstack([np.repeat(base[None], 5, 0), base + off, np.repeat(base[None], 5, 0)]),
        np.array([base, base + np.array([1.0, 0.0]), base]),  # there and back
        base + ulp * np.array([[0.0, 0.0], [3.0, 0.0], [0.0, 5.0]]),  # a few ulps apart
    ]
    for pts in cases:
        _finite_or_rejected(pts, tol, closed)


@settings(max_examples=25, deadline=None)
@given(st.sampled_from([0.0, 1e6, -1e6]), st.integers(1, 6), st.integers(0, 5),
       st.floats(1e-3, 1.0), st.floats(1e-7, 2.0), st.booleans())
def test_repeated_points_hypothesis(big, n_before, n_after, tol, size, closed):
    base = np.array([big, big])
    pts = np.vstack([np.repeat(base[None], n_before, 0), base + np.array([size, 0.5 * size]),
                     np.repeat(base[None], n_after, 0)])
    _finite_or_rejected(pts, tol, closed)


def test_coarse_ellipse_polygon_tight_tolerance_gives_lines_along_edges():
    """A 42-point polygon of a 30 x 15 ellipse at tol 0.01: each edge (hundreds of
    tolerances long) is a straight run and each vertex turns by ~8.6 degrees, below the
    corner angle. The chain is a valid C1 loop of about a line per edge and a fillet per
    vertex: no arc of huge radius, and all edges but the two meeting at the loop's start
    point (where the closure joins) are followed by a line over most of their length.
    (This input once took minutes: the fit's work is now linear in the segments.)"""
    pts, closed = coarse_ellipse(42)
    tol = 0.01
    chain = fit_arcs(pts, tol, closed=closed)
    assert_valid(chain, pts, tol, closed)
    assert chain.corners == ()
    assert flat_arcs(chain, tol) == []
    assert len(chain.segments) <= 2 * len(pts) + 2
    lines = [s for s in chain.segments if s.kind == "line"]
    followed = 0
    for i in range(len(pts)):
        a, b = pts[i], pts[(i + 1) % len(pts)]
        length = float(np.hypot(*(b - a)))
        d = (b - a) / length
        best = 0.0
        for s in lines:
            s0, s1 = np.array(s.start), np.array(s.end)
            if max(abs(float(d[0] * (q - a)[1] - d[1] * (q - a)[0])) for q in (s0, s1)) > tol:
                continue
            lo = max(0.0, min(float(d @ (s0 - a)), float(d @ (s1 - a))))
            hi = min(length, max(float(d @ (s0 - a)), float(d @ (s1 - a))))
            best = max(best, hi - lo)
        followed += best >= 0.5 * length
    assert followed >= len(pts) - 2, followed


@pytest.mark.parametrize("closed", [False, True])
def test_a_tolerance_that_merges_every_point_is_the_tolerances_fault(closed: bool) -> None:
    """Points 1 mm apart merge at 1e-9 of a 1e12 mm tolerance: the error names
    ``tolerance``; points that coincide at their own precision name ``points``."""
    curve = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 1.0]])
    with pytest.raises(InvalidInputError) as err:
        fit_arcs(curve, 1e12, closed=closed)
    assert err.value.field == "tolerance"
    assert fit_arcs(curve, 1e6, closed=closed).segments  # 1e-3 mm merge radius: fits
    with pytest.raises(InvalidInputError) as err:
        fit_arcs(np.array([[5.0, 5.0], [5.0, 5.0], [5.0, 5.0]]), 0.1, closed=closed)
    assert err.value.field == "points"
    # a curve below a nanometre is no curve, even though 1e-9 tolerances merged it
    with pytest.raises(InvalidInputError) as err:
        fit_arcs(np.array([[1.0, 1.0], [1.0, 1.0 + 1e-12]]), 0.1, closed=closed)
    assert err.value.field == "points"


# ----------------------------------------------------------------------------
# layout: every function of the arc fit reads on one screen (issue 10)


def test_arc_functions_and_modules_are_short():
    import ast

    root = Path(__file__).resolve().parents[1] / "zwcore" / "arcs"
    long_ = []
    for path in sorted(root.glob("*.py")):
        text = path.read_text()
        if len(text.splitlines()) > 500:
            long_.append((path.name, "module", len(text.splitlines())))
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                n = (node.end_lineno or node.lineno) - node.lineno + 1
                if n > 80:
                    long_.append((path.name, node.name, n))
    assert not long_, long_


# ----------------------------------------------------------------------------
# no arc flatter than the straight-run rule (issue 15): airfoils and long gentle bends


def gentle_bend(radius: float, length: float = 300.0, step: float = 0.5) -> np.ndarray:
    """A 100 mm line, an arc of ``radius`` over ``length`` mm, a 100 mm line (tangent)."""
    s = np.arange(0.0, 100.0, step)
    lead = np.stack([s - 100.0, 0.0 * s], 1)
    th = np.arange(0.0, length / radius, step / radius)
    bend = np.stack([radius * np.sin(th), radius - radius * np.cos(th)], 1)
    d = np.array([math.cos(th[-1]), math.sin(th[-1])])
    tail = bend[-1] + np.arange(step, 100.0, step)[:, None] * d
    return np.vstack([lead, bend, tail])


@pytest.mark.parametrize(("name", "tol"), [("naca2412", 0.05), ("naca2412", 0.01),
                                           ("bend1000", 0.01), ("bend5000", 0.05),
                                           ("bend20000", 0.01)])
def test_no_arc_flatter_than_the_straight_run_rule(name, tol):
    if name == "naca2412":
        pts, _ = BENCH_CURVES["naca2412"]()
    else:
        pts = gentle_bend(float(name[4:]))
    chain = fit_arcs(pts, tol)
    # (validity: the other tests; here the radii)
    assert chain.max_deviation_points <= tol and chain.max_deviation_chain <= tol
    assert flat_arcs(chain, tol) == [], [chain.segments[i].radius for i in flat_arcs(chain, tol)]


def test_naca_finely_sampled_has_no_flat_arc():
    """The rear lower surface sampled at 0.2 mm bows a little (radius ~7,000 mm): straight
    to the straight-run rule, but the line through the trailing edge leaves its far end
    most of the band. The chain ends on a shorter line from the trailing edge instead of
    an arc of radius ~40,000 mm (sagitta 0.012 mm at 0.05), at one segment more."""
    pts, _ = BENCH_CURVES["naca2412"](0.2)
    chain = fit_arcs(pts, 0.05)
    assert chain.max_deviation_points <= 0.05 and chain.max_deviation_chain <= 0.05
    assert flat_arcs(chain, 0.05) == []
    assert chain.segments[-1].kind == "line"
    assert chain.segments[-1].end == pytest.approx(tuple(pts[-1]), abs=1e-9)
