"""ArcWelder as a reference for the arc benchmark (``bench_arcs.py [--glyphs]
--arcwelder PATH``): a curve written as extruding G1 moves, compressed by an ArcWelder
console (ArcWelderConsole, or ``bench/arcwelder_driver.cpp`` built on the same library,
see bench/README.md) at the same tolerance, its output parsed back (G2/G3 with I J),
its straight G1 runs merged, and its deviation and kinks measured here, independently
of both programs.

Tolerance meaning: ArcWelder's ``--resolution-mm`` is the width of its band (it keeps
every point within ``resolution / 2`` of an arc), so ``tol`` is passed as
``2 * tol``. Its output is written with 4 decimals like the input and like zwplan's
programs (the console's default is 3).
"""

from __future__ import annotations

import itertools
import math
import re
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

FloatArray = NDArray[np.float64]

#: the console's default path tolerance (a fraction: 0.05 = 5 % arc length vs polyline)
PATH_TOLERANCE = 0.05
#: sampling step (mm) of the deviation measure: each figure is within STEP / 2 of the truth
STEP = 0.001

WORD = re.compile(r"([A-Z])\s*([-+]?\d*\.?\d+)")
Segment = tuple  # ("line", a, b) or ("arc", a, b, centre, ccw)


def _program(pts: FloatArray, closed: bool) -> str:
    """``pts`` as absolute G1 moves with relative E equal to each rounded move's length
    (the extrusion rate is constant, so ArcWelder's rate check never splits a run)."""
    path = np.round(np.vstack([pts, pts[:1]]) if closed else pts, 4)
    rows = ["G21", "G90", "M83", f"G0 X{path[0, 0]:.4f} Y{path[0, 1]:.4f}"]
    for a, b in itertools.pairwise(path):
        rows.append(f"G1 X{b[0]:.4f} Y{b[1]:.4f} E{math.dist(a, b):.6f}")
    return "\n".join(rows) + "\n"


def parse_moves(text: str) -> list[Segment]:
    """The G1/G2/G3 moves of a program as segments (G0 only moves the start)."""
    segs: list[Segment] = []
    pos: tuple[float, float] | None = None
    for line in text.splitlines():
        w = dict(WORD.findall(line.split(";")[0].upper()))
        if "G" not in w or ("X" not in w and "Y" not in w):
            continue
        g = int(float(w["G"]))
        end = (float(w.get("X", pos[0] if pos else 0.0)), float(w.get("Y", pos[1] if pos else 0.0)))
        if g in (2, 3):
            assert pos is not None, "arc before any position"
            c = (pos[0] + float(w.get("I", 0.0)), pos[1] + float(w.get("J", 0.0)))
            segs.append(("arc", pos, end, c, g == 3))
        elif g == 1 and pos is not None and end != pos:
            segs.append(("line", pos, end))
        pos = end
    return segs


def merge_g1_runs(segs: list[Segment], tol: float) -> list[Segment]:
    """Consecutive lines merged greedily into one wherever every merged vertex is within
    ``tol`` of the new line and projects onto it in order (so the line and the moves it
    replaces stay within ``tol`` of each other both ways): ArcWelder's G1 runs counted
    as the fewest lines a tolerance-``tol`` fit would use."""
    out: list[Segment] = []
    run: list[tuple[float, float]] = []

    def flush() -> None:
        i = 0
        while i < len(run) - 1:
            j = i + 1
            while j + 1 < len(run) and _fits_line(run[i : j + 2], tol):
                j += 1
            out.append(("line", run[i], run[j]))
            i = j
        run.clear()

    for s in segs:
        if s[0] == "line":
            if not run:
                run.append(s[1])
            run.append(s[2])
        else:
            flush()
            out.append(s)
    flush()
    return out


def _fits_line(pts: list[tuple[float, float]], tol: float) -> bool:
    p = np.asarray(pts, dtype=float)
    d = p[-1] - p[0]
    n = math.hypot(*d)
    if n == 0.0:
        return False
    u = d / n
    rel = p - p[0]
    along = rel @ u
    off = np.abs(rel[:, 0] * u[1] - rel[:, 1] * u[0])
    return bool(off.max() <= tol and np.all(np.diff(along) >= 0.0))


def merge_straight_runs(segs: list[Segment], pts: FloatArray, closed: bool,
                        tol: float) -> int:
    """How many segments ArcWelder's chain would have if, besides its G1 runs, every run
    of its moves (lines or nearly flat arcs) that one line can replace at ``tol`` were
    one line: a run is replaced when every input point it covers is within ``tol`` of
    the line through its ends and projects onto it in order. The most generous reading
    of "its G1 runs merged" (ArcWelder fits 3-point arcs of radius up to 9999 mm to
    straight edges whose points were rounded)."""
    path = np.array([[float(f"{x:.4f}"), float(f"{y:.4f}")] for x, y in
                     (np.vstack([pts, pts[:1]]) if closed else pts)])
    ends, k = [0], 0
    for s in segs:  # input index of every segment's end (moves follow the input)
        e = np.asarray(s[2])
        k += 1
        while k < len(path) - 1 and not np.array_equal(path[k], e):
            k += 1
        ends.append(k)
    assert ends[-1] == len(path) - 1, "ArcWelder's moves do not follow the input"
    count, i = 0, 0
    while i < len(segs):
        j = i + 1
        while j < len(segs) and _fits_line(list(map(tuple, path[ends[i] : ends[j + 1] + 1])), tol):
            j += 1
        count += 1
        i = j
    return count


