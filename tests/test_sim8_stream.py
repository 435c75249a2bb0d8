"""The program verified stage by stage (issue 12, session 6): the reader carries its modal
state across pieces of text, the simulation carries its stretch across pieces of moves, and
a plan's paths verified on a worker thread while the next stage's paths are laid give the
text and every figure of the whole program written, read and simulated at once.

Oracles: the line-by-line regex reader (``tests/nc_modal_reader.py``) for the reading, and
the whole program read and simulated in one piece for the pieces (bit for bit)."""

from __future__ import annotations

import itertools
import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import zwcore.toolpath.plans as plans_mod
from tests.nc_modal_reader import read_program
from tests.test_toolpath import _random_stage, _same_reading, _spell, wavy_part
from zwcore import plan_scanline
from zwcore.errors import InvalidInputError, LimitExceededError
from zwcore.toolpath import ProgramSettings, parse_program, program_text, scanline_toolpaths
from zwcore.toolpath._repeats import RepeatTable, repeat_of
from zwcore.toolpath.parse import ParsedProgram, ProgramReader
from zwcore.toolpath.simulate import ProgramCheck, ProgramSimulation, simulate_program

_FIELDS = ("motion", "start", "end", "center", "feed", "tool", "length_offset", "spindle_on")


def _joined(parts: list[ParsedProgram], ended: bool) -> ParsedProgram:
    """The pieces' rows as one reading (the arc mismatch: the largest of the pieces')."""
    cat = {f: np.concatenate([getattr(p, f) for p in parts]) for f in _FIELDS}
    return ParsedProgram(**cat, arc_radius_mismatch=max(p.arc_radius_mismatch for p in parts),
                         ended=ended)


def _read_in_pieces(text: str, cuts: list[int]) -> ParsedProgram:
    reader = ProgramReader()
    bounds = [0, *sorted({min(c, len(text)) for c in cuts}), len(text)]
    parts = [reader.read(text[a:b]) for a, b in itertools.pairwise(bounds)]
    parts.append(reader.read("", final=True))
    return _joined(parts, reader.ended)


def _spelled_program(seed: int, n: int) -> str:
    """A written program respelled (case, blanks, comments, N numbers, modal words left out)."""
    rng = np.random.default_rng(seed)
    lines = []
    for line in program_text([_random_stage(rng, n), _random_stage(rng, n)],
                             ProgramSettings(clearance=30.0)).splitlines():
        if re.match(r"G0[0-3] ", line) and rng.random() < 0.3:
            line = re.sub(r"^G0[0-3] | Z-?[0-9.]+", "", line, count=int(rng.integers(1, 3)))
        lines.append(line if line in ("%", "") or line.startswith("(") else _spell(rng, line))
    return "\n".join(lines) + "\n"


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10_000), st.integers(2, 30),
       st.lists(st.integers(0, 4000), max_size=12))
def test_pieces_read_as_the_whole_text_and_as_the_regex_reader(seed, n, cuts):
    # any split (mid-word, mid-comment, at line feeds) reads as the whole text does, and as
    # the independent line-by-line reader reads the whole
    text = _spelled_program(seed, n)
    try:
        theirs = read_program(text)
    except InvalidInputError as exc:  # a dropped G02 word can leave an arc without I J
        with pytest.raises(InvalidInputError, match=re.escape(str(exc))):
            _read_in_pieces(text, cuts)
        return
    pieces = _read_in_pieces(text, cuts)
    _same_reading(pieces, theirs)
    _same_reading(pieces, parse_program(text))


@pytest.mark.parametrize("cut", [0, 12, 25, 40])
def test_an_error_in_a_later_piece_names_the_line_of_the_whole_program(cut):
    text = "G17 G21 G90\nT1 M6\nG00 G43 H1 Z5\nG00 X0 Y0\nG01 X1 Y1 Z1 F100\nG91\n"
    with pytest.raises(InvalidInputError, match="line 6: G91") as whole:
        parse_program(text)
    with pytest.raises(InvalidInputError) as pieces:
        _read_in_pieces(text, [cut])
    assert str(pieces.value) == str(whole.value)


