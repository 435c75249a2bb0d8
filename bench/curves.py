"""Benchmark curves for the arc fit (design section 5), importable by the tests.

Every curve is sampled uniformly in arc length (``step`` mm, default 0.5) and
returned as ``(points, closed)`` with ``points`` ``(N, 2)`` float64 in mm.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray
from scipy.special import fresnel

FloatArray = NDArray[np.float64]

__all__ = [
    "ARCWELDER_REFERENCE",
    "BENCH_CURVES",
    "archimedean_spiral",
    "circle",
    "clothoid",
    "coarse_ellipse",
    "coarse_spiral",
    "die_edge",
    "ellipse",
    "naca2412",
    "resample",
    "sine",
]


def resample(xy: FloatArray, step: float, closed: bool = False) -> FloatArray:
    """Resample a finely sampled curve ``(M, 2)`` uniformly in arc length at ``step``."""
    if closed:
        xy = np.vstack([xy, xy[:1]])
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])
    total = float(s[-1])
    if closed:
        n = max(round(total / step), 3)
        st = np.linspace(0.0, total, n, endpoint=False)
    else:
        n = max(round(total / step), 1)
        st = np.linspace(0.0, total, n + 1)
    return np.stack([np.interp(st, s, xy[:, 0]), np.interp(st, s, xy[:, 1])], axis=1)


def circle(step: float = 0.5, radius: float = 50.0) -> tuple[FloatArray, bool]:
    """Closed circle of ``radius`` about the origin."""
    n = max(round(2 * math.pi * radius / step), 3)
    th = np.linspace(0.0, 2 * math.pi, n, endpoint=False)
    return np.stack([radius * np.cos(th), radius * np.sin(th)], axis=1), True


def ellipse(step: float = 0.5, a: float = 100.0, b: float = 50.0) -> tuple[FloatArray, bool]:
    """Closed ellipse with semi-axes ``a`` and ``b``."""
    th = np.linspace(0.0, 2 * math.pi, 400_000, endpoint=False)
    fine = np.stack([a * np.cos(th), b * np.sin(th)], axis=1)
    return resample(fine, step, closed=True), True


def archimedean_spiral(step: float = 0.5, turns: float = 4.0) -> tuple[FloatArray, bool]:
    """Open spiral ``r = 5 + 3 theta`` over ``turns`` turns."""
    th = np.linspace(0.0, 2 * math.pi * turns, 400_000)
    r = 5.0 + 3.0 * th
    return resample(np.stack([r * np.cos(th), r * np.sin(th)], axis=1), step), False


def sine(step: float = 0.5, amplitude: float = 10.0, wavelength: float = 50.0,
         length: float = 200.0) -> tuple[FloatArray, bool]:
    """Open sine ``y = A sin(2 pi x / L)`` for ``0 <= x <= length``."""
    x = np.linspace(0.0, length, 400_001)
    return resample(np.stack([x, amplitude * np.sin(2 * math.pi * x / wavelength)], axis=1),
                    step), False


def clothoid(
    step: float = 0.5, length: float = 200.0, k_end: float = 0.1
) -> tuple[FloatArray, bool]:
    """Open clothoid from curvature 0 to ``k_end`` over ``length`` (Fresnel integrals)."""
    a = math.sqrt(length / k_end)  # kappa(s) = s / a^2
    n = max(round(length / step), 1)
    s = np.linspace(0.0, length, n + 1)
    scale = a * math.sqrt(math.pi)
    fs, fc = fresnel(s / scale)
    return np.stack([scale * fc, scale * fs], axis=1), False


def naca2412(step: float = 0.5, chord: float = 200.0) -> tuple[FloatArray, bool]:
    """NACA 2412 (open trailing edge), from the upper trailing edge round to the lower one."""
    m, p, t = 0.02, 0.4, 0.12
    beta = np.linspace(0.0, math.pi, 200_001)
    x = 0.5 * (1.0 - np.cos(beta))  # cosine spacing: fine at the leading edge
    yt = 5 * t * (0.2969 * np.sqrt(x) - 0.1260 * x - 0.3516 * x**2 + 0.2843 * x**3
                  - 0.1015 * x**4)
    yc = np.where(x < p, m / p**2 * (2 * p * x - x**2),
                  m / (1 - p) ** 2 * ((1 - 2 * p) + 2 * p * x - x**2))
    dyc = np.where(x < p, 2 * m / p**2 * (p - x), 2 * m / (1 - p) ** 2 * (p - x))
    th = np.arctan(dyc)
    xu, yu = x - yt * np.sin(th), yc + yt * np.cos(th)
    xl, yl = x + yt * np.sin(th), yc - yt * np.cos(th)
    up = np.stack([xu[::-1], yu[::-1]], axis=1)
    lo = np.stack([xl[1:], yl[1:]], axis=1)
    return resample(chord * np.vstack([up, lo]), step), False


def die_edge(step: float = 0.5) -> tuple[FloatArray, bool]:
    """A die edge: lines, tangent fillets, sharp corners and an S-bend (open).

    Sharp corners are sampled exactly at their vertex.
    """
    # (kind, a, b): ("line", length, _), ("arc", radius, signed turn deg), ("corner", deg, _)
    plan: list[tuple[str, float, float]] = [
        ("line", 60.0, 0.0), ("arc", 10.0, 90.0), ("line", 40.0, 0.0),
        ("corner", -100.0, 0.0), ("line", 30.0, 0.0), ("arc", 25.0, 60.0),
        ("arc", 25.0, -60.0), ("line", 45.0, 0.0), ("arc", 8.0, -90.0),
        ("line", 35.0, 0.0), ("corner", 120.0, 0.0), ("line", 50.0, 0.0),
        ("arc", 15.0, 45.0), ("line", 20.0, 0.0),
    ]
    pos = np.zeros(2)
    head = 0.0
    pieces: list[FloatArray] = []
    current: list[FloatArray] = [pos[None, :].copy()]
    for kind, a, b in plan:
        if kind == "corner":
            pieces.append(np.vstack(current))
            current = [pos[None, :].copy()]
            head += math.radians(a)
            continue
        if kind == "line":
            s = np.linspace(0.0, a, 2001)[1:]
            pts = pos + s[:, None] * np.array([math.cos(head), math.sin(head)])
            pos = pts[-1].copy()
        else:
            turn = math.radians(b)
            sgn = 1.0 if turn > 0 else -1.0
            c = pos + sgn * a * np.array([-math.sin(head), math.cos(head)])
            ang0 = head - sgn * math.pi / 2
            ang = ang0 + np.linspace(0.0, turn, 2001)[1:]
            pts = c + a * np.stack([np.cos(ang), np.sin(ang)], axis=1)
            pos = pts[-1].copy()
            head += turn
        current.append(pts)
    pieces.append(np.vstack(current))
    out = [resample(pc, step) for pc in pieces]
    return np.vstack([out[0]] + [o[1:] for o in out[1:]]), False


#: name -> curve factory (each takes ``step``)
BENCH_CURVES: dict[str, Callable[..., tuple[FloatArray, bool]]] = {
    "circle": circle,
    "ellipse": ellipse,
    "spiral": archimedean_spiral,
    "sine": sine,
    "clothoid": clothoid,
    "naca2412": naca2412,
    "die_edge": die_edge,
}

def coarse_spiral(n: int = 84, per_turn: int = 42) -> tuple[FloatArray, bool]:
    """A coarse polygon of an Archimedean-like spiral (r = 30 + 3 t): ``n`` points,
    ``per_turn`` a turn, open. At a tight tolerance (0.01) every edge is a straight run
    hundreds of tolerances long: a line per edge and a small fillet at each vertex."""
    t = 2.0 * np.pi * np.arange(n) / per_turn
    r = 30.0 + 3.0 * t
    return np.stack([r * np.cos(t), r * np.sin(t)], axis=1), False


def coarse_ellipse(n: int = 42, a: float = 30.0, b: float = 15.0) -> tuple[FloatArray, bool]:
    """A coarse closed polygon of ``n`` points on an ellipse ``a x b`` (see
    :func:`coarse_spiral`)."""
    t = 2.0 * np.pi * np.arange(n) / n
    return np.stack([a * np.cos(t), b * np.sin(t)], axis=1), True


#: ArcWelder at the same tolerance on these very samples: arcs, lines (None: none), its
#: G1 runs merged within the tolerance. Measured with the ArcWelder library 1.2.0
#: (``bench_arcs.py --arcwelder PATH``, bench/README.md "Building ArcWelder"), stored so
#: the tests hold the fit to it without the binary. (The issue quoted "ArcWelder 2.0":
#: circle 1, clothoid 23 arcs, NACA 9 + 1 line, others as here; its circle cannot be one
#: arc, ArcWelder closes a loop with a line.) The die edge's 90 are 61 arcs and 29 lines
#: (3-point arcs of huge radius on its straight edges); merging those too gives 12.
ARCWELDER_REFERENCE: dict[str, tuple[int | None, int | None]] = {
    "circle": (1, 1),
    "ellipse": (13, None),
    "spiral": (17, None),
    "sine": (24, None),
    "clothoid": (8, None),
    "naca2412": (9, None),
    "die_edge": (61, 29),
}
