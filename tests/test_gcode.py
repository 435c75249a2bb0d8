"""G-code output: parse the program back and check it against the chain."""

from __future__ import annotations

import itertools
import math
import re
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

from zwcore.arcs.fit import fit_arcs
from zwcore.arcs.gcode import to_gcode
from zwcore.errors import InvalidInputError

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
from curves import BENCH_CURVES

WORD = re.compile(r"([A-Z])(-?\d+(?:\.\d+)?)")


def parse(program: str) -> list[dict[str, float]]:
    blocks = []
    for line in program.splitlines():
        line = line.split("(")[0].strip()
        if not line:
            continue
        words: dict[str, float] = {}
        for letter, val in WORD.findall(line):
            if letter == "G":
                words.setdefault("G", float(val))
                words[f"G{int(float(val)):02d}"] = 1.0
            else:
                words[letter] = float(val)
        blocks.append(words)
    return blocks


@pytest.mark.parametrize("name", list(BENCH_CURVES))
@pytest.mark.parametrize("decimals", [4, 6])
def test_program_parses_back_consistently(name, decimals):
    pts, closed = BENCH_CURVES[name]()
    chain = fit_arcs(pts, 0.1, closed=closed)
    prog = to_gcode(chain, feed=1200.0, decimals=decimals)
    assert "G17 G21 G90" in prog
    blocks = parse(prog)
    assert any("F" in b for b in blocks)
    pos = None
    moves = 0
    for b in blocks:
        if "G00" in b:
            pos = (b["X"], b["Y"])
            assert math.dist(pos, chain.segments[0].start) < 10.0 ** (-decimals)
            continue
        if not ("G01" in b or "G02" in b or "G03" in b):
            continue
        assert pos is not None
        # every coordinate word carries at least 4 decimals
        end = (b["X"], b["Y"])
        if "G02" in b or "G03" in b:
            c = (pos[0] + b["I"], pos[1] + b["J"])
            r0 = math.dist(pos, c)
            r1 = math.dist(end, c)
            assert abs(r0 - r1) <= 0.001, (r0, r1)
        pos = end
        moves += 1
    assert moves == len(chain.segments)
    final = chain.segments[-1].end
    assert math.dist(pos, final) < 10.0 ** (-decimals)
    for line in prog.splitlines():
        for letter, val in WORD.findall(line):
            if letter in "XYIJ":
                assert len(val.split(".")[1]) >= 4


def test_arc_direction_codes():
    th = np.linspace(0, np.pi, 200)
    ccw = np.stack([10 * np.cos(th), 10 * np.sin(th)], 1)
    prog = to_gcode(fit_arcs(ccw, 0.01), feed=500)
    assert "G03" in prog and "G02" not in prog
    prog = to_gcode(fit_arcs(ccw[::-1], 0.01), feed=500)
    assert "G02" in prog and "G03" not in prog


def test_line_is_g01():
    prog = to_gcode(fit_arcs([[0, 0], [10, 0], [20, 0]], 0.1), feed=500)
    assert "G01 X20.0000 Y0.0000" in prog


@pytest.mark.parametrize("feed", [0.0, -1.0, float("nan"), float("inf")])
def test_bad_feed_is_rejected(feed):
    chain = fit_arcs([[0, 0], [1, 0]], 0.1)
    with pytest.raises(InvalidInputError) as err:
        to_gcode(chain, feed=feed)
    assert err.value.field == "feed"


# ----------------------------------------------------------------------------
# the program as rounded stays within the tolerance of the input, both ways


