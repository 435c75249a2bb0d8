"""A flat arc left at a pinned end of an open curve is refitted along a shorter line from
that end (issue 15: NACA 2412 sampled at 0.2 mm, at 0.05 mm).

Checked against independent computations: the distance of samples to a line through the
pin (numpy, point by point), the chain densely sampled against the polyline (brute force
over every segment), the tangents at the junctions from the segments' geometry.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))

from curves import BENCH_CURVES

from zwcore.arcs._straight import PINNED_BAND, PINNED_SHRINK, Anchor, pinned_shorter
from zwcore.arcs.fit import ArcChain, fit_arcs, segment_points


def _offsets(pts: np.ndarray, q: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Distance of each point ``(M, 2)`` from the line through ``q`` along ``d``."""
    return np.abs((pts[:, 0] - q[0]) * d[1] - (pts[:, 1] - q[1]) * d[0]) / np.hypot(*d)


def _bowed_tail(radius: float, length: float, step: float) -> np.ndarray:
    """A gentle arc of ``radius`` over ``length`` mm sampled every ``step`` mm, ending at
    its last point (the pinned end), shape ``(M, 2)``."""
    th = np.arange(0.0, length / radius, step / radius)
    return np.stack([radius * np.sin(th), radius - radius * np.cos(th)], 1)


@settings(max_examples=40, deadline=None)
@given(radius=st.floats(2_000.0, 50_000.0), length=st.floats(10.0, 60.0),
       tol=st.sampled_from([0.01, 0.05, 0.1]), at_end=st.booleans())
def test_pinned_shorter_runs_keep_their_band_through_the_pin(radius, length, tol, at_end):
    pts = _bowed_tail(radius, length, 0.2)
    if not at_end:
        pts = pts[::-1].copy()
    b = len(pts) - 1
    pin = b if at_end else 0
    an = Anchor(0, b, pts[pin].copy(), np.array([1.0, 0.0]))
    got = pinned_shorter(an, pts, 0, b, tol)
    prev_len = b
    for short in got:
        # each run ends at the pin, passes through it, and is shorter than the last
        assert (short.i1 == b) if at_end else (short.i0 == 0)
        assert np.array_equal(short.q, pts[pin])
        assert short.i1 - short.i0 < prev_len
        prev_len = short.i1 - short.i0
        assert abs(np.hypot(*short.d) - 1.0) < 1e-12
        # the line through the pin with the run's direction: within the loosest share
        # (the direction is the least-squares one, the band is the pinned line's)
        seg = pts[short.i0 : short.i1 + 1]
        assert _offsets(seg, short.q, short.d).max() <= PINNED_SHRINK[0] * PINNED_BAND * tol \
            * (1 + 1e-9) + 1e-12


def test_pinned_shorter_needs_exactly_one_pinned_end():
    pts = _bowed_tail(5_000.0, 40.0, 0.2)
    b = len(pts) - 1
    free = Anchor(0, b, pts.mean(axis=0), np.array([1.0, 0.0]))
    assert pinned_shorter(free, pts, 0, b, 0.05) == []
    inner = Anchor(10, b - 10, pts[10].copy(), np.array([1.0, 0.0]))
    assert pinned_shorter(inner, pts, 0, b, 0.05) == []  # pinned, but not at a run end


