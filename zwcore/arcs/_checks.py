"""The conservative two-sided bounds of :meth:`zwcore.arcs._pieces.ToleranceBand.verify`.

A piece starts at ``p`` with unit tangent ``t`` and signed curvature ``kappa``; the
samples it stands for are given in its local frame (``u`` along ``t``, ``v`` to the
left). Each function bounds one part of the two-sided distance: the samples to the
piece, the polyline segments' interiors to the piece, and the piece's portions between
consecutive foot points to the polyline.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from zwcore.arcs._geometry import circle_gap, sagitta, unwrap

FloatArray = NDArray[np.float64]

__all__ = ["foot_positions", "portion_bounds", "samples_within", "segments_within"]


def foot_positions(u: FloatArray, v: FloatArray, kappa: float) -> FloatArray:
    """Arc-length position ``(n,)`` of each sample's foot point on the piece (the first
    sample, the piece's start, at 0)."""
    if kappa != 0.0:
        phi = np.arctan2(kappa * u, 1.0 - kappa * v)
        phi[0] = 0.0
        return unwrap(phi) / kappa
    sig = u.copy()
    sig[0] = 0.0
    return sig


def samples_within(
    u: FloatArray, v: FloatArray, g: FloatArray, sig: FloatArray, sig_end: float,
    de: FloatArray, tol: float,
) -> bool:
    """True when every sample after the first is within ``tol`` of the piece: its gap
    ``g`` to the circle, or its distance to the start (foot before it) or to the end
    (``de``, foot after it)."""
    q = np.hypot(u, v)
    before = sig < 0.0
    after = sig > sig_end
    d = np.where(before, q, np.where(after, de, g))
    return not (d.size > 1 and d[1:].max() > tol)


def segments_within(
    u: FloatArray, v: FloatArray, sig: FloatArray, sig_end: float, p: FloatArray,
    t: FloatArray, end: FloatArray, kappa: float, tol: float, dense_first: bool,
) -> bool:
    """True when the interiors of the polyline segments are within ``tol`` of the arc
    (``kappa != 0``): the farthest point from a circle on a segment is an end point or
    the point closest to the centre. The piece starts at ``p`` along ``t`` and ends at
    ``end``; ``dense_first`` skips the first segment (checked densely by the caller)."""
    du = np.diff(u)
    dv = np.diff(v)
    den = du * du + dv * dv
    den = np.where(den > 0.0, den, 1.0)
    ts = np.clip((-u[:-1] * du + (1.0 / kappa - v[:-1]) * dv) / den, 0.0, 1.0)
    xu = u[:-1] + ts * du
    xv = v[:-1] + ts * dv
    gx = np.abs(circle_gap(xu, xv, kappa))
    inside = (sig[:-1] >= 0.0) & (sig[1:] <= sig_end)
    xe = np.hypot(
        xu - (end[0] - p[0]) * t[0] - (end[1] - p[1]) * t[1],
        xv - (end[1] - p[1]) * t[0] + (end[0] - p[0]) * t[1],
    )
    dx = np.where(inside, gx, np.maximum(gx, np.minimum(np.hypot(xu, xv), xe)))
    if dense_first:
        dx[0] = 0.0
    return not dx.max() > tol


def portion_bounds(
    pts: FloatArray, sig: FloatArray, sig_end: float, g: FloatArray, de: FloatArray,
    e_k: float, kappa: float,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Bounds on the distance of the arc portions between consecutive (running-max) foot
    points to the polyline.

    Returns ``(bound, dphi, phi_c)``: the bound per portion ``(n-1,)``, the portions'
    lengths (0: empty) and the clipped running foot positions ``(n,)``. ``e_k`` is the
    distance of the first sample from the piece's start.
    """
    run = np.maximum.accumulate(sig)
    phi_c = np.clip(run, 0.0, sig_end)
    idx = np.arange(len(sig))
    arg = np.maximum.accumulate(np.where(sig >= run, idx, 0))
    e_at = np.where(sig <= sig_end, g, de)
    e_at[0] = e_k
    dphi = np.diff(phi_c)
    a_idx = arg[:-1]
    jit = np.hypot(pts[a_idx, 0] - pts[:-1, 0], pts[a_idx, 1] - pts[:-1, 1])
    bound = np.maximum(e_at[a_idx], e_at[1:]) + sagitta(kappa, dphi) + jit
    return bound, dphi, phi_c
