"""The kernels compiled in session 6 give the figures of the numpy code they replaced,
bit for bit: the anchors' over-straight test and the fillet's vertex distance
(:mod:`zwcore.arcs._anchor_kernels`), a beam level's ranking
(:func:`zwcore.arcs._ranking.rank_keys`) and the dense check's one-piece first point
(:func:`zwcore.arcs._jumps.one_piece_distance`, :func:`zwcore.arcs._jumps.piece_growth_at`)
and the landing biarc's tries (:func:`zwcore.arcs._anchor_kernels.landing_pair`).
Each reference below is the numpy formulation as it stood before (copied, not
imported): a kernel that drifts from it fails here.
"""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from zwcore.arcs._anchor_kernels import anchors_hit, landing_pair, min_segment_distance
from zwcore.arcs._anchors import StraightRuns
from zwcore.arcs._dense import _nearest_piece
from zwcore.arcs._geometry import points_to_segments_distance
from zwcore.arcs._jumps import one_piece_distance, piece_growth, piece_growth_at
from zwcore.arcs._kernels import reach_lines
from zwcore.arcs._pieces import ToleranceBand
from zwcore.arcs._ranking import rank_candidates


def _polyline(seed: int, n: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.ascontiguousarray(np.cumsum(rng.normal(0.0, 1.0, (n, 2)), axis=0))


def _cum(samples: np.ndarray) -> np.ndarray:
    return np.concatenate([[0.0], np.cumsum(np.hypot(*(np.diff(samples, axis=0).T)))])


def anchors_hit_numpy(cum, samples, k, j, i0s, i1s, qs):
    """The anchor loop of ``StraightRuns.are_over`` as it was (numpy, per anchor)."""
    out = np.zeros(len(k), dtype=bool)
    for i0, i1, q in zip(i0s.tolist(), i1s.tolist(), qs, strict=True):
        over = cum[np.minimum(j, i1)] - cum[np.maximum(k, i0)]
        hit = over > 0.5 * (cum[i1] - cum[i0])
        inside = (i0 <= k) & (j <= i1)
        if inside.any():
            at_end = inside & (j == i1) & (samples[j] == q).all(axis=1)
            at_start = inside & (k == i0) & (samples[k] == q).all(axis=1)
            hit |= at_end | at_start
        out |= hit
    return out


@st.composite
def anchor_cases(draw):
    seed = draw(st.integers(0, 2**31))
    n = draw(st.integers(4, 60))
    samples = _polyline(seed, n)
    rng = np.random.default_rng(seed + 1)
    na = draw(st.integers(1, 4))
    i0s = np.sort(rng.integers(0, n - 1, na))
    i1s = np.minimum(i0s + rng.integers(1, 12, na), n - 1)
    # the line through an end sample of the anchor (a run's pinned end), or off it
    pick = rng.integers(0, 3, na)
    qs = np.where((pick == 0)[:, None], samples[i0s],
                  np.where((pick == 1)[:, None], samples[i1s], samples[i0s] + 0.01))
    nc = draw(st.integers(1, 40))
    k = rng.integers(0, n - 1, nc)
    j = np.minimum(k + rng.integers(1, 15, nc), n - 1)
    # candidates that sit exactly on anchors' ends, where the equality tests decide
    snap = rng.integers(0, na, nc)
    on = rng.random(nc) < 0.4
    k = np.where(on, i0s[snap], k)
    j = np.where(on, np.maximum(i1s[snap], k + 1), j)
    return samples, k.astype(np.int64), j.astype(np.int64), i0s.astype(np.int64), \
        i1s.astype(np.int64), np.ascontiguousarray(qs)


@settings(max_examples=150, deadline=None)
@given(anchor_cases())
def test_anchors_hit_is_the_numpy_anchor_loop(case):
    samples, k, j, i0s, i1s, qs = case
    cum = _cum(samples)
    got = anchors_hit(cum, samples, k, j, i0s, i1s, qs)
    np.testing.assert_array_equal(got, anchors_hit_numpy(cum, samples, k, j, i0s, i1s, qs))


def test_anchors_hit_takes_both_the_share_and_the_pinned_end():
    """Hand-made: a piece covering most of an anchor, one on it ending at its pinned end
    sample, one on it off that end, one elsewhere, one covering exactly half of it (not
    more: no hit)."""
    samples = np.array([[float(i), 0.0] for i in range(12)])
    cum = _cum(samples)
    i0s, i1s = np.array([2], dtype=np.int64), np.array([10], dtype=np.int64)
    qs = samples[[10]].copy()
    k = np.array([1, 8, 7, 0, 0], dtype=np.int64)
    j = np.array([9, 10, 9, 2, 6], dtype=np.int64)
    got = anchors_hit(cum, samples, k, j, i0s, i1s, qs)
    assert got.tolist() == [True, True, False, False, False]
    np.testing.assert_array_equal(got, anchors_hit_numpy(cum, samples, k, j, i0s, i1s, qs))


@settings(max_examples=150, deadline=None)
@given(st.integers(0, 2**31), st.integers(2, 50), st.integers(0, 60), st.integers(0, 60),
       st.floats(-20, 20), st.floats(-20, 20))
def test_min_segment_distance_is_numpys_minimum(seed, n, k, hi, x, y):
    samples = _polyline(seed, n)
    k = min(k, n - 1)
    hi = min(hi, n - 1)
    seg = points_to_segments_distance(np.array([[x, y]]), samples[k:hi], samples[k + 1 : hi + 1])
    want = float(seg.min()) if seg.size else 0.0
    assert min_segment_distance(samples, x, y, k, hi) == want


def rank_numpy(samples, cum, ends, t_ends, js, b, stride, wt, bonus, kappa, n_over, special):
    """``Fitter._rank`` as it was: the compiled reach scan, then numpy."""
    reach, lreach = reach_lines(samples, ends, t_ends, js, b, stride, wt)
    reach = np.where(js >= b, b, reach)
    lreach = np.where(js >= b, b, lreach)
    lscore = cum[lreach] + 0.3 * (cum[lreach] - cum[js])
    score = np.maximum(cum[reach], lscore) + bonus
    isarc = kappa != 0.0
    order = np.lexsort((-js, isarc, -score, n_over))
    order = np.concatenate([order[special[order]], order[~special[order]]])
    return order, reach


@settings(max_examples=120, deadline=None)
@given(st.integers(0, 2**31), st.integers(8, 120), st.integers(1, 60), st.integers(1, 3),
       st.booleans())
def test_rank_candidates_is_the_numpy_ranking(seed, n, nc, stride, anchored):
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, rng.uniform(0.5, 4.0), n)
    r = rng.uniform(5.0, 50.0)
    samples = np.ascontiguousarray(np.stack([r * np.sin(t / 4), r * (1 - np.cos(t / 4))], 1)
                                   + rng.normal(0.0, 0.005, (n, 2)))
    cum = _cum(samples)
    b = n - 1
    js = rng.integers(1, n, nc).astype(np.int64)
    ang = np.arctan2(np.gradient(samples[:, 1]), np.gradient(samples[:, 0]))[js]
    ang = ang + rng.normal(0.0, 0.02, nc)
    ends = np.ascontiguousarray(samples[js] + rng.normal(0.0, 0.01, (nc, 2)))
    t_ends = np.ascontiguousarray(np.stack([np.cos(ang), np.sin(ang)], 1))
    # bonuses of lines (30 % of their length), ties between candidates' scores
    bonus = np.where(rng.random(nc) < 0.3, 0.3 * cum[js], 0.0)
    kappa = np.where(rng.random(nc) < 0.3, 0.0, rng.normal(0.0, 0.05, nc))
    n_over = (rng.integers(0, 3, nc) if anchored else np.zeros(nc)).astype(np.int64)
    special = (rng.random(nc) < 0.2) if anchored else np.zeros(nc, dtype=bool)
    wt = float(rng.uniform(0.01, 0.2))
    args = (samples, cum, ends, t_ends, js, b, stride, wt, bonus, kappa)
    got_order, got_reach = rank_candidates(*args, n_over if anchored else None, special)
    want_order, want_reach = rank_numpy(*args, n_over, special)
    np.testing.assert_array_equal(got_reach, want_reach)
    np.testing.assert_array_equal(got_order, want_order)


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 2**31), st.sampled_from([0.0, 0.02, -0.3, 1e-9]),
       st.floats(0.0, 1.0), st.floats(-3.0, 3.0), st.floats(-3.0, 3.0),
       st.floats(0.0, 2.0 * math.pi))