def _to_segments(q: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Exact distance of each point ``q`` ``(M, 2)`` to the nearest segment ``a[i]-b[i]``."""
    ab = b - a
    den = np.maximum((ab * ab).sum(1), 1e-300)
    f = np.clip(((q[:, None, :] - a[None]) * ab[None]).sum(2) / den, 0.0, 1.0)
    near = a[None] + f[..., None] * ab[None]
    return np.hypot(*(q[:, None, :] - near).transpose(2, 0, 1)).min(1)


def _to_chain(q: np.ndarray, chain: ArcChain) -> np.ndarray:
    """Exact distance of each point ``q`` ``(M, 2)`` to the chain's lines and arcs."""
    out = np.full(len(q), np.inf)
    for s in chain.segments:
        st, en = np.array(s.start), np.array(s.end)
        if s.kind == "line":
            d = _to_segments(q, st[None], en[None])
        else:
            c = np.array(s.center)
            a0 = math.atan2(st[1] - c[1], st[0] - c[0])
            ang = np.arctan2(q[:, 1] - c[1], q[:, 0] - c[0]) - a0
            ang = np.mod(ang, 2 * np.pi) if s.sweep > 0 else np.mod(-ang, 2 * np.pi)
            on = ang <= abs(s.sweep)
            d_ends = np.minimum(np.hypot(*(q - st).T), np.hypot(*(q - en).T))
            d = np.where(on, np.abs(np.hypot(*(q - c).T) - s.radius), d_ends)
        out = np.minimum(out, d)
    return out


@pytest.mark.parametrize("step", [0.1, 0.25])
def test_naca_trailing_edge_ends_on_a_line_within_tolerance(step):
    tol = 0.05
    pts, _ = BENCH_CURVES["naca2412"](step)
    chain = fit_arcs(pts, tol)
    last = chain.segments[-1]
    assert last.kind == "line"
    assert last.end == pytest.approx(tuple(pts[-1]), abs=1e-9)
    # no arc of the chain is flat (sagitta below a quarter tolerance over 20 tolerances)
    for s in chain.segments:
        if s.kind == "arc" and s.length >= 20 * tol:
            assert s.radius * (1 - math.cos(0.5 * min(abs(s.sweep), math.pi))) >= 0.25 * tol
    # every sample within the tolerance of the chain (exact distances), and the chain
    # along the lower surface behind x = 100 mm, sampled every tol / 20, within it of the
    # polyline (exact distances to its segments; the distance moves by at most tol / 40
    # between chain points)
    assert _to_chain(pts, chain).max() <= tol * (1 + 1e-9)
    step_c = tol / 20
    tail = np.vstack([segment_points(s, step_c) for s in chain.segments
                      if s.end[0] > 100.0 and s.end[1] < 0.0])
    tail = tail[tail[:, 0] > 100.0]
    lower = np.flatnonzero((pts[:-1, 0] > 90.0) & (pts[:-1, 1] < 0.0))  # its segments
    worst = max(_to_segments(tail[i : i + 1000], pts[lower], pts[lower + 1]).max()
                for i in range(0, len(tail), 1000))
    assert worst <= tol + step_c / 2
    assert chain.max_deviation_points <= tol and chain.max_deviation_chain <= tol
    # C1: the tangents of consecutive segments agree
    for a, b in zip(chain.segments[:-1], chain.segments[1:], strict=True):
        ta, tb = a.end_tangent(), b.start_tangent()
        assert abs(ta[0] * tb[1] - ta[1] * tb[0]) < 1e-9 and ta[0] * tb[0] + ta[1] * tb[1] > 0


@pytest.mark.parametrize("tol", [0.1, 0.005, 0.0031])
def test_dense_step_is_the_pairwise_sums(tol):
    """The dense check's step (``tol / 20``, coarser beyond two million points: a compiled
    sum decides where it is not close) equals the figure from numpy's own sums: the
    deviations are those of the kernel called with it (a 50 mm circle: 628 mm of polyline
    and chain, above the bound at 0.005 and 0.0031, below it at 0.1)."""
    from zwcore.arcs._dense import dense_deviations
    from zwcore.arcs._prepare import prepare, validate
    from zwcore.arcs._runs import assemble
    from zwcore.arcs.verify import deviations

    pts, closed = BENCH_CURVES["circle"]()
    prep = prepare(validate(pts, tol, 30.0, None), tol, closed, 30.0)
    pieces = assemble(prep, None, True)[0]
    samples = prep.samples
    total = float(np.hypot(*(np.diff(samples, axis=0).T)).sum()) + sum(p.length for p in pieces)
    step = max(tol / 20.0, total / 2e6)
    geo = np.array([[p.p[0], p.p[1], p.t[0], p.t[1], p.kappa, p.length, p.end[0], p.end[1]]
                    for p in pieces])
    ks = np.array([p.k for p in pieces], dtype=np.int64)
    js = np.array([p.j for p in pieces], dtype=np.int64)
    assert deviations(samples, pieces, tol) == dense_deviations(samples, geo, ks, js, tol, step)
    assert (step > tol / 20.0) == (tol < 0.01)
