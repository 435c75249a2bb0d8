"""Issue 12: where the plan says it finishes, the *program* stays within the tolerance.

The plan's simulated stock is exact at its own positions' CL; the program's points are
thinned to a chordal tolerance (up to that much above the dropped CL) and its CL between
the plan's positions comes from other samples. With the plan holding the whole tolerance
the program left up to 12 % more where the plan finished (1025² bench part 0.0106 mm,
513² 0.0112, Mount Rushmore 0.0109 at 0.01). The plan now holds ``SCALLOP_SHARE`` of it
and the chords ``CHORD_SHARE``. Checked by the product's own path (default drop-cutter CL,
rest regions) against the independent parse and sweep of the emitted program; with the
old split (the plan holding the whole tolerance) these cases fail: the synthetic part at
each grid below, and 6 of the first 30 seeds of the wavy parts at 0.01.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bench.bench_scanline_core import synthetic
from tests.test_toolpath import wavy_part
from zwcore import ZMap, plan_scanline
from zwcore.scanline.results import SCALLOP_SHARE
from zwcore.toolpath import scanline_toolpaths
from zwcore.toolpath.parse import parse_program


def _program_left(part: ZMap, tolerance: float) -> tuple[np.ndarray, np.ndarray, float]:
    """What the verified program leaves over the part, the plan's finished mask, and the
    verification's own figure there."""
    plan = plan_scanline(part, tolerance=tolerance)
    assert plan.tolerance == tolerance
    assert plan.scallop_tolerance == pytest.approx(SCALLOP_SHARE * tolerance)
    assert plan.finished is not None and plan.finished.any()
    tp = scanline_toolpaths(part, plan)
    chk = tp.check
    assert chk is not None
    assert chk.gouge <= 1e-9 and chk.below_part_moves == 0 and chk.rapid_in_material == 0.0
    # the program is a real one: it parses back (the check swept this parse)
    assert (parse_program(tp.program).motion == 1).sum() > 0
    left = chk.machined - part.z
    return left, plan.finished, chk.finished_over_part_max


# (nodes a side, tolerance): the grids where the plan finishes most of the part. (On
# coarser ones the drop-cutter's bilinear bound, about cell_diagonal² / 8R, takes most of
# 70 % of the tolerance and the plan finishes little: 193² at 0.02, 0.8 %.)
@pytest.mark.parametrize(("n", "tolerance"), [(129, 0.05), (193, 0.05), (257, 0.02)])
def test_program_within_tolerance_where_the_plan_finishes(n: int, tolerance: float):
    left, finished, reported = _program_left(synthetic(n), tolerance)
    assert left.min() >= -1e-9
    assert left[finished].max() <= tolerance
    assert reported == pytest.approx(left[finished].max(), abs=1e-12)
    # the plan finishes most of this part (bumps, a fillet pocket, a wall)
    assert finished.mean() > 0.6


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 2**31 - 1), st.sampled_from([(65, 0.25, 0.01), (49, 0.5, 0.02)]))
def test_program_within_tolerance_where_the_plan_finishes_on_random_surfaces(seed, case):
    n, dx, tolerance = case
    left, finished, _ = _program_left(wavy_part(n, dx, seed), tolerance)
    assert left.min() >= -1e-9
    assert left[finished].max() <= tolerance


def test_coarse_grid_takes_the_per_cell_bound_and_finishes():
    """At 257² (0.39 mm) the planes' gap of a Ø8 alone (0.0095 mm) is over the plan's 0.007:
    one plane per cell held every small ball so high that the plan finished 0.6 % of the
    part (its program within the tolerance on 20 %). With the ball's curvature under each
    cell (``cell_bound``) it finishes most of it, and the program holds it there."""
    part = synthetic(257)
    plan = plan_scanline(part, tolerance=0.01)
    assert plan.cell_bound
    left, finished, _ = _program_left(part, 0.01)
    assert finished.mean() > 0.5
    assert left[finished].max() <= 0.01
    assert (left <= 0.01).mean() > 0.8


def test_fine_grid_keeps_the_planes():
    """At 0.1 mm the Ø1's planes' gap (0.005 mm) is under 0.007: no per-cell bound (it
    follows a scanned surface's detail into programs twice the size)."""
    y, x = np.mgrid[0:40, 0:40] * 0.1
    part = ZMap(np.sin(x) * np.cos(y), dx=0.1, dy=0.1)
    assert not plan_scanline(part, tolerance=0.01).cell_bound
    assert plan_scanline(ZMap(part.z[::3, ::3], dx=0.3, dy=0.3), tolerance=0.01).cell_bound
