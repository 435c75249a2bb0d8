"""Tool paths and NC programs (issue 12): every property is checked on the program text,
read back by the parser and simulated, or against brute-force oracles written here."""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.nc_modal_reader import read_program
from zwcore import ZMap, default_tools, plan_contour, plan_scanline
from zwcore.errors import InvalidInputError, LimitExceededError
from zwcore.grid.tools import Tool
from zwcore.scanline.replay import replay_passes
from zwcore.toolpath import (
    CuttingData,
    Moves,
    ProgramSettings,
    StagePath,
    contour_toolpaths,
    cutting_data,
    parse_program,
    program_text,
    scanline_toolpaths,
)
from zwcore.toolpath._sweep_kernel import node_envelope
from zwcore.toolpath.plans import CHORD_FRACTION, _refine_tolerance, tool_numbers
from zwcore.toolpath.program import ARC_CCW, ARC_CW, RAPID
from zwcore.toolpath.scanline_paths import scanline_stage_path
from zwcore.toolpath.sweep import GridFrame, sweep_moves

# ---------------------------------------------------------------- oracles (tests only)

def brute_cl(m: ZMap, tool: Tool) -> np.ndarray:
    """Node-wise drop-cutter: highest tip height over each node touching no node."""
    r, z = tool.radius, m.z
    ny, nx = z.shape
    kx, ky = math.ceil(r / m.dx), math.ceil(r / m.dy)
    out = np.full(z.shape, -np.inf)
    pad = np.pad(z, ((ky, ky), (kx, kx)), constant_values=-np.inf)
    for di in range(-ky, ky + 1):
        for dk in range(-kx, kx + 1):
            d2 = (di * m.dy) ** 2 + (dk * m.dx) ** 2
            if d2 > r * r:
                continue
            h = math.sqrt(r * r - d2) - r if tool.kind == "ball" else 0.0
            out = np.maximum(out, pad[ky + di:ky + di + ny, kx + dk:kx + dk + nx] + h)
    return out


def brute_envelope(cl: np.ndarray, m: ZMap, tool: Tool) -> np.ndarray:
    """What a tool at every node's CL height leaves (erosion of the CL by the ball)."""
    r = tool.radius
    ny, nx = cl.shape
    kx, ky = math.ceil(r / m.dx), math.ceil(r / m.dy)
    out = np.full(cl.shape, np.inf)
    pad = np.pad(cl, ((ky, ky), (kx, kx)), constant_values=np.inf)
    for di in range(-ky, ky + 1):
        for dk in range(-kx, kx + 1):
            d2 = (di * m.dy) ** 2 + (dk * m.dx) ** 2
            if d2 > r * r:
                continue
            h = r - math.sqrt(r * r - d2)
            out = np.minimum(out, pad[ky + di:ky + di + ny, kx + dk:kx + dk + nx] + h)
    return out


def sampled_envelope(frame: GridFrame, p0, p1, r: float, ball: bool, samples: int = 4001):
    """Lowest tool height over every node, the tool placed at many points along the move."""
    ny, nx = frame.shape
    yy, xx = np.mgrid[0:ny, 0:nx]
    qx, qy = frame.x0 + xx * frame.dx, frame.y0 + yy * frame.dy
    out = np.full((ny, nx), np.inf)
    for t in np.linspace(0.0, 1.0, samples):
        c = (1 - t) * np.asarray(p0) + t * np.asarray(p1)
        d2 = (qx - c[0]) ** 2 + (qy - c[1]) ** 2
        h = c[2] + (r - np.sqrt(np.maximum(r * r - d2, 0.0)) if ball else 0.0)
        # strictly inside: a node exactly R away touches the tool's side only (a tie)
        out = np.minimum(out, np.where(d2 < r * r * (1 - 1e-9), h, np.inf))
    return out


