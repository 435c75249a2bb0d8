"""A reader of NC programs, independent of the writer: what a control would execute.

It knows the words the verification needs (``G00 G01 G02 G03 G17 G21 G90 G94 G43``,
``X Y Z I J F S T H M``), keeps modal state as a control does (motion mode, position, feed,
selected and active tool) and refuses anything that would change the meaning of the
coordinates it does not model (inches, incremental positions, other planes).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from zwcore.errors import InvalidInputError
from zwcore.toolpath._nc_scan import (
    ARC_NO_START,
    NOT_METRIC,
    REFUSED,
    S_LINE,
    S_X,
    S_Y,
    S_Z,
    UNREADABLE,
    WRONG_H,
    initial_state,
    scan_program,
)

__all__ = ["ParsedProgram", "ProgramReader", "parse_program"]

_REFUSED = {20: "inch units", 91: "incremental positions", 18: "the XZ plane",
            19: "the YZ plane", 41: "cutter compensation", 42: "cutter compensation"}


@dataclass(frozen=True, eq=False)
class ParsedProgram:
    """The motion blocks of a program, in execution order.

    Attributes
    ----------
    motion : (n,) int8
        0 rapid, 1 line, 2 clockwise arc, 3 counter-clockwise arc.
    start, end : (n, 3) float64
        Tip positions before and after the block.
    center : (n, 2) float64
        Arc centre (start plus ``I J``); ``nan`` for other blocks.
    feed : (n,) float64
        Active ``F`` (``nan`` for rapids).
    tool : (n,) int64
        Active tool number (after the last ``M6``; 0 before any).
    length_offset : (n,) bool
        ``G43`` active with the active tool's ``H``.
    spindle_on : (n,) bool
    arc_radius_mismatch : float
        Largest ``|r_start - r_end|`` over the arcs, mm (controls reject > 0.001).
    ended : bool
        ``M30`` (or ``M2``) seen.
    """

    motion: NDArray[np.int8]
    start: NDArray[np.float64]
    end: NDArray[np.float64]
    center: NDArray[np.float64]
    feed: NDArray[np.float64]
    tool: NDArray[np.int64]
    length_offset: NDArray[np.bool_]
    spindle_on: NDArray[np.bool_]
    arc_radius_mismatch: float
    ended: bool


def _line(text: bytes, at: int) -> str:
    stop = text.find(b"\n", at)
    return text[at:stop if stop >= 0 else len(text)].decode(errors="replace")


class ProgramReader:
    """Reads a program in pieces, as a control streams it: the modal state (position,
    motion mode, feed, tools, offsets, modes, line count) carries from one piece to the next,
    so the pieces read as their concatenation does (a line split between two pieces is read
    when its end arrives).

    Examples
    --------
    >>> reader = ProgramReader()
    >>> first = reader.read("G17 G21 G90\nG00 X0 Y0 Z5\nG01 X1")
    >>> rest = reader.read(" Y0 Z5 F100\nM30\n", final=True)
    >>> len(first.motion), len(rest.motion), rest.start[0].tolist(), reader.ended
    (1, 1, [0.0, 0.0, 5.0], True)
    """

    def __init__(self) -> None:
        self._state = initial_state()
        self._tail = b""
        self._ended = False
        self._done = False
        #: Motion blocks read so far.
        self.rows = 0

    @property
    def ended(self) -> bool:
        """``M30`` (or ``M2``) seen so far."""
        return self._ended

    def read(self, text: str, final: bool = False) -> ParsedProgram:
        """The motion blocks of the whole lines read so far that came with ``text``.

        Parameters
        ----------
        text : str
            The program's next piece (any split: a line's start is kept until its end).
        final : bool
            The program ends with this piece (a last line without a line feed is read).

        Returns
        -------
        ParsedProgram
            Rows ``self.rows`` (before the call) on; ``start[0]`` the position before them
            (``nan`` before any). ``ended`` says whether ``M30`` was seen so far.

        Raises
        ------
        InvalidInputError
            As :func:`parse_program` (line numbers count from the program's start).
        """
        if self._done:
            raise ValueError("the program was read to its end")
        try:
            raw = text.encode("ascii")
        except UnicodeEncodeError as exc:
            lineno = (int(self._state[S_LINE]) + self._tail.count(b"\n")
                      + text.count("\n", 0, exc.start) + 1)
            raise InvalidInputError("program", f"line {lineno}: a character that is not "
                                    "ASCII") from None
        if self._tail:
            raw = self._tail + raw
        cut = len(raw) if final else raw.rfind(b"\n") + 1
        raw, self._tail = raw[:cut], raw[cut:]
        self._done = final
        return self._scan(raw)

    def _scan(self, raw: bytes) -> ParsedProgram:
        buf = np.frombuffer(raw, dtype=np.uint8)
        cap = raw.count(b"\n") + 1
        motion = np.empty(cap, np.int8)
        end = np.empty((cap, 3))
        center = np.empty((cap, 2))
        feed = np.empty(cap)
        tool = np.empty(cap, np.int64)
        flags = np.empty(cap, np.uint8)
        err = np.zeros(6, np.int64)
        before = self._state[[S_X, S_Y, S_Z]].copy()
        rows = scan_program(buf, motion, end, center, feed, tool, flags, err, self._state)
        _raise(err, raw)
        self._ended |= bool(err[4])
        self.rows += rows
        # views of the first rows (no copies: a program's arrays run to hundreds of MB)
        end = end[:rows]
        start = np.empty((rows, 3))
        if rows:
            start[0] = before
            start[1:] = end[:-1]
        center = center[:rows]
        mot = motion[:rows]
        arcs = mot >= 2
        mismatch = 0.0
        if arcs.any():
            r0 = np.hypot(start[arcs, 0] - center[arcs, 0], start[arcs, 1] - center[arcs, 1])
            r1 = np.hypot(end[arcs, 0] - center[arcs, 0], end[arcs, 1] - center[arcs, 1])
            mismatch = float(np.abs(r0 - r1).max())
        fl = flags[:rows]
        return ParsedProgram(mot, start, end, center, feed[:rows], tool[:rows],
                             (fl & 1) > 0, (fl & 2) > 0, mismatch, self._ended)


def _raise(err: NDArray[np.int64], raw: bytes) -> None:
    """The scanner's error (``err``, :func:`~zwcore.toolpath._nc_scan.scan_program`), if any,
    as :class:`~zwcore.errors.InvalidInputError`."""
    code, lineno, at, value = (int(v) for v in err[:4])
    if code == UNREADABLE:
        raise InvalidInputError("program", f"line {lineno}: cannot read {_line(raw, at)!r}")
    if code == REFUSED:
        raise InvalidInputError("program", f"line {lineno}: G{value} ({_REFUSED[value]})")
    if code == WRONG_H:
        raise InvalidInputError("program", f"line {lineno}: H{value} is not the active tool "
                                f"T{int(err[5])}")
    if code == NOT_METRIC:
        raise InvalidInputError("program", f"line {lineno}: motion before G17 G21 G90")
    if code == ARC_NO_START:
        raise InvalidInputError("program", f"line {lineno}: arc without start or I J")


def parse_program(text: str) -> ParsedProgram:
    """Read a program (one compiled pass over its bytes: :mod:`zwcore.toolpath._nc_scan`).

    Raises
    ------
    InvalidInputError
        ``program``: a refused mode, a motion before a position is known, an unknown word.
    """
    reader = ProgramReader()
    prog = reader.read(text, final=True)
    if reader.rows == 0:
        raise InvalidInputError("program", "no motion blocks")
    return prog
