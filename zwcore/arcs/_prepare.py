"""Input checks and preprocessing of the arc fit: validation, repeated points, corners,
the densified sample polyline and the runs between corners (step 1 of
:mod:`zwcore.arcs.fit`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from zwcore.arcs.verify import densify
from zwcore.errors import InvalidInputError

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

__all__ = ["Prepared", "find_corners", "prepare"]


@dataclass(frozen=True)
class Prepared:
    """The curve as the fit sees it.

    ``origin`` (input coordinates of the local frame's origin), ``samples`` ``(M, 2)``
    (the densified polyline, local frame; a closed curve repeats its first point at the
    end), ``bounds`` (sample indices of the runs' ends), ``cs`` (samples of the corners),
    ``wrap`` (a closed curve whose first run passes its first point smoothly), ``loop``
    (a closed curve without corners: one run closing C1 on itself).
    """

    origin: FloatArray
    samples: FloatArray
    tol: float
    closed: bool
    bounds: list[int]
    cs: list[int]
    wrap: bool
    loop: bool

    @property
    def m_last(self) -> int:
        """Index of the last sample."""
        return len(self.samples) - 1


def validate(
    points: ArrayLike,
    tolerance: float,
    corner_angle_deg: float,
    max_radius: float | None,
) -> FloatArray:
    """``points`` as an ``(N, 2)`` float array, after checking every argument."""
    try:
        pts = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError("points", f"not a numeric (N, 2) array: {exc}") from None
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise InvalidInputError("points", f"expected shape (N, 2), got {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise InvalidInputError("points", "contains non-finite values")
    if not (isinstance(tolerance, int | float) and math.isfinite(tolerance) and tolerance > 0):
        raise InvalidInputError("tolerance", "must be a finite number > 0")
    if not (
        isinstance(corner_angle_deg, int | float)
        and math.isfinite(corner_angle_deg)
        and 0 < corner_angle_deg <= 180
    ):
        raise InvalidInputError("corner_angle_deg", "must be in (0, 180]")
    if max_radius is not None and not (
        isinstance(max_radius, int | float) and math.isfinite(max_radius) and max_radius > 0
    ):
        raise InvalidInputError("max_radius", "must be a finite number > 0 or null")
    return pts


def _dedupe(x: FloatArray, closed: bool, eps: float) -> FloatArray:
    """Drop points closer than ``eps`` to their kept predecessor (and a repeated closing point)."""
    keep = [0]
    last = x[0]
    d = np.hypot(*(np.diff(x, axis=0).T))
    if np.all(d > eps):
        out = x
    else:
        for i in range(1, len(x)):
            if math.hypot(x[i, 0] - last[0], x[i, 1] - last[1]) > eps:
                keep.append(i)
                last = x[i]
        out = x[keep]
    if closed:
        while len(out) > 1 and math.hypot(*(out[-1] - out[0])) <= eps:
            out = out[:-1]
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _along(x: FloatArray, s: FloatArray, at: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The polyline ``x`` ``(M, 2)`` (arc lengths ``s``) at arc lengths ``at``: x, y."""
    return np.interp(at, s, x[:, 0].copy()), np.interp(at, s, x[:, 1].copy())


@njit(cache=True, nogil=True, error_model="numpy")
def _probe_points(
    x: FloatArray, seg: FloatArray, total: float, closed: bool, d_probe: float
) -> tuple[FloatArray, FloatArray, FloatArray, IntArray, FloatArray, FloatArray]:
    """The compiled part of :func:`_probe_turns` (``seg``: its segment lengths, ``total``
    their sum): the probes' offsets ``a`` (point - before) and ``b`` (after - point)
    ``(K, 2)``, the heights and ``idx, si, s`` (numpy's arithmetic: its cumulative sum
    and its interpolation, the same figures)."""
    n = len(x)
    s = np.empty(len(seg) + 1)
    s[0] = 0.0
    for i in range(len(seg)):
        s[i + 1] = s[i] + seg[i]
    if closed:
        # three laps so that probes wrap around
        x3 = np.empty((3 * n + 1, 2))
        for lap in range(3):
            x3[lap * n : (lap + 1) * n] = x
        x3[3 * n] = x[0]
        s3 = np.concatenate((s[:-1] - total, s[:-1], s + total))
        si = s[:-1].copy()
        h = min(d_probe, 0.25 * total)
        bx, by = _along(x3, s3, si - h)
        ax, ay = _along(x3, s3, si + h)
        idx = np.arange(n)
    else:
        si = s[1:-1].copy()
        bx, by = _along(x, s, np.maximum(si - d_probe, 0.0))
        ax, ay = _along(x, s, np.minimum(si + d_probe, s[-1]))
        idx = np.arange(1, n - 1)
    a = np.empty((len(idx), 2))
    b = np.empty((len(idx), 2))
    height = np.empty(len(idx))
    for i in range(len(idx)):
        px, py = x[idx[i], 0], x[idx[i], 1]
        a[i, 0], a[i, 1] = px - bx[i], py - by[i]
        b[i, 0], b[i, 1] = ax[i] - px, ay[i] - py
        cx, cy = ax[i] - bx[i], ay[i] - by[i]
        height[i] = abs(cx * a[i, 1] - cy * a[i, 0]) / max(np.hypot(cx, cy), 1e-300)
    return a, b, height, idx, si, s


def _probe_turns(
    x: FloatArray, closed: bool, d_probe: float
) -> tuple[FloatArray, FloatArray, NDArray[np.int64], FloatArray, FloatArray]:
    """The turn and the height over the probes' chord at every candidate point.

    Returns ``(turn, height, idx, si, s)``: turn (radians) and height at input points
    ``idx``, their arc-length positions ``si``, and the cumulative length ``s``. The
    probes are compiled (:func:`_probe_points`); the lengths' sum (pairwise) and the
    turns' ``arctan2`` (SIMD, an ulp off libm's at times) stay numpy's.
    """
    seg = np.hypot(*(np.diff(np.vstack([x, x[:1]]) if closed else x, axis=0).T))
    total = float(seg.sum()) if closed else 0.0
    a, b, height, idx, si, s = _probe_points(
        np.ascontiguousarray(x, dtype=np.float64), seg, total, closed, float(d_probe))
    turn = np.abs(np.arctan2(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0], (a * b).sum(axis=1)))
    return turn, height, idx, si, s


def find_corners(x: FloatArray, closed: bool, tol: float, angle: float) -> list[int]:
    """Input indices where the curve turns by more than ``angle`` at the tolerance scale."""
    n = len(x)
    if n < 3 and not closed:
        return []
    d_probe = 3.0 * tol
    turn, height, idx, si, s = _probe_turns(x, closed, d_probe)
    # a corner must also stand out of the chord between the probes by a visible amount
    # (half of what a corner of exactly `angle` shows at full probe length), so curves
    # that are small at the tolerance scale get no corners from their tiny wiggles
    hot = np.flatnonzero((turn > angle) & (height > 0.5 * d_probe * math.sin(0.5 * angle)))
    if hot.size == 0:
        return []
    # one corner per cluster of hot points (closer than two probe lengths): its sharpest point
    corners: list[int] = []
    start = 0
    for m in range(1, hot.size + 1):
        if m == hot.size or si[hot[m]] - si[hot[m - 1]] > 2.0 * d_probe:
            grp = hot[start:m]
            corners.append(int(idx[grp[np.argmax(turn[grp])]]))
            start = m
    if closed and len(corners) > 1:
        # the cluster may wrap around the start of the loop
        total = float(s[-1])
        first, last = corners[0], corners[-1]
        if total - si[last] + si[first] <= 2.0 * d_probe:
            keep = first if turn[first] >= turn[last] else last
            corners = [c for c in corners if c not in (first, last)] + [keep]
            corners.sort()
    return corners


#: mm; a curve spanning less has no two points a machine tells apart: an error on
#: ``points``, whatever the tolerance (above it, merged points blame the tolerance)
MIN_CURVE_SPAN = 1e-6


def _blame_merged_points(x: FloatArray, closed: bool, tol: float, scale: float) -> None:
    """Raise for a curve whose points all merged: the tolerance's fault when the curve
    has a measurable size and only the tolerance term merged it, else the points'."""
    span = float(np.ptp(x, axis=0).max())
    if span >= MIN_CURVE_SPAN and len(_dedupe(x, closed, 1e-14 * scale)) >= 2:
        raise InvalidInputError(
            "tolerance", f"{tol:g} mm is too large for this curve: all its points lie "
            f"within {1e-9 * tol:g} mm (1e-9 tolerances) of each other")
    raise InvalidInputError("points", "fewer than two distinct points")


def prepare(raw: FloatArray, tol: float, closed: bool, corner_angle_deg: float) -> Prepared:
    """The validated input ``raw`` ``(N, 2)`` as samples and runs (see :class:`Prepared`)."""
    if len(raw) < 2:
        raise InvalidInputError("points", "need at least two points")
    origin = raw[0].copy()
    # work relative to the first point so large coordinates keep their precision
    x = raw - origin
    # points a few ulps of the *absolute* coordinates apart are one point: arcs built
    # between them would not survive the shift back to input coordinates
    scale = max(float(np.abs(x).max()), float(np.abs(raw).max()))
    eps = max(1e-9 * tol, 1e-14 * scale)
    x_all = x
    x = _dedupe(x, closed, eps)
    if len(x) < 2:
        _blame_merged_points(x_all, closed, tol, scale)
    corners_in = find_corners(x, closed, tol, math.radians(corner_angle_deg))
    poly = np.vstack([x, x[:1]]) if closed else x
    # densify long polyline segments so junctions can sit between sparse input points
    seg = np.hypot(*(np.diff(poly, axis=0).T))
    nsub = np.maximum(np.ceil(seg / (6.0 * tol)).astype(np.int64), 1)
    # (C order: the compiled kernels are specialised for it)
    samples = np.ascontiguousarray(densify(poly, 6.0 * tol) if np.any(nsub > 1) else poly)
    sample_of_input = np.concatenate([[0], np.cumsum(nsub)])
    m_last = len(samples) - 1
    cs = [int(sample_of_input[c]) for c in corners_in]
    # a closed curve with corners, whose first point is not one of them, wraps: the run
    # from the last corner round to the first one passes the first point with a smooth
    # junction there (the chain starts and ends at the first point)
    wrap = closed and bool(cs) and cs[0] != 0
    if closed and cs and not wrap:
        bounds = [*cs, m_last]
    elif closed and not cs:
        bounds = [0, m_last]
    else:
        bounds = [0, *cs, m_last]
    return Prepared(origin, samples, tol, closed, bounds, cs, wrap, closed and not cs)
