"""The compiled kernels of the arc fit against their plain-numpy reference
(``tests/arc_reference.py``, the formulation the fit used before they were compiled).

Scans (reach, running curvature bounds) do the same exact arithmetic, so they must agree
exactly. The verification and the dense deviation use transcendental functions whose
last bits differ between numpy's vector loops and libm: a kernel's accept must be a
reference accept at a hair more tolerance, a kernel's reject a reference reject at a hair
less, and the figures must agree to rounding.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, example, given, settings
from hypothesis import strategies as st

from tests import arc_reference as ref
from zwcore.arcs import _kernels
from zwcore.arcs._geometry import (
    arc_point,
    arc_points,
    line_fit,
    local_uv,
    points_to_segments_distance,
)
from zwcore.arcs._pieces import Piece, ToleranceBand
from zwcore.arcs._prepare import prepare
from zwcore.arcs._runs import assemble
from zwcore.arcs._search import Fitter
from zwcore.arcs._select import candidates, select_verified
from zwcore.arcs.verify import densify, deviations

HAIR = 1e-9


def _wavy(n: int, step: float, amp: float, wave: float, noise: float,
          seed: int) -> np.ndarray:
    """``n`` samples ``(n, 2)`` of a sum of two waves, with noise: :func:`wavy_curves`'
    curve, built here so that an ``@example`` can name one by its draws."""
    rng = np.random.default_rng(seed)
    x = np.arange(n) * step
    y = amp * np.sin(x / wave * 2 * math.pi) + 0.3 * amp * np.sin(x / (0.37 * wave))
    return np.stack([x, y], 1) + rng.uniform(-noise, noise, (n, 2))


def _junction(pts: np.ndarray, tol: float, k: int, turn: float,
              off: float) -> tuple[np.ndarray, float, np.ndarray, np.ndarray, int]:
    """:func:`junctions`' case from its draws: the junction ``off`` tolerances beside
    sample ``k``, its tangent ``turn`` radians from the polyline's."""
    d = pts[k + 1] - pts[k]
    th = math.atan2(d[1], d[0]) + turn
    t = np.array([math.cos(th), math.sin(th)])
    p = pts[k] + off * tol * np.array([-t[1], t[0]])
    return pts, tol, p, t, k


@st.composite
def wavy_curves(draw: st.DrawFn) -> tuple[np.ndarray, float]:
    """A sampled curve (a sum of two waves, with noise) and a tolerance."""
    n = draw(st.integers(8, 160))
    step = draw(st.floats(0.02, 1.0))
    amp = draw(st.floats(0.0, 5.0))
    wave = draw(st.floats(0.5, 40.0))
    noise = draw(st.floats(0.0, 0.05))
    tol = draw(st.floats(0.005, 0.3))
    seed = draw(st.integers(0, 2**31))
    return _wavy(n, step, amp, wave, noise, seed), tol


@st.composite
def junctions(draw: st.DrawFn) -> tuple[np.ndarray, float, np.ndarray, np.ndarray, int]:
    """A curve, a tolerance and a junction (point near a sample, tangent near the
    polyline's) at sample ``k``."""
    pts, tol = draw(wavy_curves())
    k = draw(st.integers(0, len(pts) - 3))
    return _junction(pts, tol, k, draw(st.floats(-0.3, 0.3)), draw(st.floats(-1.0, 1.0)))


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(junctions(), st.floats(0.5, 1.0), st.integers(1, 5))
def test_reach_scans_equal_the_reference(case, work, stride):
    pts, tol, p, t, k = case
    wt = work * tol
    b = len(pts) - 1
    # several junctions at different samples, as the beam ranks them
    ps = np.array([p, pts[min(k + 1, b)], pts[min(k + 2, b)]])
    ts = np.array([t, t, t])
    ks = np.array([k, min(k + 1, b), min(k + 2, b)], dtype=np.int64)
    got = _kernels.reach_lines(pts, ps, ts, ks, b, stride, wt)
    want = ref.reach_with_lines(pts, wt, stride, ps, ts, ks, b)
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])
    lo, up = _kernels.piece_bounds(pts, p[0], p[1], t[0], t[1], k, b, wt)
    lo_r, up_r = ref.longest_piece_bounds(pts, wt, p, t, k, b)
    np.testing.assert_array_equal(lo, lo_r)
    np.testing.assert_array_equal(up, up_r)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(junctions(), st.floats(0.0, 1.0), st.floats(0.0, 1.0), st.booleans(), st.booleans(),
       st.floats(0.9, 1.1))
