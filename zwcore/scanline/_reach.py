"""Which nodes of a z-map a ball end mill reaches: rest material by simulation.

The rest a ball of radius ``R`` leaves is its *nodal* closing minus the part (see
:mod:`zwcore.sim._nodal`: the part's node samples, tool positions at the nodes),
the meaning the tool-path layer machines. Computing it at every node of a fine
grid for every library ball would cost seconds, so it is computed only where a
ball can leave anything:

- a node is *tight* for ``R`` where the part's concave radius there, along x, y or a
  diagonal, is below ``R`` (second differences with one-sided "minmod" slopes, so
  the foot of a wall reads as sharp);
- where a ball leaves material at ``p``, the ball covering ``p`` touches the part at
  two points with ``p`` between, and along the segment between them the part must
  bend more sharply than the ball: a tight node lies within ``2R`` of ``p``.

So rest is computed exactly at the nodes within ``2R`` (plus a cell) of a tight node,
from CL positions within ``3R``; every other node is reached. Tool positions only at
nodes leave small *position cusps* between positions (larger on steep walls); they
are not real (the machine moves continuously along its lines) and, where they fall
in the band, the tool choice discounts them by comparing balls: a smaller ball is
sent to a node only where it does better there by more than the tolerance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import NDArray

from zwcore.scanline._threads import both, split
from zwcore.sim import nodal_closing, nodal_drop_cutter, refine_rest

__all__ = ["BallReach", "ball_reach", "concave_radii", "within_distance"]

F64 = NDArray[np.float64]
B8 = NDArray[np.bool_]

#: A node's closing search stops this share of the tolerance above the part.
STOP_SHARE = 1e-3


@dataclass(frozen=True, eq=False)
class BallReach:
    """Where one ball leaves material over a surface.

    Attributes
    ----------
    radius : float
    rest : (ny, nx) float64
        Nodal closing minus the surface, >= 0 (0 where the ball reaches).
    band : (ny, nx) bool
        Nodes where the rest was computed (elsewhere it is 0 by the tight-node bound).
    positions : int
        CL positions computed.
    cl : (ny, nx) float64 or None
        The nodal drop-cutter CL at the positions computed inside the grid (NaN at the
        others; None when none was).
    """

    radius: float
    rest: F64
    band: B8
    positions: int
    cl: F64 | None = None


@njit("void(f8[:, :], f8, f8, f8[:, :], i8, i8)", cache=True, nogil=True)
def _concave_kernel(z: F64, dx: float, dy: float, out: F64, i0: int, i1: int) -> None:
    """Rows ``i0..i1-1`` of :func:`concave_radii` (each row from its neighbours alone:
    two threads take two bands)."""
    ny, nx = z.shape
    diag = math.hypot(dx, dy)
    steps = ((0, 1, dx), (1, 0, dy), (1, 1, diag), (1, -1, diag))
    for i in range(i0, i1):
        for k in range(nx):
            best = np.inf
            c = z[i, k]
            for da, db, step in steps:
                ia, ka, ib, kb = i + da, k + db, i - da, k - db
                if ia < 0 or ia >= ny or ib < 0 or ib >= ny:
                    continue  # no curvature across the grid's edge
                if ka < 0 or ka >= nx or kb < 0 or kb >= nx:
                    continue
                right = (z[ia, ka] - c) / step
                left = (c - z[ib, kb]) / step
                curv = (right - left) / step
                if not curv > 0.0:
                    continue
                s = 0.0  # minmod of the one-sided slopes
                if left * right > 0.0:
                    s = min(abs(left), abs(right))
                rho = (1.0 + s * s) ** 1.5 / curv
                if rho < best:
                    best = rho
            out[i, k] = best


def concave_radii(z: F64, dx: float, dy: float) -> F64:
    """Smallest concave radius at each node along x, y and the diagonals (inf: none).

    Parameters
    ----------
    z : (ny, nx) float64
    dx, dy : float

    Returns
    -------
    (ny, nx) float64
        ``(1 + s²)^1.5 / f''`` with ``f''`` the second difference and ``s`` the
        minmod of the one-sided slopes (so the foot of a wall reads as sharp and a
        bowl's rim does not); none across the grid's edge.
    """
    out = np.empty(z.shape)
    z = np.require(z, dtype=np.float64, requirements=["C", "W"])  # (a read-only grid: copied)
    ny = z.shape[0]
    if z.size < THREAD_NODES or not split():
        _concave_kernel(z, float(dx), float(dy), out, 0, ny)
    else:  # two bands of rows on two threads (_threads): the same values
        h = ny // 2
        both(lambda: _concave_kernel(z, float(dx), float(dy), out, 0, h),
             lambda: _concave_kernel(z, float(dx), float(dy), out, h, ny))
    return out


#: Nodes from which :func:`concave_radii` runs on two threads.
THREAD_NODES = 1 << 18


def within_distance(seed: B8, distance: float, dx: float, dy: float) -> B8:
    """Nodes within ``distance`` (mm, Euclidean) of a seed node, conservatively.

    On blocks of ``k x k`` nodes (``k`` about a quarter of the distance in cells) and
    widened by a block diagonal, so the result covers the exact set.
    """
    if not seed.any():
        return np.zeros(seed.shape, dtype=bool)
    # only the seed's bounding box grown by the distance can be reached
    rows = np.flatnonzero(seed.any(axis=1))
    cols = np.flatnonzero(seed.any(axis=0))
    ga, gb = math.ceil(distance / dy) + 1, math.ceil(distance / dx) + 1
    r0, r1 = max(0, rows[0] - ga), min(seed.shape[0], rows[-1] + ga + 1)
    c0, c1 = max(0, cols[0] - gb), min(seed.shape[1], cols[-1] + gb + 1)
    out = np.zeros(seed.shape, dtype=bool)
    out[r0:r1, c0:c1] = _within_box(seed[r0:r1, c0:c1], distance, dx, dy)
    return out


@njit("void(b1[:, ::1], f8, f8, f8, b1[:, ::1])", cache=True, nogil=True)
def _near_kernel(seed: B8, sy: float, sx: float, reach: float, out: B8) -> None:
    """``out = distance to the nearest seed node <= reach`` (what
    ``ndimage.distance_transform_edt(~seed, sampling=(sy, sx)) <= reach`` gives, without
    its full-grid index arrays): per row the column gap to the nearest seed node in that
    row, then whether ``sqrt((gap sx)² + (rows sy)²) <= reach`` for some row within
    ``reach``: per row offset the largest gap passing that (rounded) test is found once,
    so the rows are integer compares over whole rows."""
    ny, nx = seed.shape
    big = nx + 1  # no seed node in the row
    gap = np.empty((ny, nx), dtype=np.int64)
    for i in range(ny):
        last = -big
        for k in range(nx):
            if seed[i, k]:
                last = k
            gap[i, k] = k - last
        last = nx + big
        for k in range(nx - 1, -1, -1):
            if seed[i, k]:
                last = k
            if last - k < gap[i, k]:
                gap[i, k] = last - k
    rows = int(reach / sy) if sy > 0.0 else 0
    # per row offset d the largest column gap within reach, by the same rounded test
    # (monotone in the gap: every step rounds monotonically), -1 where none is
    gmax = np.full(rows + 1, -1, dtype=np.int64)
    for d in range(rows + 1):
        v = d * sy
        g = 0
        while g <= nx and math.sqrt((g * sx) * (g * sx) + v * v) <= reach:
            g += 1
        gmax[d] = g - 1
    seeded = np.zeros(ny + 1, dtype=np.int64)  # rows with a seed node before row i
    for i in range(ny):
        seeded[i + 1] = seeded[i] + (1 if gap[i, 0] <= nx else 0)
    for i in range(ny):
        a0, a1 = max(0, i - rows), min(ny - 1, i + rows)
        orow = out[i]
        orow[:] = False
        if seeded[a1 + 1] == seeded[a0]:  # no seed row within reach: a sparse seed's
            continue                      # usual case, one row write
        for a in range(a0, a1 + 1):
            gm = gmax[abs(a - i)]
            if gm < 0 or seeded[a + 1] == seeded[a]:
                continue
            grow = gap[a]
            for k in range(nx):
                if grow[k] <= gm:
                    orow[k] = True


def _within_box(seed: B8, distance: float, dx: float, dy: float) -> B8:
    ny, nx = seed.shape
    k = max(1, int(distance / (4.0 * max(dx, dy))))
    if k > 1:
        py, px = -(-ny // k) * k, -(-nx // k) * k
        pad = np.zeros((py, px), dtype=bool)
        pad[:ny, :nx] = seed
        coarse = pad.reshape(py // k, k, px // k, k).any(axis=(1, 3))
    else:
        coarse = seed
    reach = distance + (k * math.hypot(dx, dy) if k > 1 else 0.0)
    near = np.empty(coarse.shape, dtype=bool)
    _near_kernel(np.ascontiguousarray(coarse), float(k * dy), float(k * dx), float(reach),
                 near)
    if k > 1:
        near = np.repeat(np.repeat(near, k, axis=0), k, axis=1)[:ny, :nx]
    return near


def ball_reach(z: F64, dx: float, dy: float, radius: float, tolerance: float,
               rho: F64 | None = None) -> BallReach:
    """Rest material of a ball of ``radius`` over the nodes of ``z``.

    Parameters
    ----------
    z : (ny, nx) float64
        The surface (a part or a stage target), at its own nodes.
    dx, dy, radius, tolerance : float
        mm; the rest is exact to ``STOP_SHARE * tolerance``.
    rho : (ny, nx) float64, optional
        :func:`concave_radii` of ``z`` (computed when not given).

    Returns
    -------
    BallReach
    """
    if rho is None:
        rho = concave_radii(z, dx, dy)
    tight = rho < radius
    band = within_distance(tight, 2.0 * radius, dx, dy)
    rest = np.zeros(z.shape)
    if not band.any():
        return BallReach(radius, rest, band, 0)
    # Positions may lie beyond the grid (the tool runs past the part's edge), over the
    # part's edge heights continued outwards (stock or fixture there, as the roughing
    # levels assume): a ball cannot dive beside the edge and touch it from the side.
    pa, pb = math.floor(radius / dy) + 1, math.floor(radius / dx) + 1
    zp = np.pad(z, ((pa, pa), (pb, pb)), mode="edge")
    bandp = np.pad(band, ((pa, pa), (pb, pb)))
    positions = within_distance(bandp, radius, dx, dy)
    cl, _ = nodal_drop_cutter(zp, radius, dx, dy, positions)
    closed = nodal_closing(zp, cl, radius, dx, dy, bandp, stop=STOP_SHARE * tolerance)
    np.maximum(closed[pa:pa + z.shape[0], pb:pb + z.shape[1]] - z, 0.0, out=rest)
    refine_rest(z, dx, dy, radius, rest, rest > tolerance, tolerance)
    inner = cl[pa:pa + z.shape[0], pb:pb + z.shape[1]]
    return BallReach(radius, rest, band, int(positions.sum()),
                     np.where(np.isfinite(inner), inner, np.nan))
