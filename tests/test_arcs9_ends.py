"""Pinned run ends redone with fewer pieces after the beam (issue 15, session 9:
:mod:`zwcore.arcs._ends`): every replacement keeps the chain C1, two-sided within the
tolerance, the run's end points (the corners) and never adds a segment."""

from __future__ import annotations

import itertools
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.test_arcs import assert_valid
from zwcore.arcs import _runs
from zwcore.arcs._ends import END_TURNS, end_tails, redo_ends, turned
from zwcore.arcs._pieces import Piece, ToleranceBand
from zwcore.arcs._search import Fitter, Stuck
from zwcore.arcs.fit import fit_arcs
from zwcore.arcs.verify import deviations

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))


def _wavy(rng: np.random.Generator, n: int, length: float, amp: float,
          noise: float) -> np.ndarray:
    """An open curve ``(n, 2)``: a sum of two sines of random phases, plus noise."""
    x = np.linspace(0.0, length, n)
    f1, f2 = rng.uniform(0.05, 0.3, 2)
    p1, p2 = rng.uniform(0.0, 2 * math.pi, 2)
    y = amp * (np.sin(f1 * x + p1) + 0.5 * np.sin(f2 * x + p2))
    return np.stack([x, y], 1) + rng.uniform(-noise, noise, (n, 2))


def _assert_c1_chain(pieces: list[Piece], samples: np.ndarray, a: int, b: int,
                     tol: float) -> None:
    """Consecutive pieces meet with the same point and tangent, the chain runs from
    sample ``a`` to sample ``b`` and keeps ``tol`` both ways over ``a..b``."""
    assert np.allclose(pieces[0].p, samples[a], atol=1e-9, rtol=0)
    assert np.allclose(pieces[-1].end, samples[b], atol=1e-9, rtol=0)
    for p, q in itertools.pairwise(pieces):
        assert p.j == q.k
        assert np.allclose(p.end, q.p, atol=1e-9, rtol=0)
        # C1: the tangents agree to rounding (a biarc's arrival is checked to 1e-9)
        assert abs(p.t_end[0] * q.t[1] - p.t_end[1] * q.t[0]) <= 1e-8
        assert p.t_end @ q.t > 0.0
    dp, dc = deviations(np.ascontiguousarray(samples[a:b + 1]),
                        [_shift(pc, a) for pc in pieces], tol)
    assert dp <= tol * (1 + 1e-9) and dc <= tol * (1 + 1e-9), (dp, dc)


def _shift(pc: Piece, a: int) -> Piece:
    return Piece(pc.p, pc.t, pc.kappa, pc.length, pc.k - a, pc.j - a, pc.end, pc.t_end,
                 pc.e_end)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**31), tol=st.sampled_from([0.01, 0.05, 0.1]),
       noise=st.sampled_from([0.0, 0.2]), pin_start=st.booleans())
def test_redo_ends_keeps_c1_band_and_ends(seed, tol, noise, pin_start):
    rng = np.random.default_rng(seed)
    samples = _wavy(rng, int(rng.integers(80, 400)), 80.0, 6.0, noise * tol)
    b = len(samples) - 1
    f = Fitter(samples, tol, 0.97, None)
    try:
        pieces, forced = f.run(0, b, False, allow_forced=False)
    except Stuck:
        return
    if forced or len(pieces) < 2:
        return
    back = ToleranceBand(np.ascontiguousarray(samples[::-1]), tol, 0.97, None)
    got = redo_ends(pieces, f.band, lambda: back, 0, b, pin_start, True,
                    lambda pcs: (0, 0, len(pcs)))
    assert len(got) <= len(pieces)
    _assert_c1_chain(got, samples, 0, b, tol)
    # every tail offered is shorter and valid too
    for alt in end_tails(pieces, f.band, b):
        assert len(alt) < len(pieces)
        _assert_c1_chain(alt, samples, 0, b, tol)


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**31))
def test_turned_twice_is_the_chain(seed):
    rng = np.random.default_rng(seed)
    samples = _wavy(rng, 150, 60.0, 5.0, 0.0)
    f = Fitter(samples, 0.05, 0.97, None)
    pieces, _ = f.run(0, len(samples) - 1, False, allow_forced=False)
    back = turned(pieces, np.ascontiguousarray(samples[::-1]))
    # the reversed chain runs along the reversed samples: C1, same band
    _assert_c1_chain(back, np.ascontiguousarray(samples[::-1]), 0, len(samples) - 1, 0.05)
    again = turned(back, samples)
    for p, q in zip(pieces, again, strict=True):
        assert (p.k, p.j) == (q.k, q.j)
        assert p.kappa == q.kappa and p.length == q.length
        assert np.array_equal(p.p, q.p) and np.array_equal(p.end, q.end)
        assert np.array_equal(p.t, q.t) and np.array_equal(p.t_end, q.t_end)


def test_end_turns_include_the_last_tangent():
    assert END_TURNS[0] == 0.0
    assert all(-d in END_TURNS for d in END_TURNS)


@pytest.fixture(scope="module")
def glyph_sets():
    from glyphs import glyph_contours

    return glyph_contours("gdb")


@pytest.mark.parametrize("row", [("noisy", 0.05), ("even", 0.05), ("chordal", 0.05)])
def test_glyph_runs_never_gain_a_segment(row, glyph_sets, monkeypatch):
    """On glyph outlines (corners: runs pinned at both ends) the chains are valid
    (C1 but at corners, both ways within tol, corners on input points) and each contour
    has at most the segments it has without the redone ends, fewer on some."""
    name, tol = row
    with_ends = [fit_arcs(pts, tol, closed=True) for _l, pts, _c in glyph_sets[name]]
    monkeypatch.setattr(_runs, "redo_ends", lambda pieces, *args, **kw: pieces)
    without = [len(fit_arcs(pts, tol, closed=True).segments)
               for _l, pts, _c in glyph_sets[name]]
    for (_l, pts, corners), ch in zip(glyph_sets[name], with_ends, strict=True):
        assert_valid(ch, pts, tol, True)
        for c in corners:
            # a true corner of the outline is still a sharp corner of the chain
            ends = np.array([ch.segments[i].end for i in ch.corners]).reshape(-1, 2)
            assert np.min(np.hypot(*(ends - c).T), initial=np.inf) <= 0.5
    counts = [len(ch.segments) for ch in with_ends]
    assert all(n <= m for n, m in zip(counts, without, strict=True)), (counts, without)
    if name == "noisy":
        assert sum(counts) < sum(without)