def test_verify_agrees_with_the_reference(case, fj, fk, given_end, dense_first, stretch):
    pts, tol, p, t, k = case
    b = len(pts) - 1
    lo, up = ref.longest_piece_bounds(pts, tol, p, t, k, b)
    assume(len(lo) >= 1)
    # a piece inside the feasible interval of its end sample (passes often), or a bit
    # outside it (fails often)
    j = k + 1 + int(fj * (len(lo) - 1))
    lo_j, up_j = max(lo[j - k - 1], -1e3), min(up[j - k - 1], 1e3)
    kappa = lo_j + (fk * 1.2 - 0.1) * (up_j - lo_j)
    e_k = float(np.hypot(*(pts[k] - p)))
    sig_end = None
    if given_end:
        u = float((pts[j] - p) @ t)
        sig_end = max(u, 1e-6) * stretch
    band = ToleranceBand(pts, tol, 1.0, None)
    got = band.verify(p, t, kappa, k, j, e_k, sig_end=sig_end, dense_first=dense_first)
    args = (p, t, kappa, k, j, e_k, sig_end, dense_first)
    if got is None:
        assert ref.verify(pts, tol * (1 - HAIR), band.dense_step, *args) is None
    else:
        want = ref.verify(pts, tol * (1 + HAIR), band.dense_step, *args)
        assert want is not None
        assert math.isclose(got[0], want[0], rel_tol=1e-12, abs_tol=1e-12)
        np.testing.assert_allclose(got[1], want[1], rtol=0, atol=1e-11)
        assert math.isclose(got[2], want[2], rel_tol=1e-9, abs_tol=1e-12)


def _pieces(pts: np.ndarray, tol: float, closed: bool) -> tuple[np.ndarray, list[Piece]]:
    prep = prepare(pts, tol, closed, math.radians(30.0))
    pieces = assemble(prep, None, True)[0]
    return prep.samples, pieces


def _brute_deviations(samples: np.ndarray, pieces: list[Piece],
                      step: float) -> tuple[float, float]:
    """Brute force: the two-sided deviation over the dense points the measures sample
    (the polyline at ``step``, each piece at ``step``), each point measured against the
    whole other side."""
    dpoly = densify(samples, step)
    d_p = np.min([ref.point_to_arc_distance(dpoly, pc.p, pc.t, pc.kappa, pc.length)
                  for pc in pieces], axis=0)
    cpts = np.vstack([ref._piece_points(pc, step)[0] for pc in pieces])
    d_c = ref._dist_all_segments(cpts, samples)
    return float(d_p.max()), float(d_c.max())


#: a straight there-and-back loop (the wiggle, 1e-236 mm, only keeps the points apart)
#: whose spoilt chain the dense measure once put at 0.003407 where a polyline point is
#: 0.003440 from it: its jump along a piece whose foot was off the arc's start
_BACK_AND_FORTH = np.stack([np.arange(17) * 0.0234375,
                            1e-236 * np.sin(np.arange(17) * 0.0234375 / 0.4)], 1)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(wavy_curves(), st.booleans(), st.floats(-1.0, 1.0))
