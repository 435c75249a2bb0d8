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

from zwcore.sim import nodal_closing, nodal_drop_cutter, refine_rest

__all__ = ["BallReach", "CuttingRegion", "ball_reach", "concave_radii", "cutting_positions",
           "material_blocks", "material_grid", "within_distance"]

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


@njit("void(f8[:, :], f8, f8, f8[:, :])", cache=True, nogil=True)
def _concave_kernel(z: F64, dx: float, dy: float, out: F64) -> None:
    ny, nx = z.shape
    diag = math.hypot(dx, dy)
    steps = ((0, 1, dx), (1, 0, dy), (1, 1, diag), (1, -1, diag))
    for i in range(ny):
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
    _concave_kernel(z, float(dx), float(dy), out)
    return out


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


@njit("void(b1[:, :], f8, f8, f8, b1[:, :])", cache=True, nogil=True)
def _near_kernel(seed: B8, sy: float, sx: float, reach: float, out: B8) -> None:
    """``out = distance to the nearest seed node <= reach`` (what
    ``ndimage.distance_transform_edt(~seed, sampling=(sy, sx)) <= reach`` gives, without
    its full-grid index arrays): per row the column gap to the nearest seed node in that
    row, then the least ``sqrt((gap sx)² + (rows sy)²)`` over the rows within ``reach``."""
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
    seeded = np.zeros(ny + 1, dtype=np.int64)  # rows with a seed node before row i
    for i in range(ny):
        seeded[i + 1] = seeded[i] + (1 if gap[i, 0] <= nx else 0)
    for i in range(ny):
        a0, a1 = max(0, i - rows), min(ny - 1, i + rows)
        if seeded[a1 + 1] == seeded[a0]:  # no seed row within reach: a sparse seed's
            out[i, :] = False             # usual case, one row write
            continue
        for k in range(nx):
            hit = False
            for a in range(a0, a1 + 1):
                g = gap[a, k]
                if g > nx:
                    continue
                u = g * sx
                v = (a - i) * sy
                if math.sqrt(u * u + v * v) <= reach:
                    hit = True
                    break
            out[i, k] = hit


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


def _ball_offsets(radius: float, dx: float, dy: float) -> tuple[NDArray[np.int64], F64]:
    """Half-width in columns of the ball's nodes on each row offset ``(2A + 1,)`` (-1: none)
    and ``h`` at each offset ``(2A + 1, 2B + 1)`` (+inf outside): the nodes within the
    radius, ``d² <= R²``, as the nodal drop-cutter counts them."""
    ra, rb = math.floor(radius / dy), math.floor(radius / dx)
    a, b = np.mgrid[-ra:ra + 1, -rb:rb + 1]
    d2 = (a * dy) ** 2 + (b * dx) ** 2
    inside = d2 <= radius * radius
    h = np.where(inside, radius - np.sqrt(np.maximum(radius * radius - d2, 0.0)), np.inf)
    half = np.where(inside, np.abs(b), -1).max(axis=1).astype(np.int64)
    return half, np.ascontiguousarray(h)


#: Block size of the material maxima :func:`cutting_positions` skips blocks by.
CUT_BLOCK = 8


