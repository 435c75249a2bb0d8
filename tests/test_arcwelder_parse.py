"""The ArcWelder reference of ``bench/bench_arcs.py --arcwelder`` without the binary:
its program parse-back, G1-run merging and the independent deviation / kink measures,
checked on hand-written programs against closed-form geometry."""

from __future__ import annotations

import itertools
import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))

from _arcwelder import (
    _program,
    deviation,
    max_kink,
    merge_g1_runs,
    merge_straight_runs,
    parse_moves,
    polyline_corners,
)


def test_parse_moves_reads_arcs_relative_to_their_start() -> None:
    text = ("; header\nG21\nG90\nM83\nG0 X10.0000 Y0.0000\n"
            "G3 X-10.000 Y0.000 I-10.000 J0 E3.14159 ;a comment\n"
            "G2 X-30 Y0 I-10 J0\nG1 X-30 Y5 E1\nG1 X-30 Y5 E1\n")
    segs = parse_moves(text)
    assert [s[0] for s in segs] == ["arc", "arc", "line"]  # the null move is dropped
    assert segs[0][1:] == ((10.0, 0.0), (-10.0, 0.0), (0.0, 0.0), True)
    assert segs[1][1:] == ((-10.0, 0.0), (-30.0, 0.0), (-20.0, 0.0), False)
    assert segs[2][1:] == ((-30.0, 0.0), (-30.0, 5.0))


def test_program_extrudes_at_a_constant_rate() -> None:
    rng = np.random.default_rng(3)
    pts = rng.uniform(-20, 20, (30, 2))
    text = _program(pts, closed=True)
    segs = parse_moves(text)
    assert len(segs) == 30
    # the moves as read back follow the input rounded to 4 decimals, closed
    path = np.vstack([pts, pts[:1]])
    np.testing.assert_allclose([s[1] for s in segs], path[:-1], atol=5e-5 + 1e-12)
    np.testing.assert_allclose([s[2] for s in segs], path[1:], atol=5e-5 + 1e-12)
    # every move's E is the length of the move as written (what ArcWelder reads), to 1e-6
    e = [float(r.split("E")[1]) for r in text.splitlines() if r.startswith("G1")]
    written = [math.dist(s[1], s[2]) for s in segs]
    np.testing.assert_allclose(e, written, rtol=0.0, atol=6e-7)


def test_g1_runs_merge_within_tolerance_but_not_round_a_corner() -> None:
    # a straight edge sampled every 0.2 mm, rounded to 4 decimals (not exactly collinear)
    t = np.linspace(0.0, 1.0, 51)
    edge = np.round(np.stack([3.0 + 7.13157 * t, 1.0 + 3.31937 * t], axis=1), 4)
    corner = np.array([[10.1, 9.0]])
    pts = np.vstack([edge, corner])
    segs = [("line", tuple(a), tuple(b)) for a, b in itertools.pairwise(pts)]
    merged = merge_g1_runs(segs, 0.001)
    assert len(merged) == 2
    assert merged[0][1:] == (tuple(edge[0]), tuple(edge[-1]))
    # at a tolerance smaller than the rounding, the edge may not merge to one line
    assert len(merge_g1_runs(segs, 1e-9)) > 2


@pytest.mark.parametrize("sweep_deg", [10.0, 60.0, 170.0])
def test_deviation_of_an_arc_from_its_chord_is_the_sagitta(sweep_deg: float) -> None:
    r = 5.0
    half = math.radians(sweep_deg) / 2
    a = (r * math.cos(-half), r * math.sin(-half))
    b = (r * math.cos(half), r * math.sin(half))
    chain = [("arc", a, b, (0.0, 0.0), True)]
    chord = np.array([a, b])
    step = 2e-3
    to_chain, to_poly = deviation(chain, chord, closed=False, step=step)
    sagitta = r * (1 - math.cos(half))
    # each sampled figure is within half a step of the exact one
    assert to_poly == pytest.approx(sagitta, abs=step / 2)
    # the chord's ends are on the arc; its middle is the sagitta away
    assert to_chain == pytest.approx(sagitta, abs=step / 2)


def test_kinks_are_measured_away_from_true_corners() -> None:
    # a square: four 90 deg corners; with the corners known there is no smooth kink
    sq = [(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0)]
    segs = [("line", sq[i], sq[(i + 1) % 4]) for i in range(4)]
    assert max_kink(segs, True, np.zeros((0, 2)), 0.1) == pytest.approx(90.0)
    corners = polyline_corners(np.array(sq), closed=True)
    assert len(corners) == 4
    assert max_kink(segs, True, corners, 0.1) == 0.0
    # a line leaving a quarter circle tangentially: no kink; at 10 deg off: 10 deg
    arc = ("arc", (10.0, 0.0), (0.0, 10.0), (0.0, 0.0), True)
    for off in (0.0, 10.0):
        d = (-math.cos(math.radians(off)), -math.sin(math.radians(off)))
        line = ("line", (0.0, 10.0), (5 * d[0], 10.0 + 5 * d[1]))
        assert max_kink([arc, line], False, np.zeros((0, 2)), 0.1) == pytest.approx(off)


def test_flat_arcs_on_a_straight_edge_count_as_one_line() -> None:
    # ArcWelder's habit on rounded straight edges: 3-point arcs of huge radius
    t = np.linspace(0.0, 1.0, 21)
    edge = np.round(np.stack([7.13157 * t, 3.31937 * t], axis=1), 4)
    segs = []
    for i in range(0, 20, 2):
        a, m, b = edge[i], edge[i + 1], edge[i + 2]
        # the circle through the three rounded points (its centre far away)
        d = 2 * (a[0] * (m[1] - b[1]) + m[0] * (b[1] - a[1]) + b[0] * (a[1] - m[1]))
        if abs(d) < 1e-12:
            segs.append(("line", tuple(a), tuple(b)))
            continue
        ux = ((a @ a) * (m[1] - b[1]) + (m @ m) * (b[1] - a[1]) + (b @ b) * (a[1] - m[1])) / d
        uy = ((a @ a) * (b[0] - m[0]) + (m @ m) * (a[0] - b[0]) + (b @ b) * (m[0] - a[0])) / d
        ccw = (m[0] - a[0]) * (b[1] - a[1]) - (m[1] - a[1]) * (b[0] - a[0]) > 0
        segs.append(("arc", tuple(a), tuple(b), (ux, uy), bool(ccw)))
    assert len(merge_g1_runs(segs, 0.01)) == len(segs)  # arcs are not G1 runs
    assert merge_straight_runs(segs, edge, closed=False, tol=0.01) == 1
    # a real bend is kept: a quarter circle as two arcs stays two
    r = 10.0
    ang = np.linspace(0.0, math.pi / 2, 41)
    quarter = np.round(np.stack([r * np.cos(ang), r * np.sin(ang)], axis=1), 4)
    two = [("arc", tuple(quarter[0]), tuple(quarter[20]), (0.0, 0.0), True),
           ("arc", tuple(quarter[20]), tuple(quarter[40]), (0.0, 0.0), True)]
    assert merge_straight_runs(two, quarter, closed=False, tol=0.01) == 2
