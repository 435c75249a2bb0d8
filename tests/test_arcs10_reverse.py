"""Runs between pinned ends also fitted backwards with the default seam (issue 15,
session 10: :func:`zwcore.arcs._runs._reverse_runs`): the chains stay C1 at every smooth
junction, two-sided within the tolerance (checked here by a plain distance computation
of its own), keep their corners, never gain a segment and lose some on the glyph
contours named below."""

from __future__ import annotations

import itertools
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.test_arcs import assert_valid, flat_arcs
from zwcore.arcs import _runs
from zwcore.arcs.fit import ArcChain, Segment, fit_arcs

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))


def _point_segment_dist(q: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance of each point of ``q`` ``(Q, 2)`` to the nearest of the segments
    ``a[i]..b[i]`` ``(S, 2)``."""
    d = b - a
    dd = np.maximum(np.einsum("ij,ij->i", d, d), 1e-300)
    f = np.clip(((q[:, None, :] - a[None]) * d[None]).sum(-1) / dd[None], 0.0, 1.0)
    foot = a[None] + f[..., None] * d[None]
    return np.hypot(*(q[:, None, :] - foot).transpose(2, 0, 1)).min(axis=1)


def _point_piece_dist(q: np.ndarray, s: Segment) -> np.ndarray:
    """Distance of the points ``q`` ``(Q, 2)`` to the segment ``s`` (exact: a line's
    foot point, an arc's radial foot when its angle lies within the sweep, else the
    nearer end)."""
    p0, p1 = np.array(s.start), np.array(s.end)
    if s.kind == "line":
        return _point_segment_dist(q, p0[None], p1[None])
    assert s.center is not None and s.radius is not None and s.sweep is not None
    c = np.array(s.center)
    a0 = math.atan2(p0[1] - c[1], p0[0] - c[0])
    ang = np.arctan2(q[:, 1] - c[1], q[:, 0] - c[0])
    # the angle from the start along the sweep's direction, in [0, 2 pi)
    rel = np.mod((ang - a0) * np.sign(s.sweep), 2.0 * math.pi)
    inside = rel <= abs(s.sweep)
    radial = np.abs(np.hypot(q[:, 0] - c[0], q[:, 1] - c[1]) - s.radius)
    ends = np.minimum(np.hypot(*(q - p0).T), np.hypot(*(q - p1).T))
    return np.where(inside, radial, ends)


def _along(s: Segment, step: float) -> np.ndarray:
    """Points along ``s`` at spacing at most ``step`` (from its own parameters)."""
    n = max(math.ceil(s.length / step), 1) + 1
    f = np.linspace(0.0, 1.0, n)
    p0 = np.array(s.start)
    if s.kind == "line":
        return p0[None] + f[:, None] * (np.array(s.end) - p0)[None]
    assert s.center is not None and s.radius is not None and s.sweep is not None
    c = np.array(s.center)
    ang = math.atan2(p0[1] - c[1], p0[0] - c[0]) + f * s.sweep
    return c[None] + s.radius * np.stack([np.cos(ang), np.sin(ang)], 1)


def _two_sided(chain: ArcChain, pts: np.ndarray, tol: float) -> tuple[float, float]:
    """The polyline (closed) to the chain and the chain to the polyline, both sampled
    every ``tol / 8``."""
    ring = np.vstack([pts, pts[:1]])
    dense = [ring[:1]]
    for a, b in itertools.pairwise(ring):
        n = max(math.ceil(math.dist(a, b) / (tol / 8)), 1)
        dense.append(a[None] + np.linspace(0.0, 1.0, n + 1)[1:, None] * (b - a)[None])
    poly = np.vstack(dense)
    to_chain = np.min([_point_piece_dist(poly, s) for s in chain.segments], axis=0)
    on_chain = np.vstack([_along(s, tol / 8) for s in chain.segments])
    to_poly = np.concatenate([_point_segment_dist(on_chain[i : i + 2000], ring[:-1], ring[1:])
                              for i in range(0, len(on_chain), 2000)])
    return float(to_chain.max()), float(to_poly.max())


def _kinks(chain: ArcChain) -> list[float]:
    """The tangent turn at every junction (the closing one included), from the
    segments' end points and centres."""
    def tangent(s: Segment, at: tuple[float, float]) -> np.ndarray:
        if s.kind == "line":
            d = np.subtract(s.end, s.start)
            return d / np.hypot(*d)
        assert s.center is not None
        r = np.subtract(at, s.center)
        r = r / np.hypot(*r)
        return np.array([-r[1], r[0]]) if s.ccw else np.array([r[1], -r[0]])

    segs = chain.segments
    out = []
    for i, s in enumerate(segs):
        t0, t1 = tangent(s, s.end), tangent(segs[(i + 1) % len(segs)],
                                             segs[(i + 1) % len(segs)].start)
        out.append(abs(math.atan2(t0[0] * t1[1] - t0[1] * t1[0], t0 @ t1)))
    return out


@pytest.fixture(scope="module")
def glyph_sets():
    from glyphs import GLYPHS, glyph_contours

    # (all of the benchmark's glyphs: the noise is drawn contour after contour)
    return glyph_contours(GLYPHS)


def _contour(sets, name: str, label: str) -> tuple[np.ndarray, np.ndarray]:
    return next((np.asarray(p, float), c) for lb, p, c in sets[name] if lb == label)


# (sampling, tol, contour, segments at most: this session's count; main's in the comment)
GAINS = [
    ("noisy", 0.05, "B2", 12),  # main 14
    ("noisy", 0.05, "R0", 21),  # main 22
    ("noisy", 0.05, "&1", 23),  # main 25
    ("noisy", 0.05, "d0", 17),  # main 18
    ("noisy", 0.05, "e1", 7),  # main 8
    ("chordal", 0.05, "R0", 17),  # main 18
    ("chordal", 0.05, "b1", 14),  # main 15
    ("chordal", 0.05, "d0", 14),  # main 15
    ("chordal", 0.01, "S0", 40),  # main 42
    ("chordal", 0.01, "@1", 42),  # main 44
]


@pytest.mark.parametrize(("name", "tol", "label", "most"), GAINS)
def test_glyph_contours_fewer_segments_valid(name, tol, label, most, glyph_sets):
    pts, corners = _contour(glyph_sets, name, label)
    chain = fit_arcs(pts, tol, closed=True)
    assert len(chain.segments) <= most
    assert_valid(chain, pts, tol, True)
    # two-sided within the tolerance by a distance computation of this test's own
    d_poly, d_chain = _two_sided(chain, pts, tol)
    assert d_poly <= tol * (1 + 1e-6) and d_chain <= tol * (1 + 1e-6), (d_poly, d_chain)
    # C1 at every junction but the corners, and every true corner still one
    kinks = _kinks(chain)
    assert all(k <= 1e-7 for i, k in enumerate(kinks) if i not in chain.corners)
    ends = np.array([chain.segments[i].end for i in chain.corners]).reshape(-1, 2)
    for c in corners:
        assert np.min(np.hypot(*(ends - c).T), initial=np.inf) <= 0.2 + 3 * tol


@pytest.mark.parametrize(("name", "tol"), [("noisy", 0.05), ("chordal", 0.05),
                                           ("noisy", 0.01)])
def test_backward_runs_never_add_segments_or_flat_arcs(name, tol, glyph_sets, monkeypatch):
    """Per contour: no more segments, flat arcs or corners lost than forwards only."""
    both = [fit_arcs(p, tol, closed=True) for _l, p, _c in glyph_sets[name]]
    monkeypatch.setattr(_runs, "_reverse_runs", lambda *a: True)
    fwd = [fit_arcs(p, tol, closed=True) for _l, p, _c in glyph_sets[name]]
    for (_l, p, _c), ch, f in zip(glyph_sets[name], both, fwd, strict=True):
        assert len(ch.segments) <= len(f.segments)
        assert len(flat_arcs(ch, tol)) <= len(flat_arcs(f, tol))
        assert len(ch.corners) == len(f.corners)
        assert_valid(ch, np.asarray(p, float), tol, True)
    assert sum(len(c.segments) for c in both) < sum(len(f.segments) for f in fwd)