@example((_BACK_AND_FORTH, 0.02308252770447345), True, 0.0625)
def test_dense_deviations_bound_the_brute_force(case, closed, bend):
    """The dense measure (and its numpy reference) measure each point against the nearby
    geometry only, so each figure is at least the brute-force one over the same points;
    where the reference finds the chain within the tolerance, so does the measure. (On a
    spoilt chain the two may pick different nearby pieces, so their figures need not
    agree: random draws found a bent chain at tolerance 0.28 measured 0.2569 and 0.2808
    where the truth is 0.2132.)"""
    pts, tol = case
    # (the brute force measures every point against every segment: keep the dense
    # sampling, length / (tol / 20), to some 40,000 points)
    assume(float(np.hypot(*np.diff(pts, axis=0).T).sum()) <= 2000.0 * tol)
    samples, pieces = _pieces(pts - pts[0], tol, closed)
    if bend:
        # a spoilt chain (curvatures changed): the measure must see the violation too
        spoilt = []
        for pc in pieces:
            kap = pc.kappa * (1.0 + 0.2 * bend) + 0.02 * bend / tol
            end = arc_point(pc.p, pc.t, kap, pc.length)
            spoilt.append(Piece(pc.p, pc.t, kap, pc.length, pc.k, pc.j, end, pc.t_end,
                                pc.e_end))
        pieces = spoilt
    got = deviations(samples, pieces, tol)
    want = ref.deviations(samples, pieces, tol)
    length = float(np.hypot(*np.diff(samples, axis=0).T).sum())
    step = max(tol / 20.0, (length + sum(pc.length for pc in pieces)) / 2e6)
    truth = _brute_deviations(samples, pieces, step)
    hair = HAIR * tol
    for g, w, tr in zip(got, want, truth, strict=True):
        assert g >= tr - hair and w >= tr - hair
        if w <= tol:
            assert g <= tol + hair
    if not bend:
        # a fitted chain (its pieces are where the bookkeeping says): the same figure
        np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12)


def test_dense_deviation_of_a_segment_peaking_at_its_last_point():
    """A polyline segment whose line passes closest to the arc's centre past its end (the
    closed form's middle candidate is the last point itself) peaks at its last point,
    0.0764 from the arc, against 0.0292 at its first: the measure once dropped the last
    point with the middle candidate and reported the first point's figure."""
    kappa, length = 0.1, 10.0
    p = np.array([-5.0, 10.0 - math.sqrt(75.0)])
    t = np.array([10.0 - p[1], p[0]]) / 10.0  # (centre (0, 10): across the radius)
    end = arc_point(p, t, kappa, length)
    samples = np.array([[-3.0, 0.43], [-2.0, 0.28]])
    pieces = [Piece(p, t, kappa, length, 0, 1, end, t, 0.0)]
    for tol in (1.0, 0.05):
        d_p, _ = deviations(samples, pieces, tol)
        truth, _ = _brute_deviations(samples, pieces, tol / 20.0)
        assert truth > 0.07
        assert abs(d_p - truth) <= HAIR * tol


def _within_two_sided(pieces: list[Piece], covered: np.ndarray, near: np.ndarray,
                      tol: float) -> bool:
    """Brute force: every dense point of the polyline ``covered`` within ``tol`` of the
    pieces and every dense point of the pieces within ``tol`` of the polyline ``near``
    (``covered`` and a little around it), with a hair for the sampling."""
    step = tol / 50.0
    chain = []
    for pc in pieces:
        n = max(math.ceil(pc.length / step), 1) + 1
        chain.append(arc_points(pc.p, pc.t, pc.kappa, np.linspace(0.0, pc.length, n)))
    cpts = np.vstack(chain)
    d_c = points_to_segments_distance(cpts, near[:-1], near[1:]).min(axis=1)
    dense = densify(covered, step)
    d_p = np.min([ref.point_to_arc_distance(dense, pc.p, pc.t, pc.kappa, pc.length)
                  for pc in pieces], axis=0)
    return bool(d_c.max() <= tol + step and d_p.max() <= tol + step)


