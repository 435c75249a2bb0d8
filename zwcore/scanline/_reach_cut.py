"""Which positions of a ball cut a given material: the reach estimate's rest regions.

A rest ball's region, as the plan's rest rule (:mod:`zwcore.scanline._rest`) takes it on
the simulated stock, is the positions near its seed whose ball, at its drop-cutter CL on
the part, cuts into the material the balls before it left. The reach estimate
(:mod:`zwcore.scanline._regions`) ranks finishing chains by that region on the balls'
lattices, for every (previous ball, next ball) pair, so it is computed here in compiled
passes over the seeds alone (no full-grid temporaries), with each position's CL kept per
ball across pairs:

- :func:`cutting_positions`: at asked positions, whether
  ``cl(c) < max over nodes q within R of material(q) - h(|q - c|)`` (the nodal drop of
  the ball on the material above its tip); blocks of :data:`CUT_BLOCK` nodes whose
  highest material is at most the tip are skipped, a query stops at its first cutting
  node;
- :class:`CuttingRegion`: the same test at every position within the radius of seed
  nodes (each tested once), the CL dropped on the part where not known yet, and the
  layers ``max(1, ceil(rest / flute))`` the region's positions need.

The nodes within the radius are those with ``d² <= R²``, as the nodal drop-cutter
(:func:`zwcore.sim.nodal_drop_cutter`) counts them.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from zwcore.sim import ball_offsets

__all__ = ["CUT_BLOCK", "CuttingRegion", "cutting_positions", "material_blocks",
           "material_grid"]

F64 = NDArray[np.float64]
B8 = NDArray[np.bool_]


def _plain(a: NDArray[np.floating]) -> F64:
    """``a`` as a writable C-ordered float64 array (the kernels' signatures; a read-only
    grid, a stored z-map say, is copied)."""
    return np.require(a, dtype=np.float64, requirements=["C", "W"])


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
        q0, q1 = max(i0, bi * b), min(i1, bi * b + b - 1)
        ea = 0 if q0 <= i <= q1 else min(abs(q0 - i), abs(q1 - i))
        for bk in range(k0 // b, k1 // b + 1):
            if blocks[bi, bk] <= t:
                continue
            # h at the block's nearest offset is no more than at any of its nodes (the
            # same rounded formula, monotone in |a| and |b|; +inf: none within R), so no
            # node of a block whose maximum less it is at most t can cut
            p0, p1 = max(k0, bk * b), min(k1, bk * b + b - 1)
            eb = 0 if p0 <= k <= p1 else min(abs(p0 - k), abs(p1 - k))
            if blocks[bi, bk] - hh[ea + ra, eb + rb] <= t:
                continue
            for q in range(q0, q1 + 1):
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
    half, hh = ball_offsets(radius, dx, dy)
    _cuts_kernel(_plain(material), blocks, b,
                 _plain(cl), half, hh, rows.astype(np.int64),
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
        self.half, self.hh = ball_offsets(radius, dx, dy)
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
            _plain(material), blocks, CUT_BLOCK,
            _plain(rest), float(flute), skip, self._seen,
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
    _material_kernel(nodes.astype(np.int64), _plain(heights),
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
