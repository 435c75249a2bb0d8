"""A second, line-by-line regex reader of NC programs (the tests' oracle for
``zwcore.toolpath.parse``, which reads bytes in one compiled pass): what a control would execute.

It knows the words the verification needs (``G00 G01 G02 G03 G17 G21 G90 G94 G43``,
``X Y Z I J F S T H M``), keeps modal state as a control does (motion mode, position, feed,
selected and active tool) and refuses anything that would change the meaning of the
coordinates it does not model (inches, incremental positions, other planes).
"""

from __future__ import annotations

import re

import numpy as np

from zwcore.errors import InvalidInputError

# the result container is shared (the reading is what this oracle checks independently)
from zwcore.toolpath.parse import ParsedProgram

__all__ = ["ParsedProgram", "read_program"]

_WORD = re.compile(r"([A-Z])\s*([-+]?(?:\d+\.?\d*|\.\d+))")
_COMMENT = re.compile(r"\([^)]*\)|;.*$")
_REFUSED = {20: "inch units", 91: "incremental positions", 18: "the XZ plane",
            19: "the YZ plane", 41: "cutter compensation", 42: "cutter compensation"}


def read_program(text: str) -> ParsedProgram:
    """Read a program.

    Raises
    ------
    InvalidInputError
        ``program``: a refused mode, a motion before a position is known, an unknown word.
    """
    pos = [np.nan, np.nan, np.nan]
    mode, feed, selected, active, offset, spindle = 0, np.nan, 0, 0, False, False
    metric = absolute = xy_plane = False
    ended = False
    rows: list[tuple[float, ...]] = []
    for lineno, raw in enumerate(text.splitlines(), 1):
        line = _COMMENT.sub("", raw.upper()).strip()
        if not line or line == "%":
            continue
        words = _WORD.findall(line)
        if "".join(a + b for a, b in words).replace(" ", "") != line.replace(" ", ""):
            raise InvalidInputError("program", f"line {lineno}: cannot read {raw!r}")
        vals: dict[str, float] = {}
        motion_word = None
        for letter, num in words:
            v = float(num)
            if letter == "G":
                g = round(v)
                if g in _REFUSED:
                    raise InvalidInputError("program", f"line {lineno}: G{g} ({_REFUSED[g]})")
                if g in (0, 1, 2, 3):
                    motion_word = g
                metric |= g == 21
                absolute |= g == 90
                xy_plane |= g == 17
                if g == 43:
                    offset = True
                if g == 49:
                    offset = False
            elif letter == "M":
                m = round(v)
                if m == 6:
                    active = selected
                    offset = False
                elif m in (3, 4):
                    spindle = True
                elif m == 5:
                    spindle = False
                elif m in (2, 30):
                    ended = True
            elif letter == "T":
                selected = round(v)
            else:
                vals[letter] = v
        if "H" in vals and round(vals["H"]) != active:
            raise InvalidInputError("program", f"line {lineno}: H{vals['H']:g} is not the "
                                    f"active tool T{active}")
        if "F" in vals:
            feed = vals["F"]
        if motion_word is not None:
            mode = motion_word
        if not any(k in vals for k in "XYZ"):
            continue
        if not (metric and absolute and xy_plane):
            raise InvalidInputError("program", f"line {lineno}: motion before G17 G21 G90")
        new = [vals.get("X", pos[0]), vals.get("Y", pos[1]), vals.get("Z", pos[2])]
        cx = cy = np.nan
        if mode >= 2:
            if np.isnan(pos[0]) or np.isnan(pos[1]) or ("I" not in vals and "J" not in vals):
                raise InvalidInputError("program", f"line {lineno}: arc without start or I J")
            cx, cy = pos[0] + vals.get("I", 0.0), pos[1] + vals.get("J", 0.0)
        rows.append((float(mode), *pos, *new, cx, cy, feed if mode else np.nan, float(active),
                     float(offset), float(spindle)))
        pos = new
    if not rows:
        raise InvalidInputError("program", "no motion blocks")
    arr = np.array([r[:10] for r in rows], dtype=np.float64)
    motion = arr[:, 0].astype(np.int8)
    start, end, center = arr[:, 1:4], arr[:, 4:7], arr[:, 7:9]
    arcs = motion >= 2
    mismatch = 0.0
    if arcs.any():
        r0 = np.hypot(start[arcs, 0] - center[arcs, 0], start[arcs, 1] - center[arcs, 1])
        r1 = np.hypot(end[arcs, 0] - center[arcs, 0], end[arcs, 1] - center[arcs, 1])
        mismatch = float(np.abs(r0 - r1).max())
    return ParsedProgram(
        motion, start, end, center, arr[:, 9], np.array([r[10] for r in rows], np.int64),
        np.array([r[11] for r in rows]) > 0, np.array([r[12] for r in rows]) > 0,
        mismatch, ended)