def test_biarc_second_arc_gets_its_start_distance():
    """The second arc of a biarc starts at the junction, which stands for sample m: its
    check uses that sample's distance from the junction (the numpy reference does), and
    the pair is within the tolerance both ways."""
    th = np.linspace(0, 1.5, 40)
    s = np.stack([20 * np.cos(th), 20 * np.sin(th)], 1)
    s[:, 1] += 0.05 * np.sin(7 * th)
    band = ToleranceBand(s, 0.1, 0.95, None)
    t0 = np.array([0.0, 1.0])
    t1 = np.array([-math.sin(1.2), math.cos(1.2)])
    got = band.biarc(s[0].copy(), t0, 0, 0.0, 30, t1)
    want = ref.biarc(s, 0.1, band.dense_step, band.kmin, band.kcap, s[0].copy(), t0, 0, 0.0,
                     30, t1, None, band.BIARC_SPLITS)
    assert got is not None and want is not None
    for a, b in zip(got, want, strict=True):
        assert (a.k, a.j) == (b.k, b.j)
        assert a.kappa == pytest.approx(b.kappa, rel=1e-12)
        assert a.e_end == pytest.approx(b.e_end, rel=1e-9, abs=1e-12)
    assert _within_two_sided(got, s[: got[1].j + 1], s, 0.1)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(junctions(), st.integers(2, 40), st.floats(-0.3, 0.3), st.booleans())
# the second arc ends on sample 26, whose foot numpy's arctan2 puts an ulp past the arc's
# end and libm's on it: both must take it as on the arc (END_SLACK; brute force: the
# pair is 0.1963 from the polyline at tolerance 0.2590)
@example(_junction(_wavy(27, 0.5, 1.5, 12.546875, 0.0, 0), 0.25903191485168087, 10,
                   0.046875, -0.7578125), 16, 0.3, False)
def test_biarc_agrees_with_the_reference(case, ahead, turn, off_sample):
    pts, tol, p, t, k = case
    b = min(k + ahead, len(pts) - 1)
    assume(b > k + 1)
    d = pts[b] - pts[b - 1]
    th = math.atan2(d[1], d[0]) + turn
    t1 = np.array([math.cos(th), math.sin(th)])
    p1 = pts[b] + 0.3 * tol * np.array([-t1[1], t1[0]]) if off_sample else None
    band = ToleranceBand(pts, tol, 0.95, None)
    e = float(np.hypot(*(pts[k] - p)))
    got = band.biarc(p, t, k, e, b, t1, p1)

    def reference(scale: float) -> list[Piece] | None:
        return ref.biarc(pts, tol * scale, band.dense_step, band.kmin, band.kcap, p, t, k, e,
                         b, t1, p1, band.BIARC_SPLITS)

    # (a biarc's junction is ill-conditioned where its tangents are nearly parallel:
    # numpy's and libm's last bits move its curvatures by some 1e-7, so the decisions
    # agree up to a wider hair than a single piece's; the second arc ends on sample b,
    # whose foot each puts on the arc's end or an ulp past it, which both take as on the
    # arc, see ref.segments_within; what the kernel accepts is measured by brute force
    # below)
    hair = 1e-5
    if got is None:
        assert reference(1 - hair) is None
        return
    assert reference(1 + hair) is not None
    want = reference(1.0)
    if want is not None and [(a.k, a.j) for a in want] == [(a.k, a.j) for a in got] and (
            np.hypot(*(want[0].end - got[0].end)) <= 1e-6 * tol):
        # the same split: the same pair up to rounding
        for a, b_ in zip(got, want, strict=True):
            # curvatures compared by what they do: the two arcs' sagittas over the arc
            # differ by no more than the hair the end points are held to (a tiny arc's
            # curvature moves by 1e-6 relative for a junction 1e-7 tol away)
            assert (a.kappa == pytest.approx(b_.kappa, rel=1e-6, abs=1e-9)
                    or abs(a.kappa - b_.kappa) * a.length**2 / 8 <= 1e-6 * tol)
            assert a.length == pytest.approx(b_.length, rel=1e-6, abs=1e-9)
            np.testing.assert_allclose(a.end, b_.end, rtol=0, atol=1e-6 * tol)
    # the pair itself, measured by brute force (the start stands for sample k at
    # distance e, the end for sample b)
    near = pts[max(k - 1, 0) : b + 2]
    assert _within_two_sided(got, pts[k : b + 1], near, tol)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(junctions(), st.floats(0.5, 1.0))
