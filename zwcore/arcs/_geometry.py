"""Geometry kernels of the arc fit: circles through a point with a fixed tangent.

Every piece of a chain is described by its start point ``P``, unit tangent ``T``
and signed curvature ``kappa`` (``> 0`` turns left / counter-clockwise, ``0`` is a
straight line), so lines and arcs share one set of formulas. Points are handled
in the piece's local frame ``u = (x - P) . T``, ``v = (x - P) . N`` with
``N = T`` rotated by +90 degrees. All formulas are written so that they stay
accurate for ``kappa -> 0`` (no ``1 / kappa`` appears without a matching factor).

Units: mm and radians.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

__all__ = [
    "arc_point",
    "arc_points",
    "line_fit",
    "local_uv",
    "points_to_segments_distance",
    "rotate",
    "rotate1",
    "sagitta",
    "sagitta1",
]


def rotate(t: FloatArray, angle: float | FloatArray) -> FloatArray:
    """Rotate unit vector(s) ``t`` (``(2,)`` or ``(..., 2)``) by ``angle`` radians."""
    c = np.cos(angle)
    s = np.sin(angle)
    x = t[..., 0]
    y = t[..., 1]
    return np.stack([c * x - s * y, s * x + c * y], axis=-1)


def rotate1(t: FloatArray, angle: float) -> FloatArray:
    """:func:`rotate` of one unit vector ``(2,)`` by a scalar angle, in scalar arithmetic
    (the same figures without numpy's overhead on two elements)."""
    c = math.cos(angle)
    s = math.sin(angle)
    x = float(t[0])
    y = float(t[1])
    return np.array([c * x - s * y, s * x + c * y])


def local_uv(p: FloatArray, t: FloatArray, pts: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Coordinates of ``pts`` ``(M, 2)`` in the frame of start ``p`` ``(2,)`` and tangent ``t``."""
    if pts.shape == (1, 2) and p.shape == (2,) and t.shape == (2,):
        # one point (a piece to one sample): the same arithmetic on floats, without the
        # overhead of eight array operations on one element
        ex = float(pts[0, 0]) - float(p[0])
        ey = float(pts[0, 1]) - float(p[1])
        tx, ty = float(t[0]), float(t[1])
        return np.array([ex * tx + ey * ty]), np.array([ey * tx - ex * ty])
    dx = pts[..., 0] - p[..., 0]
    dy = pts[..., 1] - p[..., 1]
    u = dx * t[..., 0] + dy * t[..., 1]
    v = dy * t[..., 0] - dx * t[..., 1]
    return u, v




def arc_points(
    p: FloatArray, t: FloatArray, kappa: float | FloatArray, sigma: FloatArray
) -> FloatArray:
    """Points ``(M, 2)`` at arc lengths ``sigma`` ``(M,)`` along the piece (stable for kappa=0).

    ``kappa`` may also be an ``(M,)`` array: point ``i`` lies on the piece of curvature
    ``kappa[i]`` from ``(p, t)``.
    """
    sigma = np.asarray(sigma, dtype=np.float64)
    a = kappa * sigma
    # sin(a)/kappa = sigma*sinc(a/pi); (1-cos a)/kappa = sigma*(a/2)*sinc(a/(2 pi))^2
    x = sigma * np.sinc(a / np.pi)
    y = sigma * (0.5 * a) * np.sinc(a / (2.0 * np.pi)) ** 2
    n = np.array([-t[1], t[0]])
    return p[None, :] + x[:, None] * t[None, :] + y[:, None] * n[None, :]


def arc_point(p: FloatArray, t: FloatArray, kappa: float, sigma: float) -> FloatArray:
    """:func:`arc_points` at one arc length, in scalar arithmetic (the same figures)."""
    a = kappa * sigma
    x = sigma * _sinc(a / math.pi)
    y = sigma * (0.5 * a) * _sinc(a / (2.0 * math.pi)) ** 2
    tx = float(t[0])
    ty = float(t[1])
    return np.array([float(p[0]) + x * tx + y * -ty, float(p[1]) + x * ty + y * tx])


def _sinc(x: float) -> float:
    """``numpy.sinc`` of one number."""
    y = math.pi * (x if x != 0.0 else 1.0e-20)
    return math.sin(y) / y



def sagitta(kappa: float | FloatArray, length: FloatArray) -> FloatArray:
    """Largest distance between an arc of ``length`` and its chord (0 for lines)."""
    b = 0.25 * kappa * np.asarray(length, dtype=np.float64)
    # 2 sin^2(b)/|kappa| written without dividing by kappa
    return np.abs(length) * np.abs(b) * 0.5 * np.sinc(b / np.pi) ** 2


def sagitta1(kappa: float, length: float) -> float:
    """:func:`sagitta` of one arc, in scalar arithmetic (called per
    candidate piece: numpy's overhead on one element dominates)."""
    b = 0.25 * kappa * length
    if b == 0.0:
        return 0.0
    y = math.pi * (b / math.pi)
    return abs(length) * abs(b) * 0.5 * (math.sin(y) / y) ** 2


def line_fit(
    x: FloatArray, pivot: FloatArray | None = None
) -> tuple[FloatArray, FloatArray, float]:
    """Least-squares line through ``x`` (through ``pivot`` if given): a point on it,
    the unit direction along ``x``'s order, the largest distance of ``x`` from it."""
    c = x.mean(axis=0) if pivot is None else pivot
    y = x - c
    m = y.T @ y
    # the principal axis of the 2x2 scatter matrix, in closed form
    th = 0.5 * math.atan2(2.0 * m[0, 1], m[0, 0] - m[1, 1])
    d = np.array([math.cos(th), math.sin(th)])
    if float(d @ (x[-1] - x[0])) < 0.0:
        d = -d
    off = y[:, 1] * d[0] - y[:, 0] * d[1]
    return c, d, float(np.abs(off).max()) if len(off) else 0.0



def points_to_segments_distance(pts: FloatArray, a: FloatArray, b: FloatArray) -> FloatArray:
    """Distance of each point ``(M, 2)`` to each segment ``a[k]-b[k]`` ``(K, 2)``: ``(M, K)``."""
    ab = b - a
    abx, aby = ab[:, 0], ab[:, 1]
    # (the two-term dot products written out: the figures of ``einsum`` without its
    # parsing, which cost more than the arithmetic on the few points of a call)
    den = abx * abx + aby * aby
    den = np.where(den > 0.0, den, 1.0)
    ap = pts[:, None, :] - a[None, :, :]
    s = np.clip((ap[..., 0] * abx + ap[..., 1] * aby) / den[None, :], 0.0, 1.0)
    d = ap - s[:, :, None] * ab[None, :, :]
    return np.hypot(d[..., 0], d[..., 1])
