"""NC program text (ISO 6983 / Fanuc dialect) from stage paths.

Conventions as :func:`zwcore.arcs.to_gcode`: ``G17 G21 G90``, 4 decimals, arcs as
``G02``/``G03`` with ``I J`` incremental from the *rounded* start point the control sees.
Per stage: tool change (``T M6``), spindle (``S M3``), length offset (``G43 H``) with a
rapid to the clearance height, the moves, a retract to the clearance; a stage with the
same tool number as the one before it (a tool's extra passes) changes nothing and goes on
from the clearance height; ``M5`` before each tool change and before ``M30`` at the end.
Every motion block repeats its G code (no modal motion across blocks), ``F`` appears when
the feed changes.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator

import numpy as np
from numba import njit
from numpy.typing import NDArray

from zwcore.toolpath.program import ARC_CCW, ARC_CW, RAPID, ProgramSettings, StagePath

__all__ = ["PROGRAM_HEAD", "PROGRAM_TAIL", "iter_program", "iter_stage", "program_text"]

#: Blocks per yielded chunk of text.
CHUNK_BLOCKS = 20_000


def _num(v: float, decimals: int) -> str:
    s = f"{v:.{decimals}f}"
    return s[1:] if s.startswith("-") and float(s) == 0.0 else s


@njit(cache=True, nogil=True)
def _put_fixed(out: NDArray[np.uint8], at: int, v: int, decimals: int) -> int:
    """Write the integer ``v`` scaled by ``10**-decimals`` as ``[-]d.ddd``; new offset."""
    if v < 0:
        out[at] = 45  # '-'
        at += 1
        v = -v
    n, w = 1, v // 10  # digits, at least decimals + 1 (a leading 0 before the point)
    while w > 0:
        n += 1
        w //= 10
    n = max(n, decimals + 1)
    width = n + (1 if decimals > 0 else 0)
    pos = at + width - 1
    for k in range(n):  # from the last digit backwards, the point after ``decimals`` of them
        if k == decimals and decimals > 0:
            out[pos] = 46  # '.'
            pos -= 1
        out[pos] = 48 + v % 10
        v //= 10
        pos -= 1
    return at + width


@njit(cache=True, nogil=True)
def _blocks_text(codes: NDArray[np.int8], xyzij: NDArray[np.int64], feed10: NDArray[np.int64],
                 decimals: int, out: NDArray[np.uint8]) -> int:
    """``G0c X Y Z [I J] [F]`` blocks, one a line; ``feed10 < 0``: no ``F``; bytes used."""
    at = 0
    letters = (88, 89, 90, 73, 74)  # X Y Z I J
    for n in range(len(codes)):
        c = codes[n]
        out[at], out[at + 1], out[at + 2] = 71, 48, 48 + c  # G0c
        at += 3
        words = 5 if c >= 2 else 3
        for w in range(words):
            out[at], out[at + 1] = 32, letters[w]
            at = _put_fixed(out, at + 2, xyzij[n, w], decimals)
        if feed10[n] >= 0:
            out[at], out[at + 1] = 32, 70  # ' F'
            at = _put_fixed(out, at + 2, feed10[n], 1)
        out[at] = 10
        at += 1
    return at


@njit(cache=True, nogil=True)
def _motion_words(kind: NDArray[np.int8], end: NDArray[np.float64],
                  center: NDArray[np.float64], plunge: NDArray[np.bool_], sx: float,
                  sy: float, sz: float, scale: float, half: float, feed: float,
                  plunge_feed: float, codes: NDArray[np.int8], xyzij: NDArray[np.int64],
                  feed10: NDArray[np.int64]) -> int:
    """The blocks a control sees, in one pass over a stage's moves: each end point rounded
    to the output precision (``rint(v * scale) / scale``, as ``np.round`` computes it), a
    move kept when it moves by more than ``half`` a unit in some axis or is an arc (a
    zero-length arc is a full circle), ``I J`` from the rounded previous point (the
    previous move's, kept or not), ``F`` where a feed block's feed differs from the
    previous feed block's. Fills ``codes`` (G code), ``xyzij`` (X Y Z I J in units of
    ``1 / scale``) and ``feed10`` (F in tenths, -1: none); returns the blocks kept."""
    px, py, pz = sx, sy, sz
    last, fed = 0.0, False
    m = 0
    for k in range(len(kind)):
        ex = np.rint(end[k, 0] * scale) / scale
        ey = np.rint(end[k, 1] * scale) / scale
        ez = np.rint(end[k, 2] * scale) / scale
        kd = kind[k]
        if (abs(ex - px) > half or abs(ey - py) > half or abs(ez - pz) > half
                or kd >= ARC_CW):
            code = 0 if kd == RAPID else (3 if kd == ARC_CCW else (2 if kd == ARC_CW else 1))
            codes[m] = code
            xyzij[m, 0] = np.int64(np.rint(ex * scale))
            xyzij[m, 1] = np.int64(np.rint(ey * scale))
            xyzij[m, 2] = np.int64(np.rint(ez * scale))
            i = np.rint((center[k, 0] - px) * scale) / scale
            j = np.rint((center[k, 1] - py) * scale) / scale
            xyzij[m, 3] = 0 if math.isnan(i) else np.int64(np.rint(i * scale))
            xyzij[m, 4] = 0 if math.isnan(j) else np.int64(np.rint(j * scale))
            feed10[m] = -1
            if code != 0:
                f = plunge_feed if plunge[k] else feed
                if not fed or f != last:
                    feed10[m] = np.int64(np.rint(np.rint(f * 10.0) / 10.0 * 10.0))
                last, fed = f, True
            m += 1
        px, py, pz = ex, ey, ez
    return m


def _body(codes: NDArray[np.int8], xyzij: NDArray[np.int64], feed10: NDArray[np.int64],
          decimals: int) -> Iterator[str]:
    """The motion blocks as text, :data:`CHUNK_BLOCKS` at a time."""
    # a word: ' ', letter, sign, the digits of the largest value, '.', at least decimals + 1
    digits = len(str(int(np.abs(xyzij).max(initial=0)))) + decimals + 4
    fdigits = len(str(int(feed10.max(initial=0)))) + 5
    width = 4 + 5 * digits + fdigits
    for a in range(0, len(codes), CHUNK_BLOCKS):
        b = min(a + CHUNK_BLOCKS, len(codes))
        out = np.empty((b - a) * width, np.uint8)
        used = _blocks_text(codes[a:b], xyzij[a:b], feed10[a:b], decimals, out)
        yield out[:used].tobytes().decode("ascii")


def _stage_blocks(path: StagePath, settings: ProgramSettings, previous: int | None
                  ) -> Iterator[str]:
    """The stage's text: setup blocks one per item, then its motion blocks in chunks (every
    item ends with a line feed). ``previous``: the stage before's tool number (None: the
    first stage)."""
    dec = settings.decimals
    cd, tool = path.cutting, path.tool
    clear = _num(settings.clearance, dec)
    yield (f"(stage {path.index}: {path.kind}, tool {tool.id}, {tool.kind} D{tool.diameter:g},"
           f" T{cd.tool_number})\n")
    if previous != cd.tool_number:
        if previous is not None:
            yield "M5\n"
        yield f"T{cd.tool_number} M6\n"
        yield f"S{cd.spindle_rpm:.0f} M3\n"
        yield f"G00 G43 H{cd.tool_number} Z{clear}\n"
    sx, sy = round(float(path.start[0]), dec), round(float(path.start[1]), dec)
    yield f"G00 X{_num(sx, dec)} Y{_num(sy, dec)}\n"
    mv = path.moves
    n = len(mv)
    codes, feed10 = np.empty(n, np.int8), np.empty(n, np.int64)
    xyzij = np.empty((n, 5), np.int64)
    kept = _motion_words(mv.kind, mv.end, mv.center, mv.plunge, sx, sy,
                         round(settings.clearance, dec), 10.0 ** dec, 0.5 * 10.0 ** -dec,
                         float(cd.feed), float(cd.plunge_feed), codes, xyzij, feed10)
    codes, xyzij, feed10 = codes[:kept], xyzij[:kept], feed10[:kept]
    yield from _body(codes, xyzij, feed10, dec)
    yield f"G00 Z{clear}\n"


#: The program's first and last blocks (around its stages' text).
PROGRAM_HEAD = "%\n(zwplan tool paths)\nG17 G21 G90 G94\n"
PROGRAM_TAIL = "M5\nM30\n%\n"


def iter_stage(path: StagePath, settings: ProgramSettings, previous: int | None = None
               ) -> Iterator[str]:
    """One stage's text as chunks (its tool change unless ``previous``, the stage before's
    tool number, is its own; to the retract), each ending with a line feed."""
    return _stage_blocks(path, settings, previous)


def iter_program(paths: Iterable[StagePath], settings: ProgramSettings) -> Iterator[str]:
    """The program as chunks of text (for streaming); their concatenation is the program:
    :data:`PROGRAM_HEAD`, each stage's :func:`iter_stage`, :data:`PROGRAM_TAIL`."""
    yield PROGRAM_HEAD
    previous: int | None = None
    for path in paths:
        yield from _stage_blocks(path, settings, previous)
        previous = path.cutting.tool_number
    yield PROGRAM_TAIL


def program_text(paths: Iterable[StagePath], settings: ProgramSettings) -> str:
    """The whole program as one string."""
    return "".join(iter_program(paths, settings))