def test_a_piece_carries_position_feed_and_tool_to_the_next():
    reader = ProgramReader()
    first = reader.read("G17 G21 G90\nT3 M6\nG00 G43 H3 Z5\nG00 X1 Y2\nG01 Z-1 F250\nG0")
    second = reader.read("1 X4\nM30\n", final=True)
    assert len(first.motion) == 3 and len(second.motion) == 1
    assert second.start[0].tolist() == [1.0, 2.0, -1.0]
    assert second.end[0].tolist() == [4.0, 2.0, -1.0]
    assert second.feed[0] == 250.0 and second.tool[0] == 3 and second.length_offset[0]
    assert reader.ended and not first.ended
    with pytest.raises(ValueError):
        reader.read("G00 X0\n")


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10_000), st.integers(1, 400), st.lists(st.integers(0, 400), max_size=6))
def test_repeat_table_in_pieces_is_repeat_of_the_whole(seed, n, cuts):
    rng = np.random.default_rng(seed)
    pool = rng.integers(0, 5, (max(1, n // 3), 7)).astype(np.float64)
    pool[rng.random(pool.shape) < 0.1] = -0.0  # -0.0 repeats 0.0
    keys = pool[rng.integers(0, len(pool), n)]
    insert = rng.random(n) < 0.7
    whole = repeat_of(keys[:, :3], keys[:, 3:6], keys[:, 6], insert)
    table = RepeatTable()
    bounds = [0, *sorted({min(c, n) for c in cuts}), n]
    got = np.concatenate([table.add(keys[a:b, :3], keys[a:b, 3:6], keys[a:b, 6], insert[a:b])
                          for a, b in itertools.pairwise(bounds)])
    np.testing.assert_array_equal(got, whole)
    # and against a brute-force lookup
    for i in range(n):
        same = [j for j in range(i) if insert[j] and np.array_equal(keys[j], keys[i])]
        assert got[i] == (same[0] if same else -1)


def _same_check(a: ProgramCheck, b: ProgramCheck) -> None:
    for name in ("gouge", "below_part_moves", "final_over_part_max", "final_over_part_p95",
                 "finished_over_part_max", "finished_area_fraction", "within_tolerance",
                 "rapid_in_material", "arc_radius_mismatch"):
        assert getattr(a, name) == getattr(b, name), name
    assert a.stages == b.stages  # every figure of every stretch, exactly
    np.testing.assert_array_equal(a.machined, b.machined)


def _small_plan(seed: int):
    part = wavy_part(49, 0.5, seed)
    plan = plan_scanline(part, tolerance=0.02)
    return part, plan


@settings(max_examples=5, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 2**31 - 1), st.lists(st.integers(0, 10**6), min_size=1, max_size=8))
def test_a_program_simulated_in_pieces_is_simulated_as_a_whole(seed, cuts):
    # pieces of text cut anywhere (inside a tool stretch too): the stock and every figure
    # are bit for bit those of the whole program at once
    part, plan = _small_plan(seed)
    tp = scanline_toolpaths(part, plan, verify=False)
    table = {p.cutting.tool_number: p.tool for p in tp.stages}
    models = [np.full(part.shape, float(k)) for k in range(len(tp.stages))]
    whole = simulate_program(parse_program(tp.program), table, part, plan.stock_top,
                             tolerance=plan.tolerance, stage_models=models)
    text = tp.program
    reader = ProgramReader()
    sim = ProgramSimulation(table, part, plan.stock_top, tolerance=plan.tolerance,
                            stage_models=models)
    bounds = [0, *sorted({c % len(text) for c in cuts}), len(text)]
    for a, b in itertools.pairwise(bounds):
        prog = reader.read(text[a:b], final=b == len(text))
        if len(prog.motion):
            sim.add(prog)
    _same_check(sim.check(), whole)


@pytest.mark.parametrize("seed", [3, 11])
def test_overlapped_verification_is_the_sequential_one_and_the_whole_programs(seed):
    part, plan = _small_plan(seed)
    seq = scanline_toolpaths(part, plan, overlap=False)
    ovl = scanline_toolpaths(part, plan, overlap=True)
    assert seq.program == ovl.program
    assert seq.check is not None and ovl.check is not None
    _same_check(seq.check, ovl.check)
    # the independent check: the emitted text read and simulated at once
    table = {p.cutting.tool_number: p.tool for p in seq.stages}
    from zwcore.scanline.results import stage_at_nodes
    last = [i for i in range(len(plan.stages)) if i + 1 == len(plan.stages)
            or seq.stages[i + 1].cutting.tool_number != seq.stages[i].cutting.tool_number]
    whole = simulate_program(parse_program(seq.program), table, part, plan.stock_top,
                             tolerance=plan.tolerance,
                             stage_models=[stage_at_nodes(plan.stages[i], part) for i in last],
                             reach=plan.finished)
    _same_check(ovl.check, whole)
    assert ovl.check.gouge <= 1e-9 and ovl.check.rapid_in_material == 0.0
    phases = dict(ovl.timings)
    assert {"paths", "program", "parse", "simulate", "verify_after_paths"} <= set(phases)
    assert dict(seq.cpu_timings).keys() == {"paths", "program", "parse", "simulate"}


@pytest.mark.parametrize("overlap", [False, True])
def test_program_size_limit_stops_the_paths_early(overlap, monkeypatch):
    part, plan = _small_plan(5)
    laid = []
    real = plans_mod.scanline_stage_path

    def counting(*args, **kwargs):
        laid.append(args[2])
        return real(*args, **kwargs)

    monkeypatch.setattr(plans_mod, "scanline_stage_path", counting)
    with pytest.raises(LimitExceededError) as exc:
        scanline_toolpaths(part, plan, max_bytes=200, overlap=overlap)
    assert exc.value.field == "program"
    if not overlap:  # the first stage's text passes the limit: no second stage is laid
        assert laid == [0]


def test_a_failure_on_the_worker_reaches_the_caller(monkeypatch):
    part, plan = _small_plan(7)

    def broken(self, prog):
        raise InvalidInputError("program", "broken on purpose")

    monkeypatch.setattr(ProgramSimulation, "add", broken)
    with pytest.raises(InvalidInputError, match="broken on purpose"):
        scanline_toolpaths(part, plan, overlap=True)


def _reference_words(path, settings):
    """The writer's former numpy preparation of a stage's blocks (the oracle of the one-pass
    kernel): codes, X Y Z I J in output units (I J only for arcs), F in tenths."""
    from zwcore.toolpath.program import ARC_CCW, ARC_CW, RAPID
    dec, cd, mv = settings.decimals, path.cutting, path.moves
    sx, sy = round(float(path.start[0]), dec), round(float(path.start[1]), dec)
    end = np.round(mv.end, dec) + 0.0
    prev = np.vstack([[sx, sy, round(settings.clearance, dec)], end[:-1]])
    ij = np.round(mv.center - prev[:, :2], dec) + 0.0
    keep = np.any(np.abs(end - prev) > 0.5 * 10.0 ** -dec, axis=1) | (mv.kind >= ARC_CW)
    codes = np.where(mv.kind == RAPID, 0, np.where(mv.kind == ARC_CCW, 3, np.where(
        mv.kind == ARC_CW, 2, 1))).astype(np.int8)[keep]
    feeds = np.where(mv.plunge, cd.plunge_feed, cd.feed)[keep]
    fed = np.flatnonzero(codes != 0)
    change = np.ones(len(fed), bool)
    change[1:] = feeds[fed[1:]] != feeds[fed[:-1]]
    feed10 = np.full(len(codes), -1, np.int64)
    feed10[fed[change]] = np.rint(np.round(feeds[fed[change]], 1) * 10.0).astype(np.int64)
    xyzij = np.rint(np.column_stack([end, np.nan_to_num(ij)])[keep] * 10.0 ** dec
                    ).astype(np.int64)
    xyzij[codes < 2, 3:] = 0
    return codes, xyzij, feed10


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 10_000), st.integers(1, 80), st.sampled_from([0.0, 0.3, 0.9]))
def test_motion_words_kernel_is_the_former_numpy_preparation(seed, n, repeat):
    from zwcore.toolpath.writer import _motion_words
    rng = np.random.default_rng(seed)
    path = _random_stage(rng, n)
    mv = path.moves
    # moves that stay put (to the output's precision or exactly), ends on half units,
    # negative zeros, feeds that change and come back
    stay = rng.random(n) < repeat
    for k in np.flatnonzero(stay)[1:] if n > 1 else []:
        mv.end[k] = mv.end[k - 1] + rng.choice([0.0, 4e-5, -4e-5, 6e-5], 3)
    mv.end[rng.random((n, 3)) < 0.05] = -0.0
    mv.end[rng.random((n, 3)) < 0.05] = rng.integers(-9999, 9999) * 1e-4 + 0.5e-4
    mv.plunge[:] = rng.random(n) < 0.5
    s = ProgramSettings(clearance=float(rng.choice([30.0, 12.34565])))
    want = _reference_words(path, s)
    codes, xyzij, feed10 = (np.empty(n, np.int8), np.empty((n, 5), np.int64),
                            np.empty(n, np.int64))
    sx, sy = round(float(path.start[0]), 4), round(float(path.start[1]), 4)
    m = _motion_words(mv.kind, mv.end, mv.center, mv.plunge, sx, sy, round(s.clearance, 4),
                      1e4, 0.5e-4, float(path.cutting.feed), float(path.cutting.plunge_feed),
                      codes, xyzij, feed10)
    got = xyzij[:m].copy()
    got[codes[:m] < 2, 3:] = 0
    np.testing.assert_array_equal(codes[:m], want[0])
    np.testing.assert_array_equal(got, want[1])
    np.testing.assert_array_equal(feed10[:m], want[2])