def test_candidates_agree_with_the_reference(case, work):
    pts, tol, p, t, k = case
    band = ToleranceBand(pts, tol, work, None)
    b = len(pts) - 1
    lo1, up1 = band.longest_piece_bounds(p, t, k, b)
    jm = min(k + len(lo1), b - 1)
    assume(jm > k)
    jf = np.array(Fitter.J_FRACTIONS)
    kf = np.array(ToleranceBand.K_FRACTIONS)
    got = candidates(pts, band.cum, p[0], p[1], t[0], t[1], k, jm, lo1, up1, jf, kf,
                              band.kcap)
    want = ref.candidates(pts, band.cum, p, t, k, jm, lo1, up1, jf, kf, band.kcap)
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])
    for a, b_ in zip(got[2:], want[2:], strict=True):
        np.testing.assert_allclose(a, b_, rtol=1e-12, atol=1e-12)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(wavy_curves(), st.integers(0, 200), st.integers(0, 200), st.booleans())
def test_line_spread_agrees_with_line_fit(case, i, n, pinned):
    pts, _tol = case
    i0 = min(i, len(pts) - 1)
    i1 = min(i0 + n, len(pts) - 1)
    pivot = pts[i0] if pinned else None
    want = line_fit(pts[i0 : i1 + 1], pivot)[2]
    got = _kernels.line_spread(pts, i0, i1, pinned, pts[i0, 0], pts[i0, 1])
    scale = float(np.abs(pts).max()) + 1.0
    assert got == pytest.approx(want, rel=1e-9, abs=1e-12 * scale)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(junctions(), st.floats(0.0, 1.0), st.floats(-0.2, 1.2))
def test_kappa_fits_agrees_with_the_intervals(case, fj, fk):
    pts, tol, p, t, k = case
    b = len(pts) - 1
    j = k + 1 + int(fj * (b - k - 1))
    u, v = local_uv(p, t, pts[k + 1 : j + 1])
    lo, up = ref.kappa_bounds(u, v, tol)
    lo_m, up_m = float(lo.max()), float(up.min())
    assume(math.isfinite(lo_m) and math.isfinite(up_m) and lo_m <= up_m)
    kappa = lo_m + fk * (up_m - lo_m)
    want = bool(lo_m <= kappa <= up_m)
    assert _kernels.kappa_fits(pts, p[0], p[1], t[0], t[1], k, j, tol, kappa, 0.0) == want


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(junctions(), st.floats(-0.3, 0.3))
def test_line_reaches_and_chord_circles_agree_with_numpy(case, turn):
    pts, tol, p, t, k = case
    b = len(pts) - 1
    th0 = math.atan2(t[1], t[0])
    ths = th0 + turn + np.linspace(-0.1, 0.1, 7)
    ts = np.stack([np.cos(ths), np.sin(ths)], 1)
    u, v = local_uv(p[None, None, :], ts[:, None, :], pts[None, k + 1 : b + 1, :])
    bad = (np.abs(v) > tol) | (u < -tol)
    want = np.where(bad.any(axis=1), k + np.argmax(bad, axis=1), b)
    np.testing.assert_array_equal(_kernels.line_reaches(pts, p[0], p[1], ts, k, b, tol), want)
    # the circle through p along th and through sample b: its largest gap to the samples
    tt = ts[0]
    ub, vb = local_uv(p, tt, pts[b : b + 1])
    kap = float(2.0 * vb[0] / (ub[0] ** 2 + vb[0] ** 2))
    uu, vv = local_uv(p, tt, pts[k + 1 : b + 1])
    gap = float(np.abs(ref.circle_gap(uu, vv, kap)).max())
    got = _kernels.chord_circle_gap(pts, p[0], p[1], float(ths[0]), k, b)
    assert got == pytest.approx(gap, rel=1e-9, abs=1e-12)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(junctions(), st.integers(1, 4), st.integers(0, 2**31))
