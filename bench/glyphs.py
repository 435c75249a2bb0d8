"""Glyph outlines from the DejaVu fonts that ship with matplotlib, as arc-fit inputs.

Each glyph is scaled to ``height`` mm; each closed contour is sampled three ways:
``even`` (uniformly every 0.2 mm of arc length), ``chordal`` (each Bezier piece cut
where the chord leaves the curve by more than ``chord_tol``; every on-curve point
kept) and ``noisy`` (``even`` with every point moved by at most 0.01 mm: a uniform
direction, a length uniform in [0, 0.01], seeded).
The true corners (on-curve points where the outline turns by more than 30 degrees)
are returned with each contour so a benchmark can count the ones a chain keeps.
"""

from __future__ import annotations

import math

import numpy as np
from matplotlib.font_manager import FontProperties
from matplotlib.path import Path
from matplotlib.textpath import TextPath
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

__all__ = ["ARCWELDER_GLYPH_REFERENCE", "GLYPHS", "QUICK_GLYPHS", "Contour", "glyph_contours"]

#: glyphs of the benchmark (34 closed contours in DejaVu Sans) and the quick subset
GLYPHS = "aBgRS&8@%kQbdeAM"
QUICK_GLYPHS = "aS"

Contour = tuple[str, FloatArray, FloatArray]  # (label, points (N, 2), corners (C, 2))

#: ArcWelder 1.2.0's segments (its G1 runs merged) over all contours of :data:`GLYPHS`,
#: per ``(sampling, tolerance)``, measured with ``bench_arcs.py --glyphs --arcwelder``
#: (bench/README.md) and stored so the tests hold the fit to them without the binary.
ARCWELDER_GLYPH_REFERENCE: dict[tuple[str, float], int] = {
    ("even", 0.05): 661,
    ("chordal", 0.05): 333,
    ("noisy", 0.05): 374,
    ("even", 0.01): 890,
    ("chordal", 0.01): 563,
    ("noisy", 0.01): 2066,
}


def _bezier(ctrl: FloatArray, t: FloatArray) -> FloatArray:
    n = len(ctrl) - 1
    out = np.zeros((len(t), 2))
    for i, c in enumerate(ctrl):
        out += math.comb(n, i) * ((1 - t) ** (n - i) * t**i)[:, None] * c[None, :]
    return out


def _pieces(path: Path) -> list[list[FloatArray]]:
    """Contours as lists of Bezier control polygons (2, 3 or 4 points each)."""
    out: list[list[FloatArray]] = []
    cur: list[FloatArray] = []
    pos = start = None
    for verts, code in path.iter_segments(simplify=False, curves=True):
        v = np.asarray(verts, dtype=float).reshape(-1, 2)
        if code == Path.MOVETO:
            if cur:
                out.append(cur)
            cur, pos, start = [], v[-1], v[-1]
        elif code == Path.CLOSEPOLY:
            if pos is not None and start is not None and np.hypot(*(pos - start)) > 1e-12:
                cur.append(np.stack([pos, start]))
            out.append(cur)
            cur, pos = [], None
        else:
            assert pos is not None
            cur.append(np.vstack([pos[None, :], v]))
            pos = v[-1]
    if cur:
        out.append(cur)
    return [c for c in out if c]


def _corners(pieces: list[FloatArray]) -> FloatArray:
    """On-curve points where the outline turns by more than 30 degrees."""
    out = []
    for i, pc in enumerate(pieces):
        nxt = pieces[(i + 1) % len(pieces)]
        a = pc[-1] - pc[-2]
        b = nxt[1] - nxt[0]
        if np.hypot(*a) == 0 or np.hypot(*b) == 0:
            continue
        turn = abs(math.atan2(a[0] * b[1] - a[1] * b[0], float(a @ b)))
        if turn > math.radians(30.0):
            out.append(pc[-1])
    return np.array(out).reshape(-1, 2)


def _even(pieces: list[FloatArray], step: float) -> FloatArray:
    fine = np.vstack([_bezier(pc, np.linspace(0, 1, 400, endpoint=False)) for pc in pieces])
    closed = np.vstack([fine, fine[:1]])
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(closed, axis=0).T))])
    n = max(round(s[-1] / step), 3)
    at = np.linspace(0.0, s[-1], n, endpoint=False)
    return np.stack([np.interp(at, s, closed[:, 0]), np.interp(at, s, closed[:, 1])], 1)


def _chordal(pieces: list[FloatArray], chord_tol: float) -> FloatArray:
    out = []
    for pc in pieces:
        if len(pc) == 2:
            out.append(pc[:1])
            continue
        # uniform in t with enough steps that no chord leaves the curve by chord_tol
        for n in (2, 4, 8, 16, 32, 64, 128, 256):
            t = np.linspace(0, 1, n + 1)
            pts = _bezier(pc, t)
            mid = _bezier(pc, 0.5 * (t[1:] + t[:-1]))
            if np.hypot(*(mid - 0.5 * (pts[1:] + pts[:-1])).T).max() <= chord_tol:
                break
        out.append(pts[:-1])
    return np.vstack(out)


def glyph_contours(
    glyphs: str = GLYPHS, height: float = 50.0, chord_tol: float = 0.005, seed: int = 0
) -> dict[str, list[Contour]]:
    """``{"even": [...], "chordal": [...], "noisy": [...]}``: every closed contour of
    every glyph of ``glyphs`` (DejaVu Sans, ``height`` mm tall) sampled three ways."""
    rng = np.random.default_rng(seed)
    prop = FontProperties(family="DejaVu Sans")
    out: dict[str, list[Contour]] = {"even": [], "chordal": [], "noisy": []}
    for g in glyphs:
        tp = TextPath((0, 0), g, size=1.0, prop=prop)
        ext = tp.get_extents()
        scale = height / ext.height
        for ci, pieces in enumerate(_pieces(tp)):
            pcs = [scale * (pc - np.array([ext.x0, ext.y0])) for pc in pieces]
            label = f"{g}{ci}"
            corners = _corners(pcs)
            even = _even(pcs, 0.2)
            out["even"].append((label, even, corners))
            out["chordal"].append((label, _chordal(pcs, chord_tol), corners))
            ang = rng.uniform(0.0, 2.0 * math.pi, len(even))
            rad = rng.uniform(0.0, 0.01, len(even))
            noise = rad[:, None] * np.stack([np.cos(ang), np.sin(ang)], axis=1)
            out["noisy"].append((label, even + noise, corners))
    return out
