"""G-code output: parse the program back and check it against the chain."""

from __future__ import annotations

import math
import re
import sys
from pathlib import Path

import numpy as np
import pytest

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