def test_select_verified_agrees_with_a_python_walk(case, beam, seed):
    """The compiled walk of a ranking equals the Python loop over ToleranceBand.verify."""
    pts, tol, p, t, k = case
    rng = np.random.default_rng(seed)
    band = ToleranceBand(pts, tol, 0.95, None)
    b = len(pts) - 1
    lo1, up1 = band.longest_piece_bounds(p, t, k, b)
    jm = min(k + len(lo1), b - 1)
    assume(jm > k)
    jj, kk, _ends, tends, _bonus = candidates(
        pts, band.cum, p[0], p[1], t[0], t[1], k, jm, lo1, up1, np.array(Fitter.J_FRACTIONS),
        np.array(ToleranceBand.K_FRACTIONS), band.kcap)
    n = len(jj)
    assume(n > 0)
    # some candidates spoilt (a curvature off the interval) so that some fail
    kk = kk * np.where(rng.random(n) < 0.3, 1.5, 1.0)
    order = rng.permutation(n).astype(np.int64)
    reach = rng.integers(k, b + 1, n).astype(np.int64)
    special = rng.random(n) < 0.2
    sig_end = np.full(n, np.nan)
    e = float(np.hypot(*(pts[k] - p)))
    got, figs = select_verified(
        pts, order, np.zeros(n, dtype=np.int64), jj, kk, sig_end, special, reach, tends,
        p[None, :].copy(), t[None, :].copy(), np.array([k]), np.array([e]), beam, beam // 2,
        tol, band.dense_step)
    want, seen, checks, n_special = [], set(), 0, 0
    for i in order.tolist():
        if len(want) >= beam or checks >= 12 * beam:
            break
        if special[i] and n_special >= beam // 2:
            continue
        key = (int(reach[i]), int(jj[i]), round(math.atan2(tends[i, 1], tends[i, 0]) * 1e3))
        if key in seen:
            continue
        checks += 1
        res = band.verify(p, t, float(kk[i]), k, int(jj[i]), e)
        if res is None:
            continue
        seen.add(key)
        want.append((i, res[0]))
        n_special += bool(special[i])
    assert got.tolist() == [w[0] for w in want]
    np.testing.assert_allclose(figs[:, 0], [w[1] for w in want], rtol=1e-12)


@st.composite
def polygons(draw: st.DrawFn) -> tuple[np.ndarray, float]:
    """A polygon (edges of random length, random turns, some of them straight) and a
    tolerance: coarse ones the closed form fillets, and fine ones it must refuse."""
    n = draw(st.integers(3, 40))
    seed = draw(st.integers(0, 2**31))
    tol = draw(st.floats(0.005, 0.5))
    scale = draw(st.sampled_from([0.05, 1.0, 20.0]))
    rng = np.random.default_rng(seed)
    edges = rng.uniform(0.2, 1.0, n - 1) * scale
    turns = rng.uniform(-2.5, 2.5, n - 1) * (rng.random(n - 1) < 0.8)
    heading = np.cumsum(turns)
    steps = np.stack([np.cos(heading), np.sin(heading)], 1) * edges[:, None]
    return np.vstack([[0.0, 0.0], np.cumsum(steps, axis=0)]), tol


