"""Rewrite the G01 runs of an NC program as C1 arc chains (issue 13, part 3a).

The seed's purpose (smaller NC data for die machining) on a CAM system's program:
every run of consecutive ``G01`` moves in the XY plane at constant Z becomes a
chain from :func:`zwcore.arcs.fit_arcs` within ``tolerance`` (two-sided, C1
except at real corners), written as ``G01``/``G02``/``G03`` blocks. Everything
else stays where it was, byte for byte: other G-codes, M-codes, comments, Z
moves, feeds, rapid moves, arcs already in the program, lines this reader does
not understand (kept verbatim, counted, and they end any run).

A run is only rewritten when the reader knows the position at its start and
the program is in a state where the geometry is plain: ``G17`` plane, ``G90``
absolute, motion mode ``G01``, and the block holds only ``G01``, ``N``, ``X``,
``Y``, ``Z`` (equal to the current Z) and ``F`` (on its first block, or equal to
the modal feed), and no comment (a commented block stays as written). Block
numbers (``N``) inside a rewritten run are dropped. Any G-code outside a short
list of state codes that do not move the coordinate frame (``G28``, ``G92``,
``G54``..., polar or scaling modes) makes the reader forget the position until
absolute words set it again, so a run after it is left alone, not guessed at. Units are the
program's own (``G20``/``G21`` are passed through): ``tolerance`` is in them.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

from zwcore.arcs.fit import Segment, fit_arcs
from zwcore.arcs.gcode import segment_blocks
from zwcore.errors import InvalidInputError, LimitExceededError

__all__ = ["GcodeRun", "RewrittenProgram", "program_runs", "rewrite_program"]

_COMMENT = re.compile(r"\([^()]*\)|;.*$")
_BLOCK = re.compile(r"(?:[A-Z][+-]?(?:\d+\.?\d*|\.\d+))*")
_WORD = re.compile(r"([A-Z])([+-]?(?:\d+\.?\d*|\.\d+))")
#: G-codes that change modal state without moving the coordinate frame.
_STATE_CODES = {4.0, 17.0, 18.0, 19.0, 20.0, 21.0, 40.0, 41.0, 42.0, 61.0, 64.0, 80.0,
                90.0, 91.0, 94.0, 95.0, 98.0, 99.0}
_CANNED = {73.0, 74.0, 76.0, 81.0, 82.0, 83.0, 84.0, 85.0, 86.0, 87.0, 88.0, 89.0}
#: Largest word value read; anything larger makes the block unparsable.
MAX_WORD = 1e9
#: Runs with coordinates beyond this (program units) are kept verbatim.
MAX_COORDINATE = 1e6
_AXES = "XYZ"
_OTHER_AXES = set("ABCUVWE")
_RUN_LETTERS = set("GNXYZF")


@dataclass(frozen=True)
class GcodeRun:
    """One run of ``G01`` moves and what replaced it.

    ``first_line``/``last_line`` are 1-based input line numbers; ``points`` is
    ``(n_moves + 1, 2)``, the position before the run and each move's end point.
    ``rewritten`` is False when the chain had no fewer blocks than the run (the
    run is then kept verbatim and ``segments`` is empty).
    """

    first_line: int
    last_line: int
    z: float
    points: np.ndarray
    moves_before: int
    moves_after: int
    rewritten: bool
    segments: tuple[Segment, ...] = ()
    corners: tuple[int, ...] = ()
    max_deviation_points: float = 0.0
    max_deviation_chain: float = 0.0


@dataclass(frozen=True)
class RewrittenProgram:
    """The rewritten program and its figures (bytes of UTF-8 text)."""

    text: str
    runs: tuple[GcodeRun, ...]
    moves_before: int
    moves_after: int
    bytes_before: int
    bytes_after: int
    unparsable_lines: tuple[int, ...]
    decimals: int
    notes: tuple[str, ...] = field(default=())

    @property
    def max_deviation(self) -> float:
        """Largest two-sided deviation of any rewritten run (program units)."""
        return max((max(r.max_deviation_points, r.max_deviation_chain) for r in self.runs
                    if r.rewritten), default=0.0)


@dataclass
class _State:
    pos: list[float | None] = field(default_factory=lambda: [None, None, None])
    motion: float | None = None
    plane: float = 17.0
    absolute: bool = True
    feed: float | None = None

    def forget(self) -> None:
        self.pos = [None, None, None]


@dataclass
class _OpenRun:
    first: int
    start: tuple[float, float]
    z: float
    feed_word: str
    ends: list[tuple[float, float]] = field(default_factory=list)
    lines: list[int] = field(default_factory=list)
    decimals: int = 0


def _parse(code: str) -> list[tuple[str, str]] | None:
    """Words of a comment-free block, or None when it is not a sequence of words."""
    compact = re.sub(r"\s+", "", code.upper())
    if not _BLOCK.fullmatch(compact):
        return None
    words = _WORD.findall(compact)
    # a number no control holds (hundreds of digits) is not G-code either
    return words if all(abs(float(v)) <= MAX_WORD for _k, v in words) else None


def _strip_comments(line: str) -> str | None:
    code = _COMMENT.sub("", line)
    return None if "(" in code or ")" in code else code


def _decimals(value: str) -> int:
    return len(value.split(".", 1)[1]) if "." in value else 0


def _is_motion(words: list[tuple[str, str]], gs: list[float], state: _State) -> float | None:
    """The motion a block performs (0..3, or -1 for a canned cycle), if any."""
    explicit = [g for g in gs if g in (0.0, 1.0, 2.0, 3.0) or g in _CANNED]
    if 4.0 in gs:
        return None  # dwell: its X/P is time
    has_axes = any(w[0] in _AXES or w[0] in _OTHER_AXES for w in words)
    mode = explicit[-1] if explicit else state.motion
    if not has_axes or mode is None:
        return None
    return -1.0 if mode in _CANNED else mode


def _run_move(words: list[tuple[str, str]], gs: list[float], state: _State,
              run: _OpenRun | None) -> tuple[float, float] | None:
    """End point of a block that may join (or start) a run, else None."""
    if state.plane != 17.0 or not state.absolute or None in state.pos:
        return None
    if any(w[0] not in _RUN_LETTERS for w in words) or any(g != 1.0 for g in gs):
        return None
    if not gs and state.motion != 1.0:
        return None
    vals = {k: float(v) for k, v in words if k in "XYZF"}
    if "X" not in vals and "Y" not in vals:
        return None
    z = state.pos[2]
    assert z is not None
    if "Z" in vals and abs(vals["Z"] - z) > 1e-9 * max(1.0, abs(z)):
        return None
    if run is not None and "F" in vals and vals["F"] != state.feed:
        return None
    x0, y0 = state.pos[0], state.pos[1]
    assert x0 is not None and y0 is not None
    end = (vals.get("X", x0), vals.get("Y", y0))
    if max(abs(x0), abs(y0), abs(end[0]), abs(end[1])) > MAX_COORDINATE:
        return None  # as the point-curve API: coordinates within +-1e6
    return end


def _apply(words: list[tuple[str, str]], gs: list[float], state: _State) -> None:
    """Update the modal state and the position after a block."""
    if any(g not in _STATE_CODES and g not in (0.0, 1.0, 2.0, 3.0) and g not in _CANNED
           for g in gs):
        state.forget()  # G28, G92, G54, G68, ...: the frame or the position moves unseen
    motion = _is_motion(words, gs, state)
    for g in gs:
        if g in (0.0, 1.0, 2.0, 3.0) or g in _CANNED:
            state.motion = g
        elif g == 80.0:
            state.motion = None
        elif g in (17.0, 18.0, 19.0):
            state.plane = g
        elif g in (90.0, 91.0):
            state.absolute = g == 90.0
    for k, v in words:
        if k == "F":
            state.feed = float(v)
    if motion is None:
        if 4.0 not in gs and any(w[0] in _AXES for w in words):
            state.forget()  # axis words without a motion mode: the control decides
        return
    for k, v in words:
        if k in _AXES:
            i = _AXES.index(k)
            if state.absolute:
                state.pos[i] = float(v)
            else:
                p = state.pos[i]
                state.pos[i] = None if p is None else p + float(v)
    if motion == -1.0:
        state.pos[2] = None  # a canned cycle ends at the R plane or the initial level


def _fit_run(run: _OpenRun, tolerance: float, corner_angle_deg: float,
             max_radius: float | None) -> tuple[GcodeRun, list[str] | None]:
    pts = np.array([run.start, *run.ends], dtype=np.float64)
    n = len(run.ends)
    base = dict(first_line=run.first + 1, last_line=run.lines[-1] + 1, z=run.z, points=pts,
                moves_before=n)
    keep = GcodeRun(**base, moves_after=n, rewritten=False)  # type: ignore[arg-type]
    if n < 2:
        return keep, None
    try:
        chain = fit_arcs(pts, tolerance, corner_angle_deg=corner_angle_deg,
                         max_radius=max_radius)
    except InvalidInputError:  # e.g. every move of the run has zero length
        return keep, None
    decimals = min(max(4, run.decimals), 8)
    blocks = segment_blocks(chain.segments, run.start, decimals, run.feed_word)
    if len(blocks) >= n:
        return keep, None
    if chain.segments and chain.segments[-1].kind == "arc":
        blocks.append("G01")  # later blocks may rely on the modal G01 of the run
    return GcodeRun(**base, moves_after=len(blocks) - (blocks[-1] == "G01"),  # type: ignore[arg-type]
                    rewritten=True, segments=chain.segments, corners=chain.corners,
                    max_deviation_points=chain.max_deviation_points,
                    max_deviation_chain=chain.max_deviation_chain), blocks


def rewrite_program(text: str, tolerance: float, *, corner_angle_deg: float = 30.0,
                    max_radius: float | None = None, max_points: int | None = None,
                    max_resolution: float | None = None) -> RewrittenProgram:
    """Replace every XY run of ``G01`` moves at constant Z by a C1 arc chain.

    Parameters
    ----------
    text : str
        The NC program (ISO 6983 / Fanuc-style words, ``( )`` and ``;`` comments).
    tolerance : float
        Two-sided band (program units) between each run's polyline and its chain.
    corner_angle_deg, max_radius
        As in :func:`zwcore.arcs.fit_arcs`.
    max_points, max_resolution : int, float or None
        Work bounds: most G01 end points in runs, and most total run length over
        ``tolerance`` (the fit samples at a fraction of the tolerance).

    Returns
    -------
    RewrittenProgram
        The program with each run replaced by its chain (a run whose chain would not
        have fewer blocks stays verbatim), the runs, and the figures.

    Raises
    ------
    InvalidInputError
        ``tolerance`` not finite and > 0, or no line of the program parses as G-code.
    LimitExceededError
        A work bound exceeded.
    """
    if not (isinstance(tolerance, int | float) and math.isfinite(tolerance) and tolerance > 0):
        raise InvalidInputError("tolerance", "must be a finite number > 0")
    newline = "\r\n" if "\r\n" in text else "\n"
    lines = text.splitlines()
    runs, moves_before, unparsable, parsed_any = _scan(lines)
    if not parsed_any:
        raise InvalidInputError("body", "no line of the program parses as G-code")
    _check_work(runs, tolerance, max_points, max_resolution)
    return _assemble(lines, runs, tolerance, corner_angle_deg, max_radius, newline, text,
                     moves_before, unparsable)


def _scan(lines: list[str]) -> tuple[list[_OpenRun], int, list[int], bool]:
    """The runs, the motion-block count, the unparsable lines and whether any line parsed."""
    state = _State()
    unparsable: list[int] = []
    moves_before = 0
    parsed_any = False
    runs: list[_OpenRun] = []
    run: _OpenRun | None = None
    for n, line in enumerate(lines):
        code = _strip_comments(line)
        if code is not None and code.strip() == "%":  # tape start/end marker
            code = ""
        words = None if code is None or code.lstrip().startswith("/") else _parse(code)
        if words is None:
            if code is None or not code.lstrip().startswith("/"):
                unparsable.append(n + 1)
            run = None
            state.forget()
            continue
        if not words:  # blank, "%" or a comment: kept in place, so it ends a run
            run = None
            continue
        parsed_any = True
        gs = [float(v) for k, v in words if k == "G"]
        if _is_motion(words, gs, state) is not None:
            moves_before += 1
        # a commented block stays as written (its comment with it), so it ends a run
        end = _run_move(words, gs, state, run) if code == line else None
        if end is None:
            run = None
        else:
            if run is None:
                x0, y0, z0 = state.pos
                assert x0 is not None and y0 is not None and z0 is not None
                feed = next((f"F{v}" for k, v in words if k == "F"), "")
                run = _OpenRun(first=n, start=(x0, y0), z=z0, feed_word=f" {feed}" if feed
                               else "")
                runs.append(run)
            run.ends.append(end)
            run.lines.append(n)
            run.decimals = max([run.decimals, *(_decimals(v) for k, v in words if k in "XY")])
        _apply(words, gs, state)
    return runs, moves_before, unparsable, parsed_any


def program_runs(text: str) -> list[np.ndarray]:
    """The polylines ``(n_moves + 1, 2)`` of a program's runs of G01 moves (no fitting):
    what :func:`rewrite_program` fits, e.g. to draw them."""
    return [np.array([r.start, *r.ends], dtype=np.float64) for r in _scan(text.splitlines())[0]]


def _check_work(runs: list[_OpenRun], tolerance: float, max_points: int | None,
                max_resolution: float | None) -> None:
    n = sum(len(r.ends) for r in runs)
    if max_points is not None and n > max_points:
        raise LimitExceededError("body", f"{n} G01 moves in runs exceed the limit of {max_points}")
    if max_resolution is not None:
        length = sum(float(np.hypot(*np.diff(np.array([r.start, *r.ends]), axis=0).T).sum())
                     for r in runs)
        if length / tolerance > max_resolution:
            raise LimitExceededError(
                "tolerance", f"G01 runs of total length {length:.6g} over tolerance "
                f"{tolerance:g} exceed {max_resolution:g}; use a larger tolerance")


def _assemble(lines: list[str], runs: list[_OpenRun], tolerance: float,
              corner_angle_deg: float, max_radius: float | None, newline: str, text: str,
              moves_before: int, unparsable: list[int]) -> RewrittenProgram:
    out: list[str] = []
    done: list[GcodeRun] = []
    cursor = 0
    decimals = 4
    for run in runs:
        report, blocks = _fit_run(run, tolerance, corner_angle_deg, max_radius)
        done.append(report)
        if blocks is None:
            continue
        decimals = max(decimals, min(max(4, run.decimals), 8))
        out.extend(lines[cursor:run.first])
        out.extend(blocks)
        cursor = run.lines[-1] + 1
    out.extend(lines[cursor:])
    result = newline.join(out) + (newline if text.endswith(("\n", "\r")) else "")
    saved = sum(r.moves_before - r.moves_after for r in done)
    notes = []
    if unparsable:
        notes.append(f"{len(unparsable)} line(s) not understood were kept verbatim and end any "
                     "run of G01 moves")
    return RewrittenProgram(
        text=result, runs=tuple(done), moves_before=moves_before,
        moves_after=moves_before - saved, bytes_before=len(text.encode()),
        bytes_after=len(result.encode()), unparsable_lines=tuple(unparsable),
        decimals=decimals, notes=tuple(notes))
