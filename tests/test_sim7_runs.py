"""The block sweep's row runs and its bands (sim7), on what a finishing program is made of:
zigzag scan lines of short moves along x with a large ball, read against the plain kernel
(every node gathered, its own envelope loops) and a brute-force sampled sweep."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import zwcore.toolpath.sweep as sweep_mod
from tests.test_toolpath import sampled_envelope, wavy_part
from tests.test_toolpath_kernels import KERNEL_ROUNDING
from zwcore.toolpath.sweep import BlockBounds, GridFrame, sweep_moves


def _scan_lines(part, rng: np.random.Generator, radius: float, lines: int) -> np.ndarray:
    """Tip points of a zigzag over the part: lines along x (on node rows and between them),
    short moves whose z follows the part's row plus a lift, linked by steps along y."""
    ny, nx = part.shape
    pts = []
    for j, v in enumerate(np.sort(rng.uniform(0, (ny - 1) * part.dy, lines))):
        if rng.random() < 0.5:  # exactly on a node row
            v = round(v / part.dy) * part.dy
        u = np.sort(rng.uniform(-radius, (nx - 1) * part.dx + radius, int(rng.integers(5, 25))))
        u = u if j % 2 == 0 else u[::-1]
        row = part.z[min(round(v / part.dy), ny - 1)]
        z = np.interp(u, np.arange(nx) * part.dx, row) + rng.uniform(-0.2, 0.8, len(u))
        pts.append(np.column_stack([part.x0 + u, np.full(len(u), part.y0 + v), z]))
    return np.vstack(pts)


@settings(max_examples=12, deadline=None)
@given(st.integers(0, 10_000), st.sampled_from([2, 3, 5, 8]), st.floats(1.0, 3.0),
       st.sampled_from([1, 2, 3]), st.sampled_from([1, 4, 16]))
def test_scan_lines_swept_in_row_runs_and_bands_are_the_plain_sweep(seed, block, radius,
                                                                    threads, bands):
    part = wavy_part(61, 0.1, seed, amplitude=1.0)
    frame = GridFrame(part.x0, part.y0, part.dx, part.dy, part.shape)
    rng = np.random.default_rng(seed)
    pts = _scan_lines(part, rng, radius, int(rng.integers(2, 6)))
    p0, p1 = pts[:-1].copy(), pts[1:].copy()
    apply = rng.random(len(p0)) < 0.95
    top = part.z.max() + 1.0
    plain, runs = np.full(part.shape, top), np.full(part.shape, top)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(sweep_mod, "SWEEP_THREADS", threads)
        mp.setattr(sweep_mod, "MIN_MOVES_PER_THREAD", 10)
        mp.setattr(sweep_mod, "BANDS_PER_THREAD", bands)
        a_s, a_r = sweep_moves(frame, p0, p1, radius, True, plain, ref=part.z, apply=apply)
        b_s, b_r = sweep_moves(frame, p0, p1, radius, True, runs, ref=part.z, apply=apply,
                               bounds=BlockBounds(frame, runs, part.z, block), trail=True)
    np.testing.assert_allclose(runs, plain, rtol=0, atol=KERNEL_ROUNDING)
    eps = 1e-9  # met material / below the part: the same moves say so
    np.testing.assert_allclose(np.maximum(b_s, eps), np.maximum(a_s, eps), rtol=0, atol=1e-11)
    assert abs(max(b_r.max(), 0.0) - max(a_r.max(), 0.0)) <= 1e-11
    # brute force, independent of both kernels: the ball placed at many points of each
    # cutting move removes no more than the sweep did (the sweep is the exact lowest point
    # over every position of the move), and the sweep never cuts below the lowest tip of a
    # move whose ball reaches the node
    sampled = np.full(part.shape, top)
    for s in np.flatnonzero(apply):
        sampled = np.minimum(sampled, sampled_envelope(frame, p0[s], p1[s], radius, True,
                                                       samples=65))
    assert np.all(runs <= sampled + 1e-9)
    assert runs.min() >= min(p0[apply, 2].min(), p1[apply, 2].min()) - 1e-9