@settings(max_examples=200, deadline=None)
@given(polygons(), st.booleans())
def test_fillet_clash_only_where_the_polygon_has_no_fillets(case, loop):
    """The compiled early refusal of the closed-form filleted polygon is sound: where it
    finds two neighbouring fillets that overlap, the whole-run array computation of
    :func:`polygon_run` (run here with the refusal switched off) finds no filleted
    polygon either; and a pair overlapping by more than a millionth of its edge, found
    here by brute force over every vertex, is always found."""
    from zwcore.arcs import _polygon

    pts, tol = case
    if loop:
        pts = np.vstack([pts, pts[:1]])
        assume(float(np.hypot(*(pts[-2] - pts[0]))) > 0.0)
    band = ToleranceBand(pts, tol, 0.95, None)
    work = _polygon._WORK * tol
    clash = _polygon._fillets_clash(pts, work, 1e-13 * float(band.cum[-1]))
    # brute force: every inner sample's turn and largest fillet, the edges between them
    d = np.diff(pts, axis=0)
    th = np.abs(np.arctan2(d[:-1, 0] * d[1:, 1] - d[:-1, 1] * d[1:, 0],
                           (d[:-1] * d[1:]).sum(1)))
    tangent = np.where(th > 1e-9, work / np.tan(0.25 * np.maximum(th, 1e-300)), np.nan)
    overlap = (tangent[:-1] + tangent[1:]) / np.hypot(d[1:-1, 0], d[1:-1, 1])
    if np.any(overlap > 1.0 + 1e-5):
        assert clash
    if clash:
        orig = _polygon._fillets_clash
        try:
            _polygon._fillets_clash = lambda *a: False
            assert _polygon.polygon_run(band, 0, len(pts) - 1, loop) is None
        finally:
            _polygon._fillets_clash = orig


def _straight_span_reference(pts: np.ndarray, k: int, j: int, a: int, b: int,
                             band: float) -> tuple[int, int]:
    """The straight-run growth as the fit did it in Python before it was compiled (each
    straightness test a numpy least-squares line): the first of the whole span, its last,
    first or middle half that is straight, grown at its end by galloping and bisection,
    then at its start."""

    def straight(i0: int, i1: int) -> bool:
        return i1 - i0 < 2 or line_fit(pts[i0 : i1 + 1])[2] <= band

    q4 = (j - k) // 4
    for kk, jj in ((k, j), (k + 2 * q4, j), (k, j - 2 * q4), (k + q4, j - q4)):
        if jj - kk >= 2 and straight(kk, jj):
            k, j = kk, jj
            break
    else:
        return -1, -1

    def grow(fixed: int, moving: int, limit: int, sgn: int) -> int:
        good, step = moving, max(1, abs(moving - fixed) // 4)
        while good != limit:
            cand = good + sgn * step
            cand = min(cand, limit) if sgn > 0 else max(cand, limit)
            if straight(fixed, cand) if sgn > 0 else straight(cand, fixed):
                good, step = cand, 2 * step
                continue
            lo, hi = good, cand
            while abs(hi - lo) > 1:
                mid = (lo + hi) // 2
                if straight(fixed, mid) if sgn > 0 else straight(mid, fixed):
                    lo = mid
                else:
                    hi = mid
            return lo
        return good

    i1 = grow(k, j, b, 1)
    return grow(i1, k, a, -1), i1


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(wavy_curves(), st.floats(0.0, 1.0), st.floats(0.0, 1.0), st.floats(0.0, 1.0),
       st.floats(0.0, 1.0), st.floats(0.05, 1.0))
def test_straight_span_grows_the_run_as_the_numpy_fit(case, fa, fk, fj, fb, share):
    """The compiled gallop and bisection of a straight run ends where the same steps
    with numpy's least-squares lines end (exactly, away from spreads within rounding of
    the band: the kernel's spread agrees with numpy's to 1e-9, tested above)."""
    from zwcore.arcs._straight import straight_span

    pts, tol = case
    n = len(pts) - 1
    a = int(fa * n)
    b = a + int(fb * (n - a))
    k = a + int(fk * (b - a))
    j = k + int(fj * (b - k))
    band = share * tol
    want = _straight_span_reference(pts, k, j, a, b, band)
    # (a spread within rounding of the band may be judged either way by the two)
    spreads = [line_fit(pts[i0 : i1 + 1])[2] for i0 in range(a, b + 1)
               for i1 in range(i0 + 2, min(b, i0 + 60) + 1)]
    assume(not any(abs(s - band) <= 1e-9 * (band + 1e-300) for s in spreads))
    assert straight_span(pts, k, j, a, b, band) == want
