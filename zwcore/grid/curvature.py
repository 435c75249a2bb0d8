"""Concave radius of curvature and steepest slope of a bilinear height grid.

A ball end mill of radius ``R`` reproduces a concave (valley-like) region only
where every normal curvature of the surface is at most ``1/R``. With z up, a
valley has a positive second derivative, so the quantity that limits the ball
is the largest principal curvature ``kappa_max`` where it is positive, and the
concave radius is ``1/kappa_max``.

How it is estimated (design section 3, step 2), at a grid's own spacing:

- Hessian by central differences on the 3 x 3 nodes around each node
  (exact for quadrics). On a bilinear model a crease's whole turn sits at
  its node; the stencil spreads it over one cell each side, which gives the
  "grid scale" radius ``h / (slope jump)``: detail below the spacing does not
  exist in the model, so a level of spacing ``h`` demands a radius far below
  ``h`` only where it really has a sharp crease.
- The concave eigenvalue is capped by the largest normal curvature measured
  straight along the four grid directions (x, y, both diagonals), divided by
  ``cos^2(22.5 deg)``. On smooth surfaces the cap does not bind; where the
  nine nodes are no quadric (a convex crease running diagonally, whose
  bilinear cells are saddles) the Hessian alone invents a concave direction
  that no line of nodes shows, and the cap removes it.
- The curvatures are those of the graph ``z = f(x, y)`` (shape operator with
  the first fundamental form), so a spherical bowl gives ``1/r`` everywhere,
  also on its steep flanks, and not the larger curvature of its vertical
  sections.
- The slopes in the metric are one-sided differences, not central ones. Along
  an axis where the nodes bend concave, the smaller one (*minmod*): at the
  foot of a steep wall a central slope would tilt the normal by half the wall
  and divide the crease's curvature by ``(1 + s^2/4)^1.5``, reporting a large
  radius for a sharp corner; minmod keeps the floor's normal, so steep
  creases come out sharp, as they are. Along an axis where they bend convex,
  the larger one: next to a ridge (a bowl's rim) the normal is the steep
  face's, not a flat neighbour's. On smooth surfaces either differs from the
  central slope by ``O(h f'')``.
- Boundary nodes take the second derivatives of their interior neighbour: the
  part's edge is not a crease (padding extends the part flat, which would
  otherwise read as a concave kink at every falling edge).
- Noise: second differences amplify height noise by ``~2.5/h^2``. Noise only
  ever *lowers* the estimated radius (the minimum is taken over all nodes), so
  the planner stays on the safe side; ``smoothing`` (a Gaussian of that many
  cells, which leaves quadrics unchanged inside the grid) recovers the radius
  of noisy scans.
- Curvatures below the rounding floor of the grid (``~eps |z| / h^2``) count
  as flat, so planes give ``inf``.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

__all__ = [
    "concave_curvature",
    "max_principal_curvature",
    "min_concave_radius",
    "steepest_slope",
]

F64 = NDArray[np.float64]


def _central(z: F64, di: int, dk: int) -> F64:
    """Raw second difference ``z[i+di, k+dk] - 2 z[i, k] + z[i-di, k-dk]`` at every node.

    Interior nodes only; nodes on the grid's edge copy their inner neighbour,
    because the part's edge is not a crease (the padding that extends a part
    flat would otherwise read as a kink at every falling edge). Fewer than 3
    nodes along a direction used: 0 (a bilinear patch is straight there).
    """
    ny, nx = z.shape
    if (di and ny < 3) or (dk and nx < 3):
        return np.zeros_like(z)
    i0, i1 = (1, ny - 1) if di else (0, ny)
    k0, k1 = (1, nx - 1) if dk else (0, nx)
    c = z[i0:i1, k0:k1]
    d = z[i0 + di:i1 + di, k0 + dk:k1 + dk] + z[i0 - di:i1 - di, k0 - dk:k1 - dk]
    d -= 2.0 * c
    return np.pad(d, ((i0, ny - i1), (k0, nx - k1)), mode="edge")


def _metric_slope(z: F64, h: float, axis: int) -> F64:
    """Slope along ``axis`` for the surface normal, chosen to stay honest at creases.

    Where the line of nodes bends concave at the node, the one-sided
    difference of smaller magnitude (0 if they change sign): at the foot of a
    wall the normal stays the floor's, so the crease is not divided by the
    wall's slope. Where it bends convex (or not at all), the larger one: on a
    ridge the ball can rest with any normal of the fan between the two faces,
    and the steeper face is the one a valley running along the ridge is
    measured against (a bowl's rim). On smooth surfaces either choice differs
    from the central slope by ``O(h f'')``.
    """
    d = np.diff(z, axis=axis)
    d *= 1.0 / h
    if axis == 0:
        left = np.concatenate([d[:1], d], axis=0)
        right = np.concatenate([d, d[-1:]], axis=0)
    else:
        left = np.concatenate([d[:, :1], d], axis=1)
        right = np.concatenate([d, d[:, -1:]], axis=1)
    smaller = np.abs(left) < np.abs(right)
    concave = right > left
    m = np.where(smaller == concave, left, right)
    m[concave & (left * right <= 0.0)] = 0.0
    return m


#: Four grid directions are 45 degrees apart, so on a quadric the largest
#: directional curvature is at least cos^2(22.5 deg) of the principal one.
_DIRECTIONAL_GAP = float(np.cos(np.pi / 8.0) ** 2)


#: Rows per block: the formula makes ~40 temporaries per node, so it runs in
#: blocks of rows small enough to stay in cache (bit-identical to one pass).
_BLOCK_NODES = 1 << 15


def _prepared(z: F64, smoothing: float) -> F64:
    zz = np.asarray(z, dtype=np.float64)
    if smoothing > 0.0:
        zz = ndimage.gaussian_filter(zz, sigma=float(smoothing), mode="nearest")
    return zz


def _row_blocks(zz: F64, sx: float, sy: float) -> Iterator[tuple[int, int, F64]]:
    """``(a, b, kappa[a:b])`` over blocks of rows.

    Every value depends on the node's 3 x 3 neighbourhood only (and edge rows
    copy their inner neighbour), so a block computed with one halo row on each
    side gives exactly the rows of the whole-grid computation.
    """
    ny, nx = zz.shape
    rows = max(4, _BLOCK_NODES // max(nx, 1))
    if ny <= rows + 2:
        yield 0, ny, _kappa_block(zz, sx, sy)
        return
    for a in range(0, ny, rows):
        b = min(a + rows, ny)
        if ny - b < 2:  # keep the last block at least two rows long
            b = ny
        lo, hi = max(a - 1, 0), min(b + 1, ny)
        k = _kappa_block(zz[lo:hi], sx, sy)
        yield a, b, k[a - lo: a - lo + (b - a)]
        if b == ny:
            return


def _kappa_block(zz: F64, sx: float, sy: float) -> F64:
    """The curvature formula on a block of rows (edges of the block treated as grid edges)."""
    dxx = _central(zz, 0, 1)
    dyy = _central(zz, 1, 0)
    d45 = _central(zz, 1, 1)
    d135 = _central(zz, 1, -1)
    p = _metric_slope(zz, sx, 1)
    q = _metric_slope(zz, sy, 0)
    r = dxx * (1.0 / (sx * sx))
    t = dyy * (1.0 / (sy * sy))
    s = (d45 - d135) * (1.0 / (4.0 * sx * sy))
    p2 = p * p
    q2 = q * q
    w = 1.0 + p2 + q2
    sw = np.sqrt(w)
    # Mean and Gaussian curvature of a graph (Monge patch, do Carmo 3.3).
    mean = ((1.0 + q2) * r - 2.0 * p * q * s + (1.0 + p2) * t) / (2.0 * w * sw)
    gauss = (r * t - s * s) / (w * w)
    disc = mean * mean - gauss
    np.maximum(disc, 0.0, out=disc)  # rounding can push an umbilic slightly negative
    kappa = mean + np.sqrt(disc)
    # Normal curvature along a grid step v = (vx, vy): D_v / (sqrt(W) |T|^2),
    # with T = (vx, vy, grad f . v) the step lifted onto the tangent plane.
    best = np.full_like(kappa, -np.inf)
    for d, vx, vy in ((dxx, sx, 0.0), (dyy, 0.0, sy), (d45, sx, sy), (d135, -sx, sy)):
        lift = p * vx + q * vy
        best = np.maximum(best, d / (sw * (vx * vx + vy * vy + lift * lift)))
    best *= 1.0 / _DIRECTIONAL_GAP
    return np.asarray(np.minimum(kappa, best), dtype=np.float64)


def max_principal_curvature(z: F64, sx: float, sy: float, *, smoothing: float = 0.0) -> F64:
    """Largest (concave-signed) principal curvature of the graph ``z = f(x, y)`` at every node.

    ``min(kappa_shape, kappa_dir / cos^2(22.5 deg))``: the largest eigenvalue
    of the shape operator from the central-difference Hessian, capped by the
    largest normal curvature measured directly along the four grid directions
    (x, y and both diagonals). On a smooth surface the cap never binds (the
    sampled directions are at most 22.5 deg from the principal one). Where
    the nine nodes are no quadric, e.g. a convex crease running diagonally,
    whose bilinear cells are saddles, the Hessian invents a concave direction
    that no line of nodes shows; the cap removes it.

    Parameters
    ----------
    z : (ny, nx) float64
        Node heights, rows along y; node ``(i, k)`` at ``(k*sx, i*sy)``.
    sx, sy : float
        Node spacing along x and y, > 0.
    smoothing : float
        Standard deviation in cells of a Gaussian applied first (0: none).

    Returns
    -------
    kappa : (ny, nx) float64
        In 1/mm; positive where the surface is concave (a valley in at least
        one direction), z up.
    """
    zz = _prepared(z, smoothing)
    out = np.empty_like(zz)
    for a, b, block in _row_blocks(zz, sx, sy):
        out[a:b] = block
    return out


def concave_curvature(z: F64, sx: float, sy: float, *, smoothing: float = 0.0) -> F64:
    """``max(kappa_max, 0)`` with curvatures below the rounding floor set to 0.

    Parameters
    ----------
    z : (ny, nx) float64
    sx, sy : float
    smoothing : float
        See :func:`max_principal_curvature`.

    Returns
    -------
    (ny, nx) float64
        Concave curvature in 1/mm, 0 where the surface is flat or convex.
    """
    k = max_principal_curvature(z, sx, sy, smoothing=smoothing)
    # Second differences of heights of magnitude |z| carry ~4 eps |z| / h^2 of
    # rounding; anything under a generous multiple of that is a plane.
    zmax = float(np.abs(z).max()) if z.size else 0.0
    floor = 64.0 * float(np.finfo(np.float64).eps) * max(zmax, 1.0) / min(sx, sy) ** 2
    k[k <= floor] = 0.0
    return k


def min_concave_radius(z: F64, sx: float, sy: float, *, smoothing: float = 0.0,
                       extent: tuple[int, int] | None = None) -> float:
    """Smallest concave radius of curvature of a bilinear grid.

    Parameters
    ----------
    z : (ny, nx) float64
    sx, sy : float
        Node spacing, > 0.
    smoothing : float
        See :func:`max_principal_curvature`.
    extent : (my, mx), optional
        Only nodes ``[:my, :mx]`` count (a padded level's nodes inside the input).

    Returns
    -------
    float
        ``1 / max(kappa_max)`` in mm, ``inf`` when nothing is concave.
    """
    zz = _prepared(z, smoothing)
    my, mx = zz.shape if extent is None else extent
    kmax = 0.0
    for a, b, k in _row_blocks(zz, sx, sy):
        if a < my and mx > 0:
            kmax = max(kmax, float(k[: min(b, my) - a, :mx].max()))
    # Same rounding floor as concave_curvature: below it the grid is a plane.
    zmax = float(np.abs(z).max()) if z.size else 0.0
    floor = 64.0 * float(np.finfo(np.float64).eps) * max(zmax, 1.0) / min(sx, sy) ** 2
    return float("inf") if kmax <= floor else 1.0 / kmax


def steepest_slope(z: F64, sx: float, sy: float,
                   extent: tuple[int, int] | None = None) -> float:
    """Steepest gradient magnitude ``tan(theta)`` of the bilinear surface.

    On a bilinear cell ``|grad f|^2`` is a convex function of position, so its
    maximum sits at a corner, where the gradient is made of the two cell edges
    meeting there. Exact for the bilinear model, no sampling.

    Parameters
    ----------
    z : (ny, nx) float64
    sx, sy : float
    extent : (cy, cx), optional
        Only cells ``[:cy, :cx]`` count (cells that touch the input's extent).

    Returns
    -------
    float
        ``max |grad f|`` over the surface (0 for a plane at constant height).
    """
    ny, nx = z.shape
    cy, cx = ny - 1, nx - 1  # cells
    if extent is not None:
        cy, cx = min(cy, extent[0]), min(cx, extent[1])
    if cy <= 0 or cx <= 0:
        return 0.0
    zz = z[: cy + 1, : cx + 1]
    best = 0.0
    # In blocks of cell rows (with the node row above each block), so a large
    # grid makes no full-size temporaries; every g is the same expression.
    rows = max(1, _BLOCK_NODES // max(cx + 1, 1))
    for a in range(0, cy, rows):
        b = min(a + rows, cy)
        blk = zz[a:b + 1]
        ex = np.abs(np.diff(blk, axis=1)) * (1.0 / sx)  # (rows+1, cx): x edges
        ey = np.abs(np.diff(blk, axis=0)) * (1.0 / sy)  # (rows, cx+1): y edges
        # The four corners of every cell: (bottom or top x edge) with (left
        # or right y edge).
        for bx in (ex[:-1], ex[1:]):  # bottom / top x edge of every cell
            for by in (ey[:, :-1], ey[:, 1:]):  # left / right y edge
                g = bx * bx + by * by
                best = max(best, float(g.max()))
    return float(np.sqrt(best))