def test_one_piece_first_point_is_the_general_path(seed, kappa, f, dx, dy, th):
    """The one-piece fast path's distance and nearest piece are ``_nearest_piece``'s,
    and the growth bound from its figures is ``piece_growth``'s."""
    rng = np.random.default_rng(seed)
    px, py = rng.uniform(-10, 10, 2)
    a = rng.uniform(0, 2 * math.pi)
    tx, ty = math.cos(a), math.sin(a)
    length = float(rng.uniform(0.1, 15.0))
    if kappa != 0.0:
        length = min(length, 0.95 * 2 * math.pi / abs(kappa))
    s = f * length
    if kappa == 0.0:
        x0, y0 = px + s * tx, py + s * ty
        ex, ey = px + length * tx, py + length * ty
    else:
        x0 = px + (math.sin(kappa * s) * tx - (1 - math.cos(kappa * s)) * ty) / kappa
        y0 = py + (math.sin(kappa * s) * ty + (1 - math.cos(kappa * s)) * tx) / kappa
        ex = px + (math.sin(kappa * length) * tx - (1 - math.cos(kappa * length)) * ty) / kappa
        ey = py + (math.sin(kappa * length) * ty + (1 - math.cos(kappa * length)) * tx) / kappa
    geo = np.array([[px, py, tx, ty, kappa, length, ex, ey]])
    x, y = x0 + 0.05 * dx, y0 + 0.05 * dy
    ux, uy = math.cos(th), math.sin(th)
    d, q, u, v, ang, gap = one_piece_distance(geo, 0, x, y)
    want_d, want_q = _nearest_piece(geo, np.array([0], dtype=np.int64), x, y)
    assert (d, q) == (want_d, want_q)
    assert piece_growth_at(geo, 0, u, v, ang, gap, ux, uy) == piece_growth(geo, 0, x, y, ux, uy)