def wavy_part(n: int, dx: float, seed: int, amplitude: float = 3.0) -> ZMap:
    """A random smooth surface: three products of waves, ``n x n`` nodes ``dx`` apart."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:n, 0:n] * dx
    z = sum(rng.uniform(-amplitude, amplitude) * np.sin(x / rng.uniform(1, 6) + rng.uniform(0, 6))
            * np.cos(y / rng.uniform(1, 6)) for _ in range(3))
    return ZMap(z, rng.uniform(-5, 5), rng.uniform(-5, 5), dx, dx)


def hemisphere_pocket(n: int = 97, dx: float = 0.25, radius: float = 8.0) -> ZMap:
    y, x = np.mgrid[0:n, 0:n] * dx
    c = (n - 1) * dx / 2
    r2 = (x - c) ** 2 + (y - c) ** 2
    return ZMap(np.where(r2 < radius ** 2, -np.sqrt(np.maximum(radius ** 2 - r2, 0)), 0.0),
                0.0, 0.0, dx, dx)


# ---------------------------------------------------------------- the sweep kernel

def _swept_against_sampled(frame: GridFrame, p0: np.ndarray, p1: np.ndarray, r: float,
                           ball: bool) -> np.ndarray:
    """One move swept over a high stock, checked against the sampled envelope; returns the
    swept heights (``inf`` where the move does not reach)."""
    stock = np.full(frame.shape, 100.0)
    sweep_moves(frame, p0[None], p1[None], r, ball, stock)
    oracle = sampled_envelope(frame, p0, p1, r, ball)
    reached = np.isfinite(oracle)
    exact = np.where(stock < 100.0, stock, np.inf)
    # never above any sampled position (it is the minimum over all positions) ...
    assert np.all(exact[reached] <= oracle[reached] + 1e-9)
    # ... and not below it by more than the sampling step can explain
    step = np.linalg.norm(p1 - p0) / 4000
    slack = step + (math.sqrt(max(2 * r * step, 0.0)) if ball else abs(p1[2] - p0[2]) / 4000)
    hit = np.isfinite(exact)
    assert np.all(exact[hit & reached] >= oracle[hit & reached] - slack - 1e-9)
    return exact


@settings(max_examples=25, deadline=None)
@given(st.lists(st.floats(-3, 3), min_size=6, max_size=6), st.floats(0.3, 2.0), st.booleans())
def test_sweep_is_the_exact_lower_envelope(coords, r, ball):
    frame = GridFrame(-4.0, -4.0, 0.25, 0.25, (33, 33))
    _swept_against_sampled(frame, np.array(coords[:3]), np.array(coords[3:]), r, ball)


@settings(max_examples=25, deadline=None)
@given(st.lists(st.floats(-3, 3), min_size=5, max_size=5), st.floats(0.3, 2.0), st.booleans())
def test_sweep_along_a_row_is_the_exact_lower_envelope(coords, r, ball):
    """Moves along x (``ay = 0`` exactly: each row's root comes once from the gathering)
    against the sampled envelope and the per-node closed form."""
    frame = GridFrame(-4.0, -4.0, 0.25, 0.25, (33, 33))
    p0 = np.array(coords[:3])
    p1 = np.array([coords[3], coords[1], coords[4]])
    exact = _swept_against_sampled(frame, p0, p1, r, ball)
    ny, nx = frame.shape
    closed = np.array([[node_envelope(frame.x0 + k * frame.dx, frame.y0 + i * frame.dy,
                                      *p0, *(p1 - p0), r, ball) for k in range(nx)]
                       for i in range(ny)])
    closed = np.where(closed < 100.0, closed, np.inf)
    np.testing.assert_array_equal(np.isfinite(exact), np.isfinite(closed))
    both = np.isfinite(closed)
    np.testing.assert_allclose(exact[both], closed[both], rtol=0, atol=1e-9)


# ---------------------------------------------------------------- writer and parser

def _random_stage(rng: np.random.Generator, n: int) -> StagePath:
    kind = rng.choice([1, 2, 3], n).astype(np.int8)
    kind[0] = RAPID
    end = rng.uniform(-20, 20, (n, 3))
    center = np.full((n, 2), np.nan)
    prev = np.vstack([[0.0, 0.0, 30.0], end[:-1]])
    arc = kind >= ARC_CW
    # a centre on the perpendicular bisector of the chord, so both radii agree
    mid = 0.5 * (prev[arc, :2] + end[arc, :2])
    d = end[arc, :2] - prev[arc, :2]
    center[arc] = mid + np.column_stack([-d[:, 1], d[:, 0]]) * rng.uniform(-2, 2, (arc.sum(), 1))
    moves = Moves(kind, end, center, rng.random(n) < 0.3)
    tool = Tool("BEM-D6", "ball", 6.0, 12.0)
    return StagePath(0, "scanline", tool, CuttingData(tool_number=7, spindle_rpm=9000,
                                                      feed=900, plunge_feed=250),
                     np.array([0.0, 0.0, 30.0]), moves)


def test_a_tools_extra_passes_change_no_tool():
    """Consecutive stages with one tool number: one tool change, the spindle stopped only
    before the next tool and at the end, and the parsed program keeps the tool and its
    length offset on through the second stage."""
    rng = np.random.default_rng(5)
    a, b = _random_stage(rng, 6), _random_stage(rng, 6)
    b = dataclasses.replace(b, index=1)
    other = dataclasses.replace(_random_stage(rng, 4), index=2,
                                cutting=CuttingData(tool_number=3))
    text = program_text([a, b, other], ProgramSettings(clearance=30.0))
    assert re.findall(r"^T\d+ M6$", text, re.M) == ["T7 M6", "T3 M6"]
    assert re.findall(r"^M5$", text, re.M) == ["M5", "M5"]
    assert text.index("(stage 1") < text.index("M5") < text.index("T3 M6")
    assert text.rstrip().endswith("M5\nM30\n%")
    prog = parse_program(text)
    moving = prog.motion >= 0
    assert set(prog.tool[moving].tolist()) == {7, 3} and np.all(prog.length_offset[moving])


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 10_000), st.integers(2, 60))
def test_parser_reads_back_what_the_writer_wrote(seed, n):
    path = _random_stage(np.random.default_rng(seed), n)
    text = program_text([path], ProgramSettings(clearance=30.0))
    prog = parse_program(text)
    assert prog.ended and text.rstrip().endswith("%")
    assert re.search(r"^G17 G21 G90", text, re.M) and re.search(r"^T7 M6$", text, re.M)
    assert re.search(r"^S9000 M3$", text, re.M) and re.search(r"^G00 G43 H7 Z30\.0000$", text,
                                                               re.M)
    # every position has 4 decimals, I J incremental from the rounded start
    assert all(len(w.split(".")[1]) == 4 for w in re.findall(r"[XYZIJ]-?\d+\.\d+", text))
    assert prog.arc_radius_mismatch <= 1e-3
    moving = prog.motion >= 0
    assert np.all(prog.tool[moving] == 7) and np.all(prog.length_offset)
    # the blocks after the stage's setup are the path's moves, rounded
    body = prog.end[2:-1]
    want = np.round(path.moves.end, 4)
    keep = np.r_[True, np.any(np.abs(np.diff(np.vstack([[0, 0, 30], want]), axis=0)[1:])
                              > 5e-5, axis=1)] | (path.moves.kind >= ARC_CW)
    np.testing.assert_allclose(body, want[keep], atol=1e-9)
    feeds = prog.feed[2:-1][prog.motion[2:-1] > 0]
    expect = np.where(path.moves.plunge, 250.0, 900.0)[keep][path.moves.kind[keep] > 0]
    np.testing.assert_array_equal(feeds, expect)
    arcs = prog.motion[2:-1] >= 2
    np.testing.assert_array_equal(prog.motion[2:-1][arcs],
                                  np.where(path.moves.kind[keep][arcs] == ARC_CCW, 3, 2))


def _spell(rng: np.random.Generator, block: str) -> str:
    """The same block as a person might type it: case, blanks, comments, N numbers,
    redundant signs and zeros."""
    words = block.split()
    out = []
    for w in words:
        letter, num = w[0], w[1:]
        if rng.random() < 0.3:
            letter = letter.lower()
        if rng.random() < 0.2 and not num.startswith("-"):
            num = "+" + num
        if rng.random() < 0.2 and "." in num:
            num = num + "0"
        out.append(letter + (" " if rng.random() < 0.2 else "") + num)
    sep = "" if rng.random() < 0.3 else " "
    text = sep.join(out)
    if rng.random() < 0.2:
        text = f"N{rng.integers(1, 99999)} " + text
    if rng.random() < 0.2:
        text += " (a comment)"
    if rng.random() < 0.1:
        text += " ; the rest"
    return text


def _same_reading(a, b) -> None:
    for name in ("motion", "start", "end", "center", "feed", "tool", "length_offset",
                 "spindle_on"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert a.ended == b.ended and a.arc_radius_mismatch == b.arc_radius_mismatch


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 10_000), st.integers(2, 40))
def test_parser_reads_as_the_line_by_line_regex_reader(seed, n):
    # the compiled byte reader against tests/nc_modal_reader.py (a regex per line, Python
    # modal state): the same blocks whatever the spelling, modal words left out included
    rng = np.random.default_rng(seed)
    lines = []
    for line in program_text([_random_stage(rng, n)], ProgramSettings(clearance=30.0)).splitlines():
        if re.match(r"G0[0-3] ", line) and rng.random() < 0.3:
            line = re.sub(r"^G0[0-3] | Z-?[0-9.]+", "", line, count=int(rng.integers(1, 3)))
        lines.append(line if line in ("%", "") or line.startswith("(") else _spell(rng, line))
    text = "\n".join(lines) + "\n"
    try:
        theirs = read_program(text)
    except InvalidInputError as exc:  # a dropped G02 word can leave an arc without I J
        with pytest.raises(InvalidInputError, match=re.escape(str(exc))):
            parse_program(text)
        return
    _same_reading(parse_program(text), theirs)


@pytest.mark.parametrize("text", [
    "G17 G21 G90\nG01 X1 Y2 Z3 F100\nG01 X1..2\n", "G17 G21 G90\nG01 X Y2 Z3\n",
    "G17 G21 G90\nG01 X1 Y2 Z3 (open\n", "G17 G21 G90\n%G01 X1 Y2 Z3\n",
    "G17 G21 G90\nG01 X1 Y2 Z3 #5\n", "G01 X1 Y2 Z3\n", "G17 G21 G90\nG02 X1 Y2 Z3 I1\n",
    "G17 G21 G90\nG00 X0 Y0 Z0\nG03 X1 Y2 Z3\n", "(nothing)\n%\n"])
def test_parser_refuses_what_the_regex_reader_refuses(text):
    with pytest.raises(InvalidInputError) as ours:
        parse_program(text)
    with pytest.raises(InvalidInputError) as theirs:
        read_program(text)
    assert ours.value.field == theirs.value.field == "program"
    assert str(ours.value).split(":")[0] == str(theirs.value).split(":")[0]


@pytest.mark.parametrize("block", ["G20", "G91", "G18", "G41"])
def test_parser_refuses_modes_it_does_not_model(block):
    with pytest.raises(InvalidInputError) as exc:
        parse_program(f"G17 G21 G90\n{block}\nG01 X1 Y1 Z1 F100\n")
    assert exc.value.field == "program"


def test_parser_refuses_a_length_offset_of_another_tool():
    with pytest.raises(InvalidInputError, match="H2"):
        parse_program("G17 G21 G90\nT1 M6\nG00 G43 H2 Z5\n")


# ---------------------------------------------------------------- cutting data

@pytest.mark.parametrize(("name", "value"), [
    ("feed", 0.0), ("feed", -1.0), ("plunge_feed", 0.0), ("spindle_rpm", 0.0),
    ("ramp_angle_deg", 0.0), ("ramp_angle_deg", 90.0), ("ramp_angle_deg", 95.0),
    ("tool_number", 0), ("tool_number", 1.5), ("feed", float("nan"))])
def test_cutting_data_out_of_range_names_the_field(name, value):
    with pytest.raises(InvalidInputError) as exc:
        cutting_data("tools[2]", **{name: value})
    assert exc.value.field == f"tools[2].{name}"


def test_cutting_data_defaults():
    cd = cutting_data("tools[0]", feed=800.0)
    assert cd.feed == 800.0 and 0 < cd.ramp_angle_deg < 90 and cd.plunge_feed > 0


# ---------------------------------------------------------------- scan-line stages

def _verify_scanline(part: ZMap, tolerance: float):
    plan = plan_scanline(part, default_tools("ball"), tolerance=tolerance)
    tp = scanline_toolpaths(part, plan, brute_cl, regions=[s.region for s in plan.stages])
    chk = tp.check
    assert chk is not None
    assert chk.gouge <= 1e-9 and chk.below_part_moves == 0
    assert chk.rapid_in_material == 0.0
    # where the main finishing ball reaches the part (its closing touches it), tolerance
    # holds (the rest balls after it work only in their regions)
    ball = next(s for s in plan.stages if s.level == plan.depth).tool
    closing = brute_envelope(brute_cl(part, ball), part, ball)
    reach = closing - part.z <= 1e-9
    left = chk.machined - part.z
    return plan, tp, left, reach


def _plan_finished(part: ZMap, plan) -> tuple[np.ndarray, np.ndarray]:
    """What the plan's own simulated stock leaves on the part (its passes replayed from what
    the plan reports), and where that is within the tolerance: where the plan says it
    finishes. The program is checked against it (an independent sweep of the parsed NC)."""
    planned = replay_passes(part, plan).machined - part.z
    within = planned <= plan.scallop_tolerance
    # the plan reports exactly the area it leaves above the tolerance
    assert (~within).sum() * part.dx * part.dy == pytest.approx(plan.reach.unreachable_area)
    # and claims it finished where a finishing stage (the input's level) cut it: the
    # roughing's stock replayed alone stands higher there
    first = next(i for i, s in enumerate(plan.stages) if s.level == plan.depth)
    roughed = replay_passes(part, dataclasses.replace(plan, stages=plan.stages[:first])
                            ).machined - part.z
    finished = within & (planned < roughed)
    assert finished.mean() > 0.9 * within.mean()
    return planned, finished


# The plan's reach is its simulated stock: on this bilinear z-map the steep rim cells' chords
# hold every ball up near the rim (docs/simulation.md), and the plan's discrete positions
# leave cusps a nearly fitting ball amplifies by rho / (rho - R); it reports both. The
# program must finish wherever the plan says it does, and never leave more than the plan
# reports (beyond the tolerance) anywhere.
def test_scanline_program_on_the_r8_pocket_is_gouge_free_and_within_tolerance():
    part = hemisphere_pocket()
    plan, tp, left, reach = _verify_scanline(part, 0.01)
    assert reach.mean() > 0.8  # the nodal closing of the main ball (Ø16) reaches the pocket
    planned, finished = _plan_finished(part, plan)
    assert finished.mean() > 0.5
    assert left[finished].max() <= plan.tolerance
    assert (left - planned).max() <= plan.tolerance
    # the plan's own mask is its replayed passes' (an independent replay), and the
    # verification holds the program to the tolerance there by default
    assert np.array_equal(plan.finished, finished)
    chk = tp.check
    assert chk.finished_area_fraction == pytest.approx(finished.mean())
    assert chk.finished_over_part_max == pytest.approx(left[finished].max(), abs=1e-12)
    assert chk.within_tolerance
    assert chk.final_over_part_max == pytest.approx(left.max(), abs=1e-12)
    assert chk.final_over_part_max > plan.tolerance  # the rim chords: left, and reported
    text = tp.program
    assert text.count(" M6") == len({s.tool.id for s in plan.stages})
    # every stage's stock after it lies above its model only by what the plan leaves
    assert tp.check.stages[-1].over_model_max <= float(planned.max()) + plan.tolerance


# the plan's closed-form scallop rule left 0.0163 mm on the 81-degree wall (its slope across
# the lines only); the finishing pass now cuts again through the drop-cutter position that
# leaves the least over every node its simulated moves leave above the tolerance. 'Reach' was
# the nodal closing (every node for Ø16), which the bilinear rim chords deny: it is now where
# the plan's simulated stock is within the tolerance.
def test_scanline_program_on_the_r8_pocket_meets_the_tolerance_everywhere_it_reaches():
    part = hemisphere_pocket()
    plan, _tp, left, _reach = _verify_scanline(part, 0.005)
    _planned, finished = _plan_finished(part, plan)
    assert finished.mean() > 0.5
    assert left[finished].max() <= plan.tolerance


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 2**31 - 1))
def test_scanline_program_on_random_surfaces_never_gouges(seed):
    part = wavy_part(33, 0.5, seed)
    plan, _tp, left, reach = _verify_scanline(part, 0.02)
    assert left.min() >= -1e-9
    if reach.any():
        assert np.percentile(left[reach], 95) <= plan.tolerance


def test_scanline_bad_input():
    part = hemisphere_pocket(33, 0.5)
    plan = plan_scanline(part, default_tools("ball"), tolerance=0.05)
    with pytest.raises(InvalidInputError) as exc:
        scanline_toolpaths(part, plan, brute_cl, clearance=plan.stock_top - 1, verify=False)
    assert exc.value.field == "clearance"
    with pytest.raises(LimitExceededError) as exc:
        scanline_toolpaths(part, plan, brute_cl, verify=False, max_bytes=1000)
    assert exc.value.field == "program"


# ---------------------------------------------------------------- contour stages

def _ramp_slopes(prog) -> np.ndarray:
    d = prog.end - prog.start
    xy = np.hypot(d[:, 0], d[:, 1])
    arc = prog.motion >= 2
    s0 = prog.start[arc, :2] - prog.center[arc]
    s1 = prog.end[arc, :2] - prog.center[arc]
    r = np.hypot(s0[:, 0], s0[:, 1])
    a0 = np.arctan2(s0[:, 1], s0[:, 0])
    a1 = np.arctan2(s1[:, 1], s1[:, 0])
    sw = np.where(prog.motion[arc] == 3, np.mod(a1 - a0, 2 * np.pi), np.mod(a0 - a1, 2 * np.pi))
    xy[arc] = r * np.where(sw < 1e-12, 2 * np.pi, sw)
    down = (prog.motion > 0) & (d[:, 2] < 0)
    return -d[down, 2] / np.maximum(xy[down], 1e-12)


def test_contour_program_on_a_rectangular_pocket():
    n, dx = 97, 0.25
    y, x = np.mgrid[0:n, 0:n] * dx
    z = np.where((abs(x - 12) < 8) & (abs(y - 12) < 5), -6.0, 0.0)
    part = ZMap(z, 0.0, 0.0, dx, dx)
    tools = [t for t in default_tools("flat") if t.diameter in (10, 6, 3)]
    plan = plan_contour(part, tools)
    tp = contour_toolpaths(part, plan, tolerance=0.02,
                           cutting={t.id: CuttingData(tool_number=i + 1, ramp_angle_deg=4.0)
                                    for i, t in enumerate(tools)})
    chk = tp.check
    assert chk is not None
    assert chk.gouge <= 1e-9 and chk.below_part_moves == 0 and chk.rapid_in_material == 0.0
    prog = parse_program(tp.program)
    assert (prog.motion >= 2).any()  # arcs from the fitter, as G02/G03
    assert prog.arc_radius_mismatch <= 1e-3
    # no plunge: every descending feed move within the ramp angle
    assert _ramp_slopes(prog).max() <= math.tan(math.radians(4.0)) * (1 + 1e-3) + 1e-4
    # the pocket floor is machined where the smallest tool's stage model reaches it
    last = plan.stages[-1]
    model = np.repeat(np.repeat(last.model, last.scale, 0), last.scale, 1)[:n, :n]
    over = chk.machined - model
    assert np.mean(over > 0.05) < 0.01  # only the concave corners a round tool cannot reach


def test_contour_bad_stepover():
    part = hemisphere_pocket(33, 0.5)
    plan = plan_contour(part, default_tools("flat"))
    with pytest.raises(InvalidInputError) as exc:
        contour_toolpaths(part, plan, stepover_fraction=0.8, verify=False)
    assert exc.value.field == "stepover"


# A rest stage has no whole lines of its own: without the bound the stages before leave, each
# of its stretches was entered from the stock top (Mount Rushmore's Ø1 rest passes plunged
# 11,855 times a pass from 41 mm: 31,420 min for the program instead of 2,874).
def test_rest_stages_enter_above_the_stock_the_stages_before_really_leave():
    part = hemisphere_pocket()
    plan, tp, _left, _reach = _verify_scanline(part, 0.01)  # the parsed program: no rapid
    frame = GridFrame(part.x0, part.y0, part.dx, part.dy, part.shape)  # in material
    stock = np.full(part.shape, plan.stock_top)
    data = tool_numbers(list(dict.fromkeys(s.tool for s in plan.stages)), None)
    before, rest = None, 0
    def path(i, stage, bound):
        return scanline_stage_path(
            part, stage, i, data[stage.tool.id], brute_cl, clearance=tp.settings.clearance,
            chord_tolerance=CHORD_FRACTION * plan.tolerance, stock_top=plan.stock_top,
            refine_tolerance=_refine_tolerance(plan, stage), region=stage.region,
            stock_before=bound)

    for i, stage in enumerate(plan.stages):
        sp = path(i, stage, before)
        assert np.array_equal(sp.moves.end, tp.stages[i].moves.end)  # as the program has it
        if before is not None:
            # an upper bound of what the paths before really left (swept here, move by move;
            # the bound's rise R - sqrt(R² - d²) and the sweep's envelope round apart by
            # up to ~1e-6 mm where d is near R: entries stay ENTRY_GAP above the bound)
            assert np.all(before >= stock - 1e-6)
        if i and sp.figures["lines"] == 0 and sp.figures["segments"] > 0:
            rest += 1
            alone = path(i, stage, None)
            # the same stretches, entered lower: less plunging, less time
            assert sp.figures["segments"] == alone.figures["segments"]
            assert sp.lengths()["plunge"] < alone.lengths()["plunge"]
            rate = tp.settings.rapid_feed
            assert sp.time_min(rate) < alone.time_min(rate)
        p0 = np.vstack([sp.start[None], sp.moves.end[:-1]])
        sweep_moves(frame, p0, sp.moves.end, stage.tool.radius, True, stock,
                    apply=sp.moves.kind != RAPID)
        before = sp.stock_after
    assert rest