@njit("b1(f8[:, :], f8[:, :], i8, f8, i8, i8, i8[:], f8[:, :])", cache=True, nogil=True)
def _cuts_at(material: F64, blocks: F64, b: int, t: float, i: int, k: int,
             half: NDArray[np.int64], hh: F64) -> bool:
    """Whether a node within the ball at ``(i, k)`` has ``material - h > t`` (blocks of
    ``b x b`` nodes whose maximum is at most ``t`` skipped)."""
    ny, nx = material.shape
    ra = (half.size - 1) // 2
    rb = (hh.shape[1] - 1) // 2
    i0, i1 = max(0, i - ra), min(ny - 1, i + ra)
    k0, k1 = max(0, k - rb), min(nx - 1, k + rb)
    for bi in range(i0 // b, i1 // b + 1):
        for bk in range(k0 // b, k1 // b + 1):
            if blocks[bi, bk] <= t:
                continue
            for q in range(max(i0, bi * b), min(i1, bi * b + b - 1) + 1):
                w = half[q - i + ra]
                if w < 0:
                    continue
                row = material[q]
                hr = hh[q - i + ra]
                for p in range(max(k0, k - w, bk * b), min(k1, k + w, bk * b + b - 1) + 1):
                    if row[p] - hr[p - k + rb] > t:
                        return True
    return False


@njit("void(f8[:, :], f8[:, :], i8, f8[:, :], i8[:], f8[:, :], i8[:], i8[:], b1[:, :])",
      cache=True, nogil=True)
def _cuts_kernel(material: F64, blocks: F64, b: int, cl: F64, half: NDArray[np.int64],
                 hh: F64, rows: NDArray[np.int64], cols: NDArray[np.int64], out: B8) -> None:
    for n in range(rows.size):
        i, k = rows[n], cols[n]
        out[i, k] = _cuts_at(material, blocks, b, cl[i, k], i, k, half, hh)


def cutting_positions(material: F64, cl: F64, radius: float, dx: float, dy: float,
                      positions: B8) -> B8:
    """Positions whose ball, with its tip at ``cl``, cuts into ``material``.

    Parameters
    ----------
    material : (ny, nx) float64
        Heights of the material to cut at the nodes (-inf where there is none).
    cl : (ny, nx) float64
        The ball's tip height at each asked position.
    radius, dx, dy : float
    positions : (ny, nx) bool
        The positions asked.

    Returns
    -------
    (ny, nx) bool
        ``cl(c) < max over nodes q within radius of c of material(q) - h(|q - c|)`` at
        the asked positions (the nodal drop of the ball on the material above its tip),
        False elsewhere. Exact: only blocks whose highest material is above the tip are
        visited, and a query stops at its first cutting node.
    """
    out = np.zeros(material.shape, dtype=bool)
    rows, cols = np.nonzero(positions)
    if rows.size == 0:
        return out
    b = CUT_BLOCK
    blocks = material_blocks(material)
    half, hh = _ball_offsets(radius, dx, dy)
    _cuts_kernel(np.ascontiguousarray(material, dtype=np.float64), blocks, b,
                 np.ascontiguousarray(cl, dtype=np.float64), half, hh, rows.astype(np.int64),
                 cols.astype(np.int64), out)
    return out



@njit("f8(f8[:, :], i8, i8, i8[:], f8[:, :])", cache=True, nogil=True)
def _cl_at(zp: F64, i: int, k: int, half: NDArray[np.int64], hh: F64) -> float:
    """Nodal drop-cutter CL at the padded grid's node ``(i, k)`` (the ball's nodes all
    inside it)."""
    ra = (half.size - 1) // 2
    rb = (hh.shape[1] - 1) // 2
    best = -np.inf
    for a in range(-ra, ra + 1):
        w = half[a + ra]
        row = zp[i + a]
        hr = hh[a + ra]
        for b in range(-w, w + 1):
            v = row[k + b] - hr[b + rb]
            if v > best:
                best = v
    return best


@njit("UniTuple(f8, 2)(i8[:], i8[:], f8[:, :], f8[:, :], i8, i8, i8[:], f8[:, :], f8[:, :], "
      "f8[:, :], i8, f8[:, :], f8, b1[:, :], i4[:, :], i4[:, :], i4)", cache=True, nogil=True)
def _region_kernel(rows: NDArray[np.int64], cols: NDArray[np.int64], zp: F64, cl: F64,
                   pa: int, pb: int, half: NDArray[np.int64], hh: F64, material: F64,
                   blocks: F64, b: int, rest: F64, flute: float, skip: B8,
                   seen: NDArray[np.int32], cut: NDArray[np.int32], gen: int
                   ) -> tuple[float, float]:
    """Stamp the ball's nodes around every seed node; test each position once (``seen``);
    mark those that cut (``cut``) and sum their layers ``max(1, ceil(rest / flute))``,
    positions in ``skip`` left out. Returns (positions cutting, layers)."""
    ny, nx = cl.shape
    ra = (half.size - 1) // 2
    count, layers = 0.0, 0.0
    for n in range(rows.size):
        si, sk = rows[n], cols[n]
        # seeds come row by row: after the seed just left of this one, only each disc
        # row's new right end is new
        step = n > 0 and rows[n - 1] == si and cols[n - 1] == sk - 1
        for a in range(max(-ra, -si), min(ra, ny - 1 - si) + 1):
            w = half[a + ra]
            if w < 0:
                continue
            i = si + a
            k0 = max(0, sk - w)
            if step:
                k0 = max(k0, sk + w)
            for k in range(k0, min(nx - 1, sk + w) + 1):
                if seen[i, k] == gen:
                    continue
                seen[i, k] = gen
                if skip[i, k]:
                    continue
                t = cl[i, k]
                if np.isnan(t):
                    t = _cl_at(zp, i + pa, k + pb, half, hh)
                    cl[i, k] = t
                # a tip below the material at its own node cuts it (h(0) = 0)
                if material[i, k] > t or _cuts_at(material, blocks, b, t, i, k, half, hh):
                    cut[i, k] = gen
                    count += 1.0
                    layers += max(1.0, math.ceil(rest[i, k] / flute))
    return count, layers


class CuttingRegion:
    """The positions of one ball (on one lattice) that cut a given material, near seeds.

    For the reach estimate's ranking of finishing chains: the region a rest ball really
    machines, as the plan's rest rule (:mod:`zwcore.scanline._rest`) takes it, is the
    positions within its radius of the seed whose ball, at its nodal CL on the part,
    cuts into the material the previous ball left. The CL (``(ny, nx)``, NaN until
    asked) and the stamp buffers are kept across calls, so a ball ranked after many
    previous balls computes each position's CL once.

    Parameters
    ----------
    z : (ny, nx) float64
        The part on the lattice (continued beyond its edge by its edge heights, as
        :func:`ball_reach`).
    dx, dy, radius : float
    cl : (ny, nx) float64, optional
        CL already known (NaN elsewhere), e.g. :attr:`BallReach.cl`.
    """

    def __init__(self, z: F64, dx: float, dy: float, radius: float,
                 cl: F64 | None = None) -> None:
        self.shape = z.shape
        self.radius = radius
        self.pa, self.pb = math.floor(radius / dy) + 1, math.floor(radius / dx) + 1
        self.zp = np.ascontiguousarray(np.pad(z, ((self.pa, self.pa), (self.pb, self.pb)),
                                              mode="edge"), dtype=np.float64)
        self.cl = (np.full(z.shape, np.nan) if cl is None
                   else np.array(cl, dtype=np.float64, order="C"))
        self.half, self.hh = _ball_offsets(radius, dx, dy)
        self._seen = np.zeros(z.shape, dtype=np.int32)
        self._cut = np.zeros(z.shape, dtype=np.int32)
        self._gen = 0

    def layers(self, seeds: NDArray[np.int64], material: F64, blocks: F64, rest: F64,
               flute: float, skip: B8 | None = None) -> tuple[int, float]:
        """Positions within the radius of the ``seeds`` (flat node indices) that cut
        ``material``, and their layers.

        Parameters
        ----------
        seeds : (n,) int64
        material : (ny, nx) float64
            Heights of the material (-inf where none).
        blocks : (ceil(ny / CUT_BLOCK), ceil(nx / CUT_BLOCK)) float64
            :func:`material_blocks` of ``material``.
        rest : (ny, nx) float64
            Depth of the material over the part (for the layers).
        flute : float
        skip : (ny, nx) bool, optional
            Positions left out (counted elsewhere).

        Returns
        -------
        count : int
            Positions that cut.
        layers : float
            Their sum of ``max(1, ceil(rest / flute))``.
        """
        self._gen += 1
        if skip is None:
            skip = np.zeros(self.shape, dtype=bool)
        rows, cols = np.divmod(seeds.astype(np.int64), self.shape[1])
        count, layers = _region_kernel(
            rows, cols, self.zp, self.cl, self.pa, self.pb, self.half, self.hh,
            np.ascontiguousarray(material, dtype=np.float64), blocks, CUT_BLOCK,
            np.ascontiguousarray(rest, dtype=np.float64), float(flute), skip, self._seen,
            self._cut, self._gen)
        return int(count), float(layers)

    def last_region(self) -> B8:
        """The cutting positions of the last :meth:`layers` call, ``(ny, nx)`` bool."""
        return self._cut == self._gen


@njit("void(i8[:], f8[:], i8, f8[:, :], f8[:, :])", cache=True, nogil=True)
def _material_kernel(nodes: NDArray[np.int64], heights: F64, b: int, out: F64,
                     blocks: F64) -> None:
    nx = out.shape[1]
    for n in range(nodes.size):
        i, k = nodes[n] // nx, nodes[n] % nx
        h = heights[n]
        out[i, k] = h
        if h > blocks[i // b, k // b]:
            blocks[i // b, k // b] = h


def material_grid(shape: tuple[int, int], nodes: NDArray[np.int64], heights: F64
                  ) -> tuple[F64, F64]:
    """The material's heights on the grid (-inf off ``nodes``) and their maxima over blocks
    of ``CUT_BLOCK`` nodes each way (:func:`material_blocks`), from the flat indices and
    heights of the nodes that carry material (in one pass over them).

    Returns
    -------
    grid : (ny, nx) float64
    blocks : (ceil(ny / CUT_BLOCK), ceil(nx / CUT_BLOCK)) float64
    """
    b = CUT_BLOCK
    grid = np.full(shape, -np.inf)
    blocks = np.full((-(-shape[0] // b), -(-shape[1] // b)), -np.inf)
    _material_kernel(nodes.astype(np.int64), np.ascontiguousarray(heights, dtype=np.float64),
                     b, grid, blocks)
    return grid, blocks


def material_blocks(material: F64) -> F64:
    """Maxima of ``material`` ``(ny, nx)`` over blocks of ``CUT_BLOCK`` nodes each way."""
    ny, nx = material.shape
    b = CUT_BLOCK
    py, px = -(-ny // b) * b, -(-nx // b) * b
    pad = np.full((py, px), -np.inf)
    pad[:ny, :nx] = material
    return np.ascontiguousarray(pad.reshape(py // b, b, px // b, b).max(axis=(1, 3)))
