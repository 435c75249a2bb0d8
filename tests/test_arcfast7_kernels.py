"""The compiled probes of the corner finder (:func:`zwcore.arcs._prepare._probe_turns`)
give numpy's figures bit for bit: the numpy formulation it replaced is the reference."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from zwcore.arcs._prepare import _probe_turns, find_corners


def _interp_polyline(x: np.ndarray, s: np.ndarray, at: np.ndarray) -> np.ndarray:
    return np.stack([np.interp(at, s, x[:, 0]), np.interp(at, s, x[:, 1])], axis=1)


def probe_turns_numpy(x: np.ndarray, closed: bool, d_probe: float) -> tuple:
    """``_probe_turns`` as numpy expressions (the code before the kernel)."""
    n = len(x)
    if closed:
        xx = np.vstack([x, x[:1]])
        seg = np.hypot(*(np.diff(xx, axis=0).T))
        total = float(seg.sum())
        s = np.concatenate([[0.0], np.cumsum(seg)])
        x3 = np.vstack([xx[:-1], xx[:-1], xx])
        s3 = np.concatenate([s[:-1] - total, s[:-1], s + total])
        si = s[:-1]
        before = _interp_polyline(x3, s3, si - min(d_probe, 0.25 * total))
        after = _interp_polyline(x3, s3, si + min(d_probe, 0.25 * total))
        idx = np.arange(n)
    else:
        seg = np.hypot(*(np.diff(x, axis=0).T))
        s = np.concatenate([[0.0], np.cumsum(seg)])
        si = s[1:-1]
        before = _interp_polyline(x, s, np.maximum(si - d_probe, 0.0))
        after = _interp_polyline(x, s, np.minimum(si + d_probe, s[-1]))
        idx = np.arange(1, n - 1)
    pc = x[idx]
    a = pc - before
    b = after - pc
    turn = np.abs(np.arctan2(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0], (a * b).sum(axis=1)))
    chord = after - before
    clen = np.maximum(np.hypot(chord[:, 0], chord[:, 1]), 1e-300)
    height = np.abs(chord[:, 0] * a[:, 1] - chord[:, 1] * a[:, 0]) / clen
    return turn, height, idx, si, s


@st.composite
def polylines(draw):
    rng = np.random.default_rng(draw(st.integers(0, 2**31)))
    n = draw(st.integers(2, 80))
    kind = draw(st.sampled_from(["random", "walk", "arc", "collinear"]))
    if kind == "random":
        p = rng.uniform(-5, 5, (n, 2))
    elif kind == "walk":
        p = np.cumsum(rng.normal(0, 1, (n, 2)), axis=0)
    elif kind == "arc":
        t = np.sort(rng.uniform(0, 6, n))
        p = np.stack([np.cos(t), np.sin(t)], 1)
    else:
        p = np.outer(np.sort(rng.uniform(0, 10, n)), [0.6, 0.8])
    scale = 10.0 ** draw(st.integers(-3, 3))
    p = p * scale + rng.uniform(-1e4, 1e4, 2) * draw(st.sampled_from([0.0, 1.0]))
    return p - p[0], draw(st.booleans()), draw(st.sampled_from([1e-4, 0.003, 0.3, 3.0]))


@settings(max_examples=300, deadline=None)
@given(polylines())
def test_probe_turns_are_numpys(case):
    x, closed, d_probe = case
    got = _probe_turns(x, closed, d_probe)
    ref = probe_turns_numpy(x, closed, d_probe)
    for g, r in zip(got, ref, strict=True):
        assert g.shape == r.shape and np.array_equal(g, r, equal_nan=True)


def test_corners_of_a_square_and_a_circle():
    """An independent check of what the probes feed: a square's four corners, none on a
    circle sampled finely (turns there are 0.3 deg over the probes)."""
    side = np.linspace(0.0, 10.0, 21)[:-1]
    sq = np.vstack([np.stack([side, 0 * side], 1), np.stack([10 + 0 * side, side], 1),
                    np.stack([10 - side, 10 + 0 * side], 1), np.stack([0 * side, 10 - side], 1)])
    assert find_corners(sq, True, 0.1, np.radians(30.0)) == [0, 20, 40, 60]
    th = np.linspace(0, 2 * np.pi, 629)[:-1]
    assert find_corners(np.stack([50 * np.cos(th), 50 * np.sin(th)], 1), True, 0.1,
                        np.radians(30.0)) == []