#: whether each example of the landing test landed (both outcomes must occur)
LANDED: list[bool] = []


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**31), st.floats(0.01, 0.3), st.floats(-0.6, 0.6),
       st.floats(-0.3, 0.3), st.integers(1, 5))
def test_landing_pair_is_one_biarc_per_landing_point(seed, tol, turn, off, n_land):
    """The landing kernel returns the first landing point whose biarc (with radii of at
    least the tolerance) ``ToleranceBand.biarc`` finds, trying them one by one."""
    rng = np.random.default_rng(seed)
    # an arc bending onto a straight run, sampled at a quarter of a millimetre
    s = np.arange(0.0, 30.0, 0.25)
    r = rng.uniform(8.0, 40.0)
    th = np.minimum(s, 12.0) / r
    head = np.stack([r * np.sin(th), r * (1 - np.cos(th))], 1)
    d = np.array([math.cos(th[-1]), math.sin(th[-1])])
    tail = head[s <= 12.0][-1] + (s[s > 12.0] - 12.0)[:, None] * d
    samples = np.ascontiguousarray(np.vstack([head[s <= 12.0], tail])
                                   + rng.normal(0.0, 0.1 * tol, (len(s), 2)))
    band = ToleranceBand(samples, tol, 0.9, None)
    k = int(rng.integers(0, 20))
    a0 = turn + math.atan2(samples[k + 1, 1] - samples[k, 1], samples[k + 1, 0] - samples[k, 0])
    p0 = samples[k] + off * tol * np.array([-math.sin(a0), math.cos(a0)])
    t0 = np.array([math.cos(a0), math.sin(a0)])
    i0 = int(np.searchsorted(s, 12.0)) + 1
    ms = sorted({int(m) for m in rng.integers(i0, len(s) - 1, n_land)})
    q = samples[i0]
    p1s = np.array([q + float((samples[m] - q) @ d) * d for m in ms])
    i, f, m1 = landing_pair(samples, p0, t0, k, 0.0, np.array(ms, dtype=np.int64), p1s, d,
                            band.splits_array(StraightRuns.LANDING_SPLITS), tol,
                            band.dense_step, band.kmin, band.kcap)
    want = None
    for n, m in enumerate(ms):
        got = band.biarc(p0, t0, k, 0.0, m, d, p1s[n], StraightRuns.LANDING_SPLITS)
        if got is not None and max(abs(got[0].kappa), abs(got[1].kappa)) <= 1.0 / tol:
            want = (n, got)
            break
    LANDED.append(want is not None)
    if want is None:
        assert i == -1
        return
    assert i == want[0]
    pieces = band.biarc_pieces(p0, t0, k, ms[i], d, p1s[i], False, f, m1)
    for a, b in zip(pieces, want[1], strict=True):
        assert (a.kappa, a.length, a.k, a.j, a.e_end) == (b.kappa, b.length, b.k, b.j, b.e_end)
        np.testing.assert_array_equal(a.end, b.end)
        np.testing.assert_array_equal(a.t_end, b.t_end)


def test_landing_examples_took_both_outcomes():
    """The landing test above saw landings found and refused (else it proves little)."""
    test_landing_pair_is_one_biarc_per_landing_point()
    assert any(LANDED) and not all(LANDED)
