"""An independent reader of the NC blocks the tests look at (G00-G03 in G17, G90).

Written for the tests, sharing nothing with ``zwcore.io.gcode_program``: it turns
a program into a list of moves with their geometry, so the tests can measure
what a control would cut.
"""

from __future__ import annotations

import itertools
import math
import re
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

_WORD = re.compile(r"([A-Z])\s*([-+]?[0-9]*\.?[0-9]*)")


@dataclass
class Move:
    line: int  # 0-based
    code: int  # 0, 1, 2, 3
    start: tuple[float, float, float]
    end: tuple[float, float, float]
    center: tuple[float, float] | None = None

    def radii(self) -> tuple[float, float]:
        assert self.center is not None
        cx, cy = self.center
        return (math.hypot(self.start[0] - cx, self.start[1] - cy),
                math.hypot(self.end[0] - cx, self.end[1] - cy))

    def xy_points(self, step: float) -> np.ndarray:
        """Points along the move's XY path, at most ``step`` apart."""
        (x0, y0, _), (x1, y1, _) = self.start, self.end
        if self.code in (0, 1):
            n = max(2, math.ceil(math.hypot(x1 - x0, y1 - y0) / step) + 1)
            f = np.linspace(0.0, 1.0, n)[:, None]
            return np.array([x0, y0]) + f * np.array([x1 - x0, y1 - y0])
        assert self.center is not None
        cx, cy = self.center
        r = math.hypot(x0 - cx, y0 - cy)
        a0 = math.atan2(y0 - cy, x0 - cx)
        a1 = math.atan2(y1 - cy, x1 - cx)
        sweep = (a1 - a0) % (2 * math.pi) if self.code == 3 else -((a0 - a1) % (2 * math.pi))
        if sweep == 0.0:
            sweep = 2 * math.pi if self.code == 3 else -2 * math.pi  # a full circle
        n = max(2, math.ceil(abs(sweep) * r / step) + 1)
        t = a0 + np.linspace(0.0, sweep, n)
        return np.c_[cx + r * np.cos(t), cy + r * np.sin(t)]


def read_moves(program: str) -> list[Move]:
    """Every motion block with its start and end (modal motion, absolute XY)."""
    pos = [0.0, 0.0, 0.0]
    mode = 0
    moves = []
    for n, raw in enumerate(program.splitlines()):
        line = re.sub(r"\(.*?\)|;.*", "", raw).upper().strip()
        words = {k: float(v) for k, v in _WORD.findall(line) if v not in ("", ".", "-", "+")}
        gs = [int(float(v)) for k, v in _WORD.findall(line) if k == "G" and v]
        for g in gs:
            if g in (0, 1, 2, 3):
                mode = g
        if not any(k in words for k in "XYZ"):
            continue
        start = tuple(pos)
        for i, k in enumerate("XYZ"):
            if k in words:
                pos[i] = words[k]
        center = None
        if mode in (2, 3):
            center = (start[0] + words.get("I", 0.0), start[1] + words.get("J", 0.0))
        moves.append(Move(n, mode, start, tuple(pos), center))  # type: ignore[arg-type]
    return moves


def two_sided(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """Max distance a -> b and b -> a of two dense point sets (each ``(N, 2)``)."""
    return float(cKDTree(b).query(a)[0].max()), float(cKDTree(a).query(b)[0].max())


def densify(poly: np.ndarray, step: float) -> np.ndarray:
    """The polyline ``(N, 2)`` with points at most ``step`` apart."""
    out = [poly[:1]]
    for p, q in itertools.pairwise(poly):
        n = max(1, math.ceil(float(np.hypot(*(q - p))) / step))
        out.append(p + (q - p) * (np.arange(1, n + 1) / n)[:, None])
    return np.vstack(out)
