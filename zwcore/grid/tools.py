"""Cutting tools: ball and flat end mills, and the default tool library.

Flute lengths follow catalogue practice for solid-carbide end mills (about
two diameters for ball end mills, the DIN 6527 short series for flat end
mills), so the default library plans like a real tool crib.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Literal

from zwcore.errors import InvalidInputError

__all__ = ["DEFAULT_LIBRARY", "TOOL_KINDS", "Tool", "ToolKind", "default_tools", "tool_library"]

ToolKind = Literal["ball", "flat"]
TOOL_KINDS: tuple[ToolKind, ...] = ("ball", "flat")


@dataclass(frozen=True)
class Tool:
    """An end mill.

    Attributes
    ----------
    id : str
        Crib identifier, unique within a library.
    kind : {"ball", "flat"}
    diameter : float
        Cutting diameter in mm.
    flute_length : float
        Length of cut in mm: the deepest a single pass may engage.
    """

    id: str
    kind: ToolKind
    diameter: float
    flute_length: float

    @property
    def radius(self) -> float:
        return self.diameter / 2.0


_BALL = [(1, 2), (2, 4), (3, 6), (4, 8), (5, 10), (6, 12), (8, 16), (10, 20), (12, 24),
         (16, 32), (20, 40)]
_FLAT = [(3, 8), (4, 11), (5, 13), (6, 13), (8, 19), (10, 22), (12, 26), (16, 32), (20, 38)]

DEFAULT_LIBRARY: tuple[Tool, ...] = tuple(
    [Tool(f"BEM-D{d}", "ball", float(d), float(lc)) for d, lc in _BALL]
    + [Tool(f"FEM-D{d}", "flat", float(d), float(lc)) for d, lc in _FLAT]
)


def default_tools(kind: ToolKind) -> tuple[Tool, ...]:
    """The shipped library's tools of one kind, largest first."""
    return tool_library([t for t in DEFAULT_LIBRARY if t.kind == kind], kind)


def tool_library(tools: Iterable[Tool], kind: ToolKind, field: str = "tools") -> tuple[Tool, ...]:
    """Validate a tool library for one kind of operation and sort it largest first.

    Raises
    ------
    InvalidInputError
        Empty library, a tool of the wrong kind, a non-positive or non-finite size,
        or a repeated id; ``field`` names the tool (``tools[3].diameter``).
    """
    items = list(tools)
    if not items:
        raise InvalidInputError(field, f"the {kind} end mill library is empty")
    seen: set[str] = set()
    for n, tool in enumerate(items):
        where = f"{field}[{n}]"
        if tool.kind != kind:
            raise InvalidInputError(f"{where}.kind", f"must be {kind!r} here, got {tool.kind!r}")
        if not tool.id:
            raise InvalidInputError(f"{where}.id", "must not be empty")
        if tool.id in seen:
            raise InvalidInputError(f"{where}.id", f"duplicate tool id {tool.id!r}")
        seen.add(tool.id)
        for name in ("diameter", "flute_length"):
            v = getattr(tool, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise InvalidInputError(f"{where}.{name}", f"must be finite and > 0, got {v!r}")
    return tuple(sorted(items, key=lambda t: (-t.diameter, -t.flute_length, t.id)))