def run_arcwelder(exe: str, pts: FloatArray, tol: float, closed: bool = True,
                  ) -> tuple[list[Segment], float]:
    """ArcWelder's chain for the polyline ``pts`` at tolerance ``tol`` (G1 runs merged
    within ``tol``) and the console's wall time (s)."""
    with tempfile.TemporaryDirectory() as tmp:
        src, dst = Path(tmp) / "in.gcode", Path(tmp) / "out.gcode"
        src.write_text(_program(pts, closed))
        t0 = time.perf_counter()
        subprocess.run([exe, str(src), str(dst), f"--resolution-mm={2 * tol!r}",
                        f"--path-tolerance-percent={PATH_TOLERANCE}",
                        "--default-xyz-precision=4"], check=True, capture_output=True)
        dt = time.perf_counter() - t0
        text = dst.read_text()
    # (its output may drop the first G0 of an open path: the moves start at the first point)
    start = f"G0 X{pts[0, 0]:.4f} Y{pts[0, 1]:.4f}\n"
    return merge_g1_runs(parse_moves(start + text), tol), dt


def _arc_frame(s: Segment) -> tuple[FloatArray, float, float, float, float]:
    """Centre, start angle, signed sweep, start and end radius of an arc segment."""
    a, b, c = np.asarray(s[1]), np.asarray(s[2]), np.asarray(s[3])
    a0 = math.atan2(a[1] - c[1], a[0] - c[0])
    a1 = math.atan2(b[1] - c[1], b[0] - c[0])
    sweep = (a1 - a0) % (2 * math.pi) if s[4] else -((a0 - a1) % (2 * math.pi))
    if sweep == 0.0:
        sweep = 2 * math.pi if s[4] else -2 * math.pi
    return c, a0, sweep, float(np.hypot(*(a - c))), float(np.hypot(*(b - c)))


def sample_chain(segs: list[Segment], step: float = STEP) -> FloatArray:
    """Points along the chain at most ``step`` apart, end points included (an arc whose
    rounded end radius differs from its start radius is blended linearly between them)."""
    out = []
    for s in segs:
        a, b = np.asarray(s[1]), np.asarray(s[2])
        if s[0] == "line":
            n = max(2, math.ceil(math.hypot(*(b - a)) / step) + 1)
            out.append(a + np.linspace(0.0, 1.0, n)[:, None] * (b - a))
        else:
            c, a0, sweep, r0, r1 = _arc_frame(s)
            n = max(2, math.ceil(abs(sweep) * max(r0, r1) / step) + 1)
            t = np.linspace(0.0, 1.0, n)
            r = r0 + t * (r1 - r0)
            ang = a0 + t * sweep
            out.append(c + r[:, None] * np.stack([np.cos(ang), np.sin(ang)], axis=1))
    return np.vstack(out)


def _densify(pts: FloatArray, closed: bool, step: float) -> FloatArray:
    path = np.vstack([pts, pts[:1]]) if closed else pts
    out = [path[:1]]
    for a, b in itertools.pairwise(path):
        n = max(1, math.ceil(math.hypot(*(b - a)) / step))
        out.append(a + np.linspace(0.0, 1.0, n + 1)[1:, None] * (b - a))
    return np.vstack(out)


def deviation(segs: list[Segment], pts: FloatArray, closed: bool,
              step: float = STEP) -> tuple[float, float]:
    """Largest distance polyline -> chain and chain -> polyline, both sampled every
    ``step`` mm on both curves (each figure within ``step / 2`` of the exact one)."""
    chain = sample_chain(segs, step)
    poly = _densify(pts, closed, step)
    to_chain = float(cKDTree(chain).query(poly)[0].max())
    to_poly = float(cKDTree(poly).query(chain)[0].max())
    return to_chain, to_poly


def _tangents(s: Segment) -> tuple[FloatArray, FloatArray]:
    a, b = np.asarray(s[1]), np.asarray(s[2])
    if s[0] == "line":
        d = (b - a) / max(math.hypot(*(b - a)), 1e-300)
        return d, d
    c = np.asarray(s[3])
    sg = 1.0 if s[4] else -1.0
    ta, tb = a - c, b - c
    return (sg * np.array([-ta[1], ta[0]]) / max(math.hypot(*ta), 1e-300),
            sg * np.array([-tb[1], tb[0]]) / max(math.hypot(*tb), 1e-300))


def max_kink(segs: list[Segment], closed: bool, corners: FloatArray, reach: float) -> float:
    """Largest turn (degrees) between consecutive segments at junctions farther than
    ``reach`` from every true corner of the input (``corners`` (C, 2))."""
    tans = [_tangents(s) for s in segs]
    pairs = list(range(len(segs) if closed else len(segs) - 1))
    worst = 0.0
    for i in pairs:
        j = (i + 1) % len(segs)
        at = np.asarray(segs[i][2])
        if len(corners) and np.hypot(*(corners - at).T).min() <= reach:
            continue
        t0, t1 = tans[i][1], tans[j][0]
        worst = max(worst, abs(math.degrees(math.atan2(t0[0] * t1[1] - t0[1] * t1[0],
                                                       float(t0 @ t1)))))
    return worst


def polyline_corners(pts: FloatArray, closed: bool, angle_deg: float = 30.0) -> FloatArray:
    """Vertices of ``pts`` where the polyline turns by more than ``angle_deg``."""
    path = np.vstack([pts[-1:], pts, pts[:1]]) if closed else pts
    d0 = path[1:-1] - path[:-2]
    d1 = path[2:] - path[1:-1]
    turn = np.degrees(np.abs(np.arctan2(d0[:, 0] * d1[:, 1] - d0[:, 1] * d1[:, 0],
                                        (d0 * d1).sum(axis=1))))
    return path[1:-1][turn > angle_deg].reshape(-1, 2)
