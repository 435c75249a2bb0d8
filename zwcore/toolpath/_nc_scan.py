"""The byte-level reader behind :func:`zwcore.toolpath.parse.parse_program` (numba).

One pass over the program's bytes, as a control reads it: comments (``(...)`` and ``;`` to
the end of the line) and blanks are skipped, every other character must belong to a word
(a letter, optional blanks, a number ``[-+]?(digits[.digits]|.digits)``), words act in the
order they appear, and the modal state (motion mode, position, feed, selected and active
tool, length offset, spindle, units, distance mode, plane) carries over from block to block.
Numbers are read digit by digit as ``mantissa / 10**decimals`` (both exact in float64 for
up to 15 significant digits, so the division is the correctly rounded value ``float()``
gives). It shares no code with the writer.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

#: Error codes of :func:`scan_program` (``err[0]``).
OK, UNREADABLE, REFUSED, WRONG_H, NOT_METRIC, ARC_NO_START = 0, 1, 2, 3, 4, 5
#: Motion G codes (the modal group the reader models) and refused modes.
REFUSED_G = (20, 91, 18, 19, 41, 42)
#: Slots of the modal state :func:`scan_program` reads at its start and leaves at its end
#: (a program read in pieces carries it from one piece to the next; integers and flags are
#: exact in float64).
(S_X, S_Y, S_Z, S_MODE, S_FEED, S_SELECTED, S_ACTIVE, S_OFFSET, S_SPINDLE, S_METRIC,
 S_ABSOLUTE, S_XY_PLANE, S_LINE, STATE_SIZE) = range(14)


def initial_state() -> NDArray[np.float64]:
    """The modal state before a program: no position, no feed, no tool, nothing set."""
    state = np.zeros(STATE_SIZE)
    state[[S_X, S_Y, S_Z, S_FEED]] = math.nan
    return state

_SPACE, _TAB, _CR, _LF = 32, 9, 13, 10
_PLUS, _MINUS, _DOT, _PCT, _SEMI, _LPAR, _RPAR = 43, 45, 46, 37, 59, 40, 41
_ZERO, _NINE, _A, _Z, _LA, _LZ = 48, 57, 65, 90, 97, 122


@njit(cache=True, nogil=True)
def _number(buf: NDArray[np.uint8], i: int, end: int) -> tuple[float, int]:
    """The number starting at ``buf[i]`` (after blanks); ``(nan, i)`` if there is none."""
    n = end
    while i < n and (buf[i] == _SPACE or buf[i] == _TAB):
        i += 1
    neg = False
    if i < n and (buf[i] == _PLUS or buf[i] == _MINUS):
        neg = buf[i] == _MINUS
        i += 1
    mant, frac, digits, seen_dot, any_digit = 0.0, 0, 0, False, False
    while i < n:
        c = buf[i]
        if _ZERO <= c <= _NINE:
            any_digit = True
            mant = mant * 10.0 + (c - _ZERO)
            digits += 1
            if seen_dot:
                frac += 1
        elif c == _DOT and not seen_dot:
            seen_dot = True
        else:
            break
        i += 1
    if not any_digit:
        return math.nan, -1
    v = mant / 10.0 ** frac
    return (-v if neg else v), i


@njit(cache=True, nogil=True)
def scan_program(buf: NDArray[np.uint8], motion: NDArray[np.int8], end: NDArray[np.float64],
                 center: NDArray[np.float64], feed: NDArray[np.float64],
                 tool: NDArray[np.int64], flags: NDArray[np.uint8], err: NDArray[np.int64],
                 state: NDArray[np.float64]) -> int:
    """Read the program (or a piece of it: whole lines) in ``buf``; fill one row per
    motion block; return the row count.

    ``flags`` bit 0: length offset active, bit 1: spindle on. ``err``: ``[code, line
    number (1-based), byte offset of the line, value]``; ``err[4]``: set to 1 if
    ``M30``/``M2`` was seen. ``state`` (:data:`STATE_SIZE`, from :func:`initial_state`):
    the modal state before the first line, the state after the last line on return (after
    an error: unspecified).
    """
    n = len(buf)
    pos_x, pos_y, pos_z = state[S_X], state[S_Y], state[S_Z]
    mode, f_act = int(state[S_MODE]), state[S_FEED]
    selected, active = int(state[S_SELECTED]), int(state[S_ACTIVE])
    offset, spindle = state[S_OFFSET] != 0.0, state[S_SPINDLE] != 0.0
    metric, absolute = state[S_METRIC] != 0.0, state[S_ABSOLUTE] != 0.0
    xy_plane = state[S_XY_PLANE] != 0.0
    rows, lineno, i = 0, int(state[S_LINE]), 0
    has = np.zeros(26, np.bool_)
    val = np.zeros(26)
    while i < n:
        lineno += 1
        line_start = i
        has[:] = False
        motion_word = -1
        words = 0
        percent = False
        bad = False
        while i < n and buf[i] != _LF:
            c = buf[i]
            if c == _SPACE or c == _TAB or c == _CR:
                i += 1
            elif c == _LPAR:
                while i < n and buf[i] != _RPAR and buf[i] != _LF:
                    i += 1
                if i < n and buf[i] == _RPAR:
                    i += 1
                else:  # an unclosed comment
                    bad = True
            elif c == _SEMI:
                while i < n and buf[i] != _LF:
                    i += 1
            elif c == _PCT:
                percent = True
                i += 1
            elif (_A <= c <= _Z) or (_LA <= c <= _LZ):
                letter = (c - _A) if c <= _Z else (c - _LA)
                v, j = _number(buf, i + 1, n)
                if j < 0:
                    bad = True
                    i += 1
                    continue
                i = j
                words += 1
                if letter == 6:  # G
                    g = int(np.rint(v))
                    for r in REFUSED_G:
                        if g == r:
                            err[0], err[1], err[2], err[3] = REFUSED, lineno, line_start, g
                            return rows
                    if 0 <= g <= 3:
                        motion_word = g
                    metric |= g == 21
                    absolute |= g == 90
                    xy_plane |= g == 17
                    if g == 43:
                        offset = True
                    elif g == 49:
                        offset = False
                elif letter == 12:  # M
                    m = int(np.rint(v))
                    if m == 6:
                        active = selected
                        offset = False
                    elif m == 3 or m == 4:
                        spindle = True
                    elif m == 5:
                        spindle = False
                    elif m == 2 or m == 30:
                        err[4] = 1
                elif letter == 19:  # T
                    selected = int(np.rint(v))
                else:
                    has[letter] = True
                    val[letter] = v
            else:
                bad = True
                i += 1
        i += 1  # past the line feed
        if bad or (percent and words > 0):
            err[0], err[1], err[2] = UNREADABLE, lineno, line_start
            return rows
        if has[7] and int(np.rint(val[7])) != active:  # H
            err[0], err[1], err[2], err[3] = WRONG_H, lineno, line_start, int(np.rint(val[7]))
            err[5] = active
            return rows
        if has[5]:  # F
            f_act = val[5]
        if motion_word >= 0:
            mode = motion_word
        if not (has[23] or has[24] or has[25]):  # no X Y Z: no motion
            continue
        if not (metric and absolute and xy_plane):
            err[0], err[1], err[2] = NOT_METRIC, lineno, line_start
            return rows
        nx = val[23] if has[23] else pos_x
        ny = val[24] if has[24] else pos_y
        nz = val[25] if has[25] else pos_z
        cx = cy = math.nan
        if mode >= 2:
            if math.isnan(pos_x) or math.isnan(pos_y) or not (has[8] or has[9]):
                err[0], err[1], err[2] = ARC_NO_START, lineno, line_start
                return rows
            cx = pos_x + (val[8] if has[8] else 0.0)
            cy = pos_y + (val[9] if has[9] else 0.0)
        motion[rows] = mode
        end[rows, 0], end[rows, 1], end[rows, 2] = nx, ny, nz
        center[rows, 0], center[rows, 1] = cx, cy
        feed[rows] = f_act if mode else math.nan
        tool[rows] = active
        flags[rows] = (1 if offset else 0) | (2 if spindle else 0)
        rows += 1
        pos_x, pos_y, pos_z = nx, ny, nz
    state[S_X], state[S_Y], state[S_Z] = pos_x, pos_y, pos_z
    state[S_MODE], state[S_FEED] = mode, f_act
    state[S_SELECTED], state[S_ACTIVE] = selected, active
    state[S_OFFSET], state[S_SPINDLE] = 1.0 if offset else 0.0, 1.0 if spindle else 0.0
    state[S_METRIC], state[S_ABSOLUTE] = 1.0 if metric else 0.0, 1.0 if absolute else 0.0
    state[S_XY_PLANE] = 1.0 if xy_plane else 0.0
    state[S_LINE] = lineno
    return rows
