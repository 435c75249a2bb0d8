"""Moves that repeat earlier ones (issue 12's speed): the simulation skips sweeping a move
that repeats one that already cut; every figure and the machined stock must be what the
full sweep gives. The hash table is checked against a brute-force search."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

import zwcore.toolpath.simulate as sim_mod
from zwcore import ZMap
from zwcore.grid.tools import Tool
from zwcore.toolpath import (
    CuttingData,
    Moves,
    ProgramSettings,
    StagePath,
    parse_program,
    program_text,
    simulate_program,
)
from zwcore.toolpath._repeats import repeat_of
from zwcore.toolpath.program import ARC_CCW, ARC_CW, LINE, RAPID


@settings(max_examples=50, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_repeats_are_the_brute_force_first_earlier_equal_move(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 80))
    pool = np.round(rng.uniform(-3, 3, (6, 3)), 1)  # few points: many repeats
    p0 = pool[rng.integers(0, 6, n)]
    p1 = pool[rng.integers(0, 6, n)]
    r = rng.choice([0.5, 0.5, 0.75], n)
    insert = rng.random(n) < 0.6
    src = repeat_of(p0, p1, r, insert)
    for i in range(n):
        want = -1
        for j in range(i):
            same = np.array_equal(p0[j], p0[i]) and np.array_equal(p1[j], p1[i])
            if insert[j] and same and r[j] == r[i]:
                want = j
                break
        assert src[i] == want


def _program(rng: np.random.Generator, tools: list[tuple[Tool, int]]) -> str:
    """Stages of lines, rapids and arcs over a small part, with many moves repeated (same
    and reversed direction, as feeds and as rapids)."""
    stages = []
    for k, (tool, number) in enumerate(tools):
        n = int(rng.integers(20, 60))
        pts = np.column_stack([np.round(rng.uniform(0, 10, (n, 2)), 1),
                               np.round(rng.uniform(-0.5, 2.0, n), 2)])
        idx = np.concatenate([np.arange(n), rng.integers(0, n, n), np.arange(n),
                              np.arange(n)[::-1]])
        end = pts[idx]
        kind = rng.choice([RAPID, LINE, LINE, LINE, ARC_CW, ARC_CCW], len(idx)).astype(np.int8)
        prev = np.vstack([[0.0, 0.0, 8.0], end[:-1]])
        arc = (kind >= ARC_CW) & (np.hypot(*(end[:, :2] - prev[:, :2]).T) > 0.2)
        kind[(kind >= ARC_CW) & ~arc] = LINE
        mid = 0.5 * (prev[arc, :2] + end[arc, :2])
        d = end[arc, :2] - prev[arc, :2]
        center = np.full((len(idx), 2), np.nan)
        center[arc] = mid + np.column_stack([-d[:, 1], d[:, 0]]) * 0.7
        moves = Moves(kind, end, center, np.zeros(len(idx), bool))
        stages.append(StagePath(k, "scanline", tool, CuttingData(tool_number=number),
                                np.array([0.0, 0.0, 8.0]), moves))
    return program_text(stages, ProgramSettings(clearance=8.0))


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_skipping_repeats_changes_no_figure(seed):
    rng = np.random.default_rng(seed)
    n = 41
    y, x = np.mgrid[0:n, 0:n] * 0.25
    part = ZMap(np.sin(x) * np.cos(y * 0.7) * 0.6, 0.0, 0.0, 0.25, 0.25)
    ball = Tool("BEM-D2", "ball", 2.0, 10.0)
    flat = Tool("FEM-D3", "flat", 3.0, 10.0)
    text = _program(rng, [(ball, 1), (flat, 2), (ball, 1)])
    prog = parse_program(text)
    out = []
    for skip in (False, True):
        old = sim_mod.SKIP_REPEATS
        sim_mod.SKIP_REPEATS = skip
        try:
            out.append(simulate_program(prog, {1: ball, 2: flat}, part, 3.0, tolerance=0.05,
                                        stage_models=[part.z, part.z, part.z]))
        finally:
            sim_mod.SKIP_REPEATS = old
    a, b = out
    np.testing.assert_array_equal(a.machined, b.machined)
    assert a.stages == b.stages
    for f in ("gouge", "below_part_moves", "final_over_part_max", "final_over_part_p95",
              "rapid_in_material", "within_tolerance"):
        assert getattr(a, f) == getattr(b, f)
    # the programs do cut, gouge and rapid through material, so the figures are not trivial
    assert a.gouge > 0 and a.rapid_in_material > 0
    # and many moves are repeats (same direction) of moves that cut
    known = np.isfinite(prog.start).all(1)
    src = repeat_of(prog.start[known], prog.end[known], np.zeros(known.sum()),
                    prog.motion[known] > 0)
    assert (src >= 0).sum() >= 15