def control_path(program: str, step: float) -> np.ndarray:
    """Points ``(K, 2)`` along the path an NC control runs for ``program`` (parsed here:
    G00/G01 straight, G02/G03 about centre = start + I J, the radius going linearly
    from the start's to the end's, end = start a full circle), at most ``step`` apart."""
    pos = None
    out: list[np.ndarray] = []
    for b in parse(program):
        if "G00" in b:
            pos = np.array([b["X"], b["Y"]])
            out.append(pos[None, :])
            continue
        if not ("G01" in b or "G02" in b or "G03" in b):
            continue
        assert pos is not None
        end = np.array([b["X"], b["Y"]])
        if "G01" in b:
            n = max(math.ceil(math.dist(pos, end) / step), 1)
            f = np.linspace(0.0, 1.0, n + 1)[1:, None]
            out.append(pos + f * (end - pos))
        else:
            c = pos + np.array([b["I"], b["J"]])
            r0, r1 = math.dist(pos, c), math.dist(end, c)
            a0 = math.atan2(pos[1] - c[1], pos[0] - c[0])
            a1 = math.atan2(end[1] - c[1], end[0] - c[0])
            if "G03" in b:
                sw = (a1 - a0) % (2 * math.pi) or 2 * math.pi
            else:
                sw = -((a0 - a1) % (2 * math.pi) or 2 * math.pi)
            n = max(math.ceil(abs(sw) * max(r0, r1) / step), 1)
            f = np.linspace(0.0, 1.0, n + 1)[1:]
            rad = r0 + f * (r1 - r0)
            ang = a0 + f * sw
            out.append(c + rad[:, None] * np.stack([np.cos(ang), np.sin(ang)], axis=1))
        pos = end
    return np.vstack(out)


def _dist_to_polyline(pts: np.ndarray, poly: np.ndarray, h: float = 0.05) -> np.ndarray:
    """Exact distance of each point ``(K, 2)`` to the polyline ``poly``: the polyline cut
    into pieces at most ``h`` long; the nearest piece's midpoint lies within the distance
    to the nearest midpoint plus ``h / 2`` (a k-d tree finds those candidates)."""
    n = np.maximum(np.ceil(np.hypot(*np.diff(poly, axis=0).T) / h).astype(int), 1)
    f = np.concatenate([np.arange(k) / k for k in n])
    a = np.repeat(poly[:-1], n, axis=0) + f[:, None] * np.repeat(np.diff(poly, axis=0), n, 0)
    b = np.vstack([a[1:], poly[-1:]])
    tree = cKDTree(0.5 * (a + b))
    d_mid, _ = tree.query(pts)
    cand = tree.query_ball_point(pts, d_mid + 0.5 * h + 1e-12)
    counts = np.array([len(c) for c in cand])
    qi = np.repeat(np.arange(len(pts)), counts)
    si = np.concatenate(cand).astype(int)
    ab = b[si] - a[si]
    ap = pts[qi] - a[si]
    t = np.clip((ap * ab).sum(1) / np.maximum((ab * ab).sum(1), 1e-300), 0.0, 1.0)
    d = np.hypot(*(ap - t[:, None] * ab).T)
    out = np.full(len(pts), np.inf)
    np.minimum.at(out, qi, d)
    return out


def _program_cases():
    # noisy input at a tolerance equal to the noise: the chain uses the whole band
    rng = np.random.default_rng(3)
    th = np.linspace(0.0, 2 * math.pi, 350, endpoint=False)
    blob = np.stack([(10 + 2 * np.sin(3 * th)) * np.cos(th),
                     (10 + 2 * np.sin(3 * th)) * np.sin(th)], 1)
    yield "noisy_blob", blob + rng.uniform(-0.01, 0.01, blob.shape), True, 0.01
    sine, _ = BENCH_CURVES["sine"](0.2, length=40.0)
    yield "noisy_sine", sine + rng.uniform(-0.01, 0.01, sine.shape), False, 0.01
    yield "ellipse_coarse", np.stack([30 * np.cos(th[::10]), 15 * np.sin(th[::10])], 1), \
        True, 0.01


@pytest.mark.parametrize("case", list(_program_cases()), ids=lambda c: c[0])
def test_rounded_program_within_tolerance_both_ways(case):
    from zwcore.arcs.gcode import rounding_budget

    _, pts, closed, tol = case
    chain = fit_arcs(pts, tol, closed=closed, reserve=rounding_budget(4))
    path = control_path(to_gcode(chain, feed=800.0, decimals=4), 0.002)
    poly = np.vstack([pts, pts[:1]]) if closed else pts
    # (the path sampled 0.002 mm apart: its chords are within 1e-7 mm of it)
    assert _dist_to_polyline(path, poly).max() <= tol
    dense = np.vstack([np.linspace(a, b, max(math.ceil(math.dist(a, b) / 0.002), 1) + 1)
                       for a, b in itertools.pairwise(poly)])
    assert _dist_to_polyline(dense, path).max() <= tol - 1e-7


def test_reserve_must_leave_a_tolerance():
    with pytest.raises(InvalidInputError) as err:
        fit_arcs([[0, 0], [1, 0]], 0.0003, reserve=0.0004)
    assert err.value.field == "tolerance"
