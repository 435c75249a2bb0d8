"""The NC program model: cutting data per tool, moves per stage, lengths and times.

A stage's moves are arrays (one row per block): the kind (rapid, linear feed, clockwise
or counter-clockwise arc), the end point ``(x, y, z)`` of the tool tip, the arc centre and
whether the move runs at the plunge feed. The writer (:mod:`zwcore.toolpath.writer`) turns
them into text; :mod:`zwcore.toolpath.parse` reads text back without this module.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from zwcore.errors import InvalidInputError
from zwcore.grid.feeds import (
    DEFAULT_FEED,
    DEFAULT_PLUNGE_FEED,
    DEFAULT_RAPID_FEED,
    machining_minutes,
)
from zwcore.grid.tools import Tool

__all__ = [
    "ARC_CCW",
    "ARC_CW",
    "LINE",
    "RAPID",
    "CuttingData",
    "Moves",
    "ProgramSettings",
    "StagePath",
    "cutting_data",
    "move_lengths",
]

F64 = NDArray[np.float64]

RAPID, LINE, ARC_CW, ARC_CCW = 0, 1, 2, 3

#: Field ranges ``(low, high)``: low exclusive, high inclusive except for the ramp angle.
_RANGES = {
    "spindle_rpm": (0.0, 200_000.0),
    "feed": (0.0, 100_000.0),
    "plunge_feed": (0.0, 100_000.0),
    "ramp_angle_deg": (0.0, 90.0),
}


@dataclass(frozen=True)
class CuttingData:
    """How a tool runs on the machine.

    Attributes
    ----------
    tool_number : int
        Magazine pocket and length-offset register (``T``, ``H``), 1..9999.
    spindle_rpm : float
        ``S``, rev/min, > 0.
    feed : float
        Cutting feed ``F``, mm/min, > 0.
    plunge_feed : float
        Feed of moves that go down into material (ramps, plunges), mm/min, > 0.
    ramp_angle_deg : float
        Steepest descent of a ramp or helix entry, degrees, in (0, 90).
    """

    tool_number: int = 1
    spindle_rpm: float = 12_000.0
    feed: float = DEFAULT_FEED
    plunge_feed: float = DEFAULT_PLUNGE_FEED
    ramp_angle_deg: float = 3.0


def cutting_data(field_prefix: str = "tool", **values: object) -> CuttingData:
    """Validated :class:`CuttingData`; ``None`` values take the defaults.

    Raises
    ------
    InvalidInputError
        A value out of range; the field is named ``{field_prefix}.{name}``.
    """
    given = {k: v for k, v in values.items() if v is not None}
    unknown = set(given) - set(CuttingData.__dataclass_fields__)
    if unknown:
        raise InvalidInputError(f"{field_prefix}.{sorted(unknown)[0]}", "unknown cutting field")
    n = given.get("tool_number", 1)
    if not isinstance(n, int) or isinstance(n, bool) or not 1 <= n <= 9999:
        raise InvalidInputError(f"{field_prefix}.tool_number", f"must be an integer in 1..9999, "
                                f"got {n!r}")
    out: dict[str, object] = {"tool_number": n}
    for name, (lo, hi) in _RANGES.items():
        v = given.get(name, getattr(CuttingData, name))
        if not isinstance(v, int | float) or isinstance(v, bool) or not math.isfinite(v):
            raise InvalidInputError(f"{field_prefix}.{name}", f"must be a finite number, got {v!r}")
        open_top = name == "ramp_angle_deg"
        if not (lo < v < hi or (v == hi and not open_top)):
            top = ")" if open_top else "]"
            raise InvalidInputError(f"{field_prefix}.{name}",
                                    f"must lie in ({lo:g}, {hi:g}{top}, got {v!r}")
        out[name] = float(v)
    return CuttingData(**out)  # type: ignore[arg-type]


@dataclass(frozen=True)
class ProgramSettings:
    """Program-wide settings.

    Attributes
    ----------
    clearance : float
        Safe height for rapids between regions and tool changes, mm (above the stock top).
    rapid_feed : float
        Rapid traverse rate for the time estimate, mm/min.
    decimals : int
        Digits after the decimal point (4).
    """

    clearance: float
    rapid_feed: float = DEFAULT_RAPID_FEED
    decimals: int = 4


@dataclass(frozen=True, eq=False)
class Moves:
    """Blocks of one stage, in order.

    Attributes
    ----------
    kind : (n,) int8
        ``RAPID``, ``LINE``, ``ARC_CW`` or ``ARC_CCW``.
    end : (n, 3) float64
        Tip position at the end of the block, mm.
    center : (n, 2) float64
        Arc centre (absolute), ``nan`` for rapids and lines.
    plunge : (n,) bool
        Runs at the plunge feed.
    """

    kind: NDArray[np.int8]
    end: F64
    center: F64
    plunge: NDArray[np.bool_]

    def __len__(self) -> int:
        return len(self.kind)

    @staticmethod
    def concat(parts: list[Moves]) -> Moves:
        if not parts:
            return Moves(np.zeros(0, np.int8), np.zeros((0, 3)), np.zeros((0, 2)),
                         np.zeros(0, bool))
        return Moves(np.concatenate([p.kind for p in parts]),
                     np.concatenate([p.end for p in parts]),
                     np.concatenate([p.center for p in parts]),
                     np.concatenate([p.plunge for p in parts]))

    @staticmethod
    def lines(points: F64, plunge: NDArray[np.bool_] | bool = False,
              kind: int = LINE) -> Moves:
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        n = len(pts)
        return Moves(np.full(n, kind, np.int8), pts, np.full((n, 2), np.nan),
                     np.broadcast_to(np.asarray(plunge, bool), (n,)).copy())


def move_lengths(start: F64, moves: Moves) -> F64:
    """Path length of each block (helix length for arcs), mm; ``start``: (3,) tip position."""
    prev = np.vstack([np.asarray(start, np.float64)[None, :], moves.end[:-1]])
    d = moves.end - prev
    length = np.sqrt((d * d).sum(axis=1))
    arc = moves.kind >= ARC_CW
    if arc.any():
        c = moves.center[arc]
        p0, p1 = prev[arc], moves.end[arc]
        r = np.hypot(p0[:, 0] - c[:, 0], p0[:, 1] - c[:, 1])
        a0 = np.arctan2(p0[:, 1] - c[:, 1], p0[:, 0] - c[:, 0])
        a1 = np.arctan2(p1[:, 1] - c[:, 1], p1[:, 0] - c[:, 0])
        ccw = moves.kind[arc] == ARC_CCW
        sw = np.where(ccw, np.mod(a1 - a0, 2 * np.pi), np.mod(a0 - a1, 2 * np.pi))
        sw = np.where(sw < 1e-12, 2 * np.pi, sw)
        length[arc] = np.hypot(r * sw, p1[:, 2] - p0[:, 2])
    return length


@dataclass(frozen=True, eq=False)
class StagePath:
    """One stage's tool path.

    Attributes
    ----------
    index : int
        Stage index in the plan.
    kind : {"scanline", "contour"}
    tool : Tool
    cutting : CuttingData
    start : (3,) float64
        Tip position before the first block (above the first point at the clearance).
    moves : Moves
    figures : dict
        Path figures (lengths by kind, counts, air-cut estimates), for the response.
    stock_after : (ny, nx) float64 or None
        An upper bound of the stock after this stage on the part's nodes (scan-line
        stages: from their whole lines and the bound they were given), for the next
        stage's links and entries; ``None``: not known.
    """

    index: int
    kind: Literal["scanline", "contour"]
    tool: Tool
    cutting: CuttingData
    start: F64
    moves: Moves
    figures: dict[str, float] = field(default_factory=dict)
    stock_after: F64 | None = None

    def lengths(self) -> dict[str, float]:
        """Rapid, feed and plunge path lengths, mm."""
        length = move_lengths(self.start, self.moves)
        rapid = self.moves.kind == RAPID
        plunge = ~rapid & self.moves.plunge
        return {"rapid": float(length[rapid].sum()), "plunge": float(length[plunge].sum()),
                "feed": float(length[~rapid & ~plunge].sum())}

    def time_min(self, rapid_feed: float) -> float:
        """Machining time estimate in minutes (each kind at its rate; no acceleration)."""
        ln = self.lengths()
        return machining_minutes(ln["feed"], ln["plunge"], ln["rapid"], feed=self.cutting.feed,
                                 plunge_feed=self.cutting.plunge_feed, rapid_feed=rapid_feed)
