"""NC program text (ISO 6983 / Fanuc dialect) from stage paths.

Conventions as :func:`zwcore.arcs.to_gcode`: ``G17 G21 G90``, 4 decimals, arcs as
``G02``/``G03`` with ``I J`` incremental from the *rounded* start point the control sees.
Per stage: tool change (``T M6``), spindle (``S M3``), length offset (``G43 H``) with a
rapid to the clearance height, the moves, a retract to the clearance, ``M5``; ``M30`` at
the end. Every motion block repeats its G code (no modal motion across blocks), ``F``
appears when the feed changes.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator

import numpy as np

from zwcore.toolpath.program import ARC_CCW, ARC_CW, RAPID, ProgramSettings, StagePath

__all__ = ["iter_program", "program_text"]

#: Blocks per yielded chunk of text.
CHUNK_BLOCKS = 20_000


def _num(v: float, decimals: int) -> str:
    s = f"{v:.{decimals}f}"
    return s[1:] if s.startswith("-") and float(s) == 0.0 else s


def _stage_blocks(path: StagePath, settings: ProgramSettings) -> Iterator[str]:
    dec = settings.decimals
    cd, tool = path.cutting, path.tool
    clear = _num(settings.clearance, dec)
    yield (f"(stage {path.index}: {path.kind}, tool {tool.id}, {tool.kind} D{tool.diameter:g},"
           f" T{cd.tool_number})")
    yield f"T{cd.tool_number} M6"
    yield f"S{cd.spindle_rpm:.0f} M3"
    yield f"G00 G43 H{cd.tool_number} Z{clear}"
    sx, sy = round(float(path.start[0]), dec), round(float(path.start[1]), dec)
    yield f"G00 X{_num(sx, dec)} Y{_num(sy, dec)}"
    mv = path.moves
    end = np.round(mv.end, dec) + 0.0  # + 0.0 turns -0.0 into 0.0
    prev = np.vstack([[sx, sy, round(settings.clearance, dec)], end[:-1]])
    ij = np.round(mv.center - prev[:, :2], dec) + 0.0
    moved = np.any(np.abs(end - prev) > 0.5 * 10.0 ** -dec, axis=1)
    keep = moved | (mv.kind >= ARC_CW)
    feeds = np.where(mv.plunge, cd.plunge_feed, cd.feed)
    fmt = f"%.{dec}f"
    line_fmt = f"G0%d X{fmt} Y{fmt} Z{fmt}"
    arc_fmt = f"G0%d X{fmt} Y{fmt} Z{fmt} I{fmt} J{fmt}"
    last_f = None
    codes = np.where(mv.kind == RAPID, 0, np.where(mv.kind == ARC_CCW, 3, np.where(
        mv.kind == ARC_CW, 2, 1)))
    rows = end.tolist()
    ijs = ij.tolist()
    for n in np.flatnonzero(keep).tolist():
        code = int(codes[n])
        x, y, z = rows[n]
        if code >= 2:
            text = arc_fmt % (code, x, y, z, ijs[n][0], ijs[n][1])
        else:
            text = line_fmt % (code, x, y, z)
        if code != 0 and feeds[n] != last_f:
            last_f = feeds[n]
            text += f" F{last_f:.1f}"
        yield text
    yield f"G00 Z{clear}"
    yield "M5"


def iter_program(paths: Iterable[StagePath], settings: ProgramSettings) -> Iterator[str]:
    """The program as chunks of text (for streaming); their concatenation is the program."""
    head = ["%", "(zwplan tool paths)", "G17 G21 G90 G94"]
    buf: list[str] = head
    for path in paths:
        for block in _stage_blocks(path, settings):
            buf.append(block)
            if len(buf) >= CHUNK_BLOCKS:
                yield "\n".join(buf) + "\n"
                buf = []
    buf += ["M30", "%"]
    yield "\n".join(buf) + "\n"


def program_text(paths: Iterable[StagePath], settings: ProgramSettings) -> str:
    """The whole program as one string."""
    return "".join(iter_program(paths, settings))
