"""G01 runs of an NC program rewritten as arc chains (zwcore.io.gcode_program).

Every check reads the rewritten program with the independent reader in
``tests/nc_reader.py`` and measures against the known geometry the G01 moves were
sampled from.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.nc_reader import densify, read_moves, two_sided
from zwcore.errors import InvalidInputError, LimitExceededError
from zwcore.io.gcode_program import RewrittenProgram, rewrite_program

TOL = 0.01


def arc_points(c: tuple[float, float], r: float, a0: float, a1: float, n: int) -> np.ndarray:
    t = np.linspace(a0, a1, n)
    return np.c_[c[0] + r * np.cos(t), c[1] + r * np.sin(t)]


def g01(points: np.ndarray, first_feed: str = "") -> list[str]:
    """G01 blocks to every point but the first (the current position); modal after one."""
    out = []
    for i, (x, y) in enumerate(points[1:]):
        out.append(f"G01 X{x:.4f} Y{y:.4f}{first_feed}" if i == 0 else f"X{x:.4f} Y{y:.4f}")
    return out


def known_program() -> tuple[str, list[dict[str, object]]]:
    """Four runs at known geometry, each entered by a rapid and a plunge."""
    runs: list[dict[str, object]] = []
    lines = ["%", "O0001 (known answers)", "G17 G21 G90 G40", "T1 M06", "S12000 M03"]

    def run(points: np.ndarray, z: float, circles: list[tuple[tuple[float, float], float]],
            n_lines: int, feed: str = "") -> None:
        x0, y0 = points[0]
        lines.extend(["G00 Z5.", f"G00 X{x0:.4f} Y{y0:.4f}", f"G01 Z{z:.3f} F150"])
        lines.extend(g01(points, feed))
        runs.append({"points": points, "z": z, "circles": circles, "n_lines": n_lines})

    # a half circle, a line, a full circle, a line into an arc at a 90 degree corner
    run(arc_points((50, 10), 20, 0, math.pi, 120), -1.0, [((50, 10), 20)], 0, " F600")
    x = np.linspace(0, 60, 61)
    run(np.c_[x, -40 + 0.5 * x], -1.5, [], 1)
    run(arc_points((100, 0), 30, 0, 2 * math.pi, 200), -2.0, [((100, 0), 30)], 0)
    corner = np.vstack([np.c_[np.linspace(0, 30, 31), np.full(31, 100.0)],
                        arc_points((50, 100), 20, math.pi, 0, 150)[1:]])
    run(corner, -1.0, [((50, 100), 20)], 1)
    lines += ["G00 Z5.", "M05", "M30", "%"]
    return "\n".join(lines) + "\n", runs


@functools.cache
def known_rewrite() -> tuple[str, list[dict[str, object]], RewrittenProgram]:
    text, runs = known_program()
    return text, runs, rewrite_program(text, TOL)


def _arc_moves_fit_circles(moves: list, circles: list, tol: float) -> None:
    for m in moves:
        if m.code not in (2, 3):
            continue
        r0, r1 = m.radii()
        assert abs(r0 - r1) <= 1e-3  # what NC controls accept
        # the arc is one of the run's circles: centre and radius within the tolerance
        assert any(math.dist(m.center, c) <= 2 * tol and abs(r0 - r) <= 2 * tol
                   for c, r in circles), (m, circles)


def test_known_circles_and_lines_come_back() -> None:
    text, runs, out = known_rewrite()
    moves_in, moves_out = read_moves(text), read_moves(out.text)
    assert out.moves_before == len(moves_in) and out.moves_after == len(moves_out)
    assert out.moves_after < out.moves_before / 20
    assert out.bytes_before == len(text.encode()) and out.bytes_after == len(out.text.encode())
    assert out.bytes_after < out.bytes_before / 5
    assert out.unparsable_lines == () and len(out.runs) == 4 and all(r.rewritten for r in out.runs)
    # the moves of each run: from its plunge to the next rapid
    plunges = [i for i, m in enumerate(moves_out) if m.code == 1 and m.start[:2] == m.end[:2]]
    for k, (spec, start) in enumerate(zip(runs, plunges, strict=True)):
        end = plunges[k + 1] - 2 if k + 1 < len(plunges) else len(moves_out) - 1
        cut = [m for m in moves_out[start + 1:end] if m.code in (1, 2, 3)]
        assert all(m.start[2] == m.end[2] == spec["z"] for m in cut)
        circles = spec["circles"]
        _arc_moves_fit_circles(cut, circles, TOL)  # type: ignore[arg-type]
        n_arcs = sum(m.code in (2, 3) for m in cut)
        assert n_arcs <= 2 * len(circles)  # type: ignore[arg-type]
        assert sum(m.code == 1 for m in cut) == spec["n_lines"]
        path = np.vstack([m.xy_points(0.002) for m in cut])
        poly = densify(spec["points"], 0.002)  # type: ignore[arg-type]
        assert np.allclose(path[0], poly[0], atol=1e-4) and np.allclose(path[-1], poly[-1],
                                                                         atol=1e-4)
        d_in, d_out = two_sided(poly, path)
        assert d_in <= TOL + 1e-3 and d_out <= TOL + 1e-3
    assert out.max_deviation <= TOL * (1 + 1e-9)


def test_everything_else_stays_in_place() -> None:
    text, _runs, out = known_rewrite()
    in_lines = text.splitlines()
    run_lines = {n - 1 for r in out.runs for n in range(r.first_line, r.last_line + 1)}
    kept_in = [line for n, line in enumerate(in_lines) if n not in run_lines]
    written = {n for m in read_moves(out.text) if m.code in (1, 2, 3) and m.start[2] == m.end[2]
               and m.start[:2] != m.end[:2] for n in [m.line]}
    kept_out = [line for n, line in enumerate(out.text.splitlines())
                if n not in written and line != "G01"]
    assert kept_out == kept_in


UNUSUAL = """(header comment)
G90 G17
G00 X0 Y0 Z2
G01 Z-1 F100
G01 X1 Y0
X2 Y0.05 (a comment ends the run)
X3 Y0.1
X4 Y0.15
#100=5
G01 X1.2.3 Y4
G91
G01 X1 Y0
X1 Y0.1
X1 Y0.2
G90
G02 X10 Y0 I1 J0
G81 X20 Y0 Z-3 R1
X21 Y0
G80
G28 Z5
G01 X30 Y0
X31 Y0.1
X32 Y0.3
G04 X1.0
M30
"""


def test_unusual_blocks_are_kept_and_counted() -> None:
    out = rewrite_program(UNUSUAL, 0.5)
    lines = UNUSUAL.splitlines()
    assert out.unparsable_lines == (9, 10)
    # only the run between the comment and "#100=5" (3 moves, fitted by one line) changes:
    # the G91 run, the canned cycle and the moves after G28 (Z unknown) stay verbatim
    rewritten = [r for r in out.runs if r.rewritten]
    assert [(r.first_line, r.last_line) for r in rewritten] == [(7, 8)]
    new = out.text.splitlines()
    assert new[:6] == lines[:6] and new[7:] == lines[8:]
    assert new[6] == "G01 X4.0000 Y0.1500"


def test_bad_programs() -> None:
    with pytest.raises(InvalidInputError) as e:
        rewrite_program("hello world\nthis is not NC\n", 0.1)
    assert e.value.field == "body"
    with pytest.raises(InvalidInputError) as e:
        rewrite_program("G01 X1 Y1\n", 0.0)
    assert e.value.field == "tolerance"
    text, _ = known_program()
    with pytest.raises(LimitExceededError) as e:
        rewrite_program(text, 1e-6, max_resolution=1e5)
    assert e.value.field == "tolerance"


@settings(max_examples=8)
@given(seed=st.integers(0, 2**32 - 1), tol=st.sampled_from([0.005, 0.02, 0.1]))
def test_random_runs_stay_within_tolerance(seed: int, tol: float) -> None:
    rng = np.random.default_rng(seed)
    steps = rng.normal(size=(int(rng.integers(3, 60)), 2)) * rng.uniform(0.05, 3.0)
    pts = np.vstack([[0.0, 0.0], np.cumsum(steps, axis=0)])
    text = "\n".join(["G90 G17", "G00 X0 Y0 Z1", "G01 Z0 F100", *g01(pts), "M30"]) + "\n"
    out = rewrite_program(text, tol)
    moves = [m for m in read_moves(out.text) if m.code in (1, 2, 3) and m.start[:2] != m.end[:2]]
    assert out.moves_after <= out.moves_before
    for m in moves:
        if m.code in (2, 3):
            r0, r1 = m.radii()
            assert abs(r0 - r1) <= 1e-3
    path = np.vstack([m.xy_points(tol / 10) for m in moves])
    poly = densify(np.round(pts, 4), tol / 10)
    d_in, d_out = two_sided(poly, path)
    assert d_in <= tol * 1.06 + 1e-4 and d_out <= tol * 1.06 + 1e-4
