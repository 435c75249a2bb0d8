"""Triangle meshes to z-maps: STL parsing and a vectorised z-buffer.

The z-map of a part seen from +z holds, at each node, the highest surface
point straight above it. :func:`rasterise` computes it as a z-buffer of the
triangles by scan conversion: every (triangle, grid row) pair gets the span of
columns the triangle covers on that row, every (triangle, node) pair in a span
the height of the triangle's plane there, and a scatter maximum keeps the
highest per node. Work and memory are proportional to the nodes the triangles
cover (plus one entry per triangle and row), never to triangles x nodes, and
there is no Python loop over triangles or nodes: chunks of pairs are numpy
array operations.
"""

from __future__ import annotations

import io
import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from zwcore.errors import InvalidInputError, LimitExceededError
from zwcore.grid.zmap import MAX_ABS_HEIGHT

__all__ = ["MeshZMap", "ZMapGrid", "rasterise", "read_stl", "zmap_grid"]

#: Node positions within this fraction of a cell of a triangle edge count as
#: inside it, so a node on an edge shared by two triangles, or on the part's
#: outline (node (0, 0) sits on the mesh's lower-left corner), is never lost to
#: rounding.
EDGE_SLACK = 1e-7

#: (triangle, node) pairs computed per chunk: ~100 MB of temporaries.
CHUNK_PAIRS = 1 << 21


def read_stl(data: bytes, field: str = "stl") -> NDArray[np.float64]:
    """Parse a binary or ASCII STL file.

    Parameters
    ----------
    data : bytes
        The whole file.
    field : str
        Name used in errors.

    Returns
    -------
    triangles : (n, 3, 3) float64
        Vertex ``j`` of triangle ``t`` at ``triangles[t, j] = (x, y, z)``, mm.

    Raises
    ------
    InvalidInputError
        Not an STL file, a truncated one, no triangles, non-finite or out-of-range
        coordinates.
    """
    from stl import mesh as stl_mesh  # numpy-stl; imported here: only this reader needs it

    if not data:
        raise InvalidInputError(field, "the STL file is empty")
    try:
        parsed = stl_mesh.Mesh.from_file("upload.stl", fh=io.BytesIO(data), calculate_normals=False)
    except (ValueError, AssertionError, RuntimeError, TypeError, IndexError,
            UnicodeDecodeError) as exc:
        raise InvalidInputError(field, f"not a readable binary or ASCII STL file ({exc})") from None
    triangles = np.asarray(parsed.vectors, dtype=np.float64).reshape(-1, 3, 3)
    if len(triangles) == 0:
        raise InvalidInputError(field, "holds no triangles (truncated, empty or not an STL file)")
    bad = ~np.isfinite(triangles).all(axis=(1, 2))
    if bad.any():
        t = int(np.argmax(bad))
        raise InvalidInputError(field, f"triangle {t} has a non-finite vertex coordinate "
                                f"(NaN or infinity); {int(bad.sum())} such triangle(s)")
    big = (np.abs(triangles) > MAX_ABS_HEIGHT).any(axis=(1, 2))
    if big.any():
        raise InvalidInputError(field, f"triangle {int(np.argmax(big))} has a coordinate beyond "
                                f"±{MAX_ABS_HEIGHT:g} mm")
    return triangles


@dataclass(frozen=True)
class ZMapGrid:
    """Node layout of a z-map: node ``(k, i)`` at ``(x0 + k*dx, y0 + i*dy)``."""

    x0: float
    y0: float
    dx: float
    dy: float
    nx: int
    ny: int


def zmap_grid(triangles: NDArray[np.float64], *, dx: float | None = None, dy: float | None = None,
              nx: int | None = None, ny: int | None = None, x0: float | None = None,
              y0: float | None = None, max_cells: int | None = None) -> ZMapGrid:
    """Place a grid over a mesh: by cell size (``dx``, ``dy`` default ``dx``) or by node
    count (``nx`` and ``ny``), from ``(x0, y0)`` (default: the mesh's lower-left corner)
    to the mesh's upper-right corner.

    With a cell size the last node is the last one not beyond the mesh (so the mesh's
    lower-left corner is node (0, 0) and spacing is exact); with node counts the
    spacing is chosen so the last node sits on the corner.

    Raises
    ------
    InvalidInputError
        Neither or both of cell size and node counts, an origin beyond the mesh.
    LimitExceededError
        More than ``max_cells`` nodes (the field named is ``dx`` or ``nx``).
    """
    pts = triangles.reshape(-1, 3)
    lo, hi = pts[:, :2].min(axis=0), pts[:, :2].max(axis=0)
    gx0 = float(lo[0]) if x0 is None else float(x0)
    gy0 = float(lo[1]) if y0 is None else float(y0)
    if gx0 > hi[0] or gy0 > hi[1]:
        field = "x0" if gx0 > hi[0] else "y0"
        raise InvalidInputError(field, f"origin ({gx0:g}, {gy0:g}) lies beyond the mesh's "
                                f"upper-right corner ({hi[0]:g}, {hi[1]:g})")
    span_x, span_y = float(hi[0]) - gx0, float(hi[1]) - gy0
    by_size = dx is not None or dy is not None
    by_count = nx is not None or ny is not None
    if by_size == by_count:
        raise InvalidInputError("dx", "give a cell size (dx, optional dy) or a shape "
                                "(nx and ny), not both and not neither")
    if by_size:
        if dx is None:
            raise InvalidInputError("dx", "required when dy is given")
        sx, sy = float(dx), float(dy if dy is not None else dx)
        # floor with a little slack: 85.82 mm at 0.1 mm is 859 nodes, not 858
        cols = math.floor(span_x / sx * (1 + 1e-12) + 1e-9) + 1
        rows = math.floor(span_y / sy * (1 + 1e-12) + 1e-9) + 1
        if max_cells is not None and cols * rows > max_cells:
            raise LimitExceededError("dx", f"cell size {sx:g} x {sy:g} mm over {span_x:g} x "
                                     f"{span_y:g} mm gives {rows} x {cols} nodes, more than "
                                     f"the limit of {max_cells}")
        return ZMapGrid(gx0, gy0, sx, sy, max(cols, 2), max(rows, 2))
    if nx is None or ny is None:
        raise InvalidInputError("nx" if nx is None else "ny", "nx and ny go together")
    if max_cells is not None and nx * ny > max_cells:
        raise LimitExceededError("nx", f"{ny} x {nx} nodes exceed the limit of {max_cells}")
    if span_x <= 0 or span_y <= 0:
        raise InvalidInputError("nx", "the mesh has no extent in x or y to spread nodes over")
    return ZMapGrid(gx0, gy0, span_x / (nx - 1), span_y / (ny - 1), int(nx), int(ny))


@dataclass(frozen=True)
class MeshZMap:
    """A rasterised mesh.

    Attributes
    ----------
    z : (ny, nx) float64
        Highest surface point above each node; ``background`` where none.
    covered : (ny, nx) bool
        Nodes some triangle lies above.
    undercut : (ny, nx) bool
        Nodes whose vertical line meets the mesh at three or more distinct heights:
        a surface hides under the top one (the bottom of a closed part is not
        counted), which the z-map cannot show.
    background : float
        Height given to the nodes outside the part.
    triangles_used : int
        Triangles with a non-zero footprint in the xy-plane (vertical ones add nothing).
    """

    z: NDArray[np.float64]
    covered: NDArray[np.bool_]
    undercut: NDArray[np.bool_]
    background: float
    triangles_used: int


def _planes(tri: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64],
                                                 NDArray[np.float64], NDArray[np.float64]]:
    """Coefficients of ``z = a*x + b*y + c`` per triangle and twice its signed area in
    the xy-plane (the normal's z by the winding)."""
    p0, p1, p2 = tri[:, 0], tri[:, 1], tri[:, 2]
    n = np.cross(p1 - p0, p2 - p0)
    with np.errstate(divide="ignore", invalid="ignore"):  # vertical ones are dropped
        a = -n[:, 0] / n[:, 2]
        b = -n[:, 1] / n[:, 2]
        c = p0[:, 2] - a * p0[:, 0] - b * p0[:, 1]
    return a, b, c, n[:, 2]


def _row_spans(tri: NDArray[np.float64], rows_y: NDArray[np.floating], slack_y: float,
               slack_x: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """x-interval of each triangle (one per pair) on the horizontal line ``y``.

    ``tri`` is (m, 3, 3) repeated per pair, ``rows_y`` (m,). Every non-horizontal
    edge whose y-range holds ``y`` (within ``slack_y``) gives its crossing (a
    horizontal edge's ends are its neighbours' ends). Returns (xlo, xhi), widened by
    ``slack_x``; xlo > xhi when the line misses the triangle.
    """
    xlo = np.full(len(rows_y), np.inf)
    xhi = np.full(len(rows_y), -np.inf)
    for j in range(3):  # the three edges, not a loop over triangles
        p, q = tri[:, j], tri[:, (j + 1) % 3]
        ey = q[:, 1] - p[:, 1]
        ok = ((rows_y >= np.minimum(p[:, 1], q[:, 1]) - slack_y)
              & (rows_y <= np.maximum(p[:, 1], q[:, 1]) + slack_y) & (ey != 0))
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.clip((rows_y - p[:, 1]) / np.where(ey != 0, ey, 1.0), 0.0, 1.0)
        x = p[:, 0] + t * (q[:, 0] - p[:, 0])
        xlo = np.where(ok, np.minimum(xlo, x), xlo)
        xhi = np.where(ok, np.maximum(xhi, x), xhi)
    return xlo - slack_x, xhi + slack_x


def _ranges(starts: NDArray[np.int64], counts: NDArray[np.int64]) -> tuple[
        NDArray[np.int64], NDArray[np.int64]]:
    """For each i, ``starts[i] + arange(counts[i])``, concatenated, and the owner index."""
    owner = np.repeat(np.arange(len(counts)), counts)
    first = np.cumsum(counts) - counts
    offset = np.arange(int(counts.sum()), dtype=np.int64) - np.repeat(first, counts)
    return starts[owner] + offset, owner


def _chunks(weights: NDArray[np.int64], budget: int) -> list[slice]:
    """Consecutive slices whose weights add up to about ``budget`` (at least one item)."""
    ends = np.cumsum(weights)
    out, start, base = [], 0, 0
    while start < len(weights):
        stop = int(np.searchsorted(ends, base + budget, side="right"))
        stop = max(stop, start + 1)
        out.append(slice(start, stop))
        base = int(ends[stop - 1])
        start = stop
    return out


def rasterise(triangles: NDArray[np.float64], grid: ZMapGrid, background: float | None = None,
              max_pairs: int | None = None) -> MeshZMap:
    """Z-buffer of a triangle mesh on a grid: the highest surface point above each node.

    Parameters
    ----------
    triangles : (n, 3, 3) float64
        Vertices, mm (finite: see :func:`read_stl`).
    grid : ZMapGrid
        Where the nodes are.
    background : float, optional
        Height of nodes no triangle lies above; default the mesh's lowest point.
    max_pairs : int, optional
        Refuse a mesh whose triangles cover more (triangle, node) pairs than this
        (depth complexity times nodes): the work bound.

    Returns
    -------
    MeshZMap

    Raises
    ------
    LimitExceededError
        The mesh covers more than ``max_pairs`` (triangle, node) pairs.
    """
    tri = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    bg = float(tri[:, :, 2].min()) if background is None else float(background)
    a, b, c, nz = _planes(tri) if len(tri) else (np.empty(0),) * 4
    # Vertical (or sliver) triangles have no footprint: the edges of their neighbours
    # carry the wall's top, the node slack the rest.
    area_scale = np.abs(tri[:, :, :2]).max(axis=(1, 2)) ** 2 + grid.dx * grid.dy
    keep = np.abs(nz) > 1e-12 * area_scale
    tri, a, b, c, nz = tri[keep], a[keep], b[keep], c[keep], nz[keep]

    # Rows each triangle spans (with slack, so shared edges and the outline keep their nodes).
    ys = (tri[:, :, 1] - grid.y0) / grid.dy
    i0 = np.maximum(np.ceil(ys.min(axis=1) - EDGE_SLACK), 0).astype(np.int64)
    i1 = np.minimum(np.floor(ys.max(axis=1) + EDGE_SLACK), grid.ny - 1).astype(np.int64)
    nrows = np.maximum(i1 - i0 + 1, 0)
    xs = (tri[:, :, 0] - grid.x0) / grid.dx
    ncols_box = np.maximum(np.minimum(np.floor(xs.max(axis=1) + EDGE_SLACK), grid.nx - 1)
                           - np.maximum(np.ceil(xs.min(axis=1) - EDGE_SLACK), 0) + 1, 0)
    if max_pairs is not None:
        # bounding boxes bound the pairs from above; refuse before any expansion
        box = float(np.sum(nrows * ncols_box.astype(np.float64)))
        if box > max_pairs and _exact_pairs(tri, i0, nrows, grid) > max_pairs:
            raise LimitExceededError(
                "stl", f"the triangles cover more than {max_pairs} (triangle, node) pairs on "
                f"this grid (overlapping large triangles); use a coarser cell size")

    mesh = _Footprints(tri, a, b, c, i0, nrows, np.maximum(ncols_box, 1).astype(np.int64))
    size = grid.nx * grid.ny
    top = np.full(size, -np.inf)
    bottom = np.full(size, np.inf)
    for node, zp in mesh.hits(grid):
        np.maximum.at(top, node, zp)
        np.minimum.at(bottom, node, zp)
    covered = np.isfinite(top)
    z = np.where(covered, top, bg).reshape(grid.ny, grid.nx)
    return MeshZMap(z, covered.reshape(z.shape), _undercut(mesh, grid, top, bottom),
                    bg, len(tri))


class _Footprints:
    """Triangles with their planes and the grid rows they span, ready to scan-convert."""

    def __init__(self, tri: NDArray[np.float64], a: NDArray[np.float64], b: NDArray[np.float64],
                 c: NDArray[np.float64], i0: NDArray[np.int64], nrows: NDArray[np.int64],
                 ncols: NDArray[np.int64]) -> None:
        self.tri, self.a, self.b, self.c = tri, a, b, c
        self.zlo, self.zhi = tri[:, :, 2].min(axis=1), tri[:, :, 2].max(axis=1)
        self.i0, self.nrows, self.ncols = i0, nrows, ncols

    def hits(self, grid: ZMapGrid, which: NDArray[np.int64] | None = None
             ) -> Iterator[tuple[NDArray[np.int64], NDArray[np.float64]]]:
        """(flat node index, height) of every (triangle, node) pair, in chunks; only the
        triangles ``which`` when given."""
        which = np.arange(len(self.tri)) if which is None else which
        for part in _chunks(np.maximum(self.nrows[which] * self.ncols[which], 1), CHUNK_PAIRS):
            tw = which[part]
            rows, owner = _ranges(self.i0[tw], self.nrows[tw])
            t = tw[owner]
            y = grid.y0 + rows * grid.dy
            xlo, xhi = _row_spans(self.tri[t], y, EDGE_SLACK * grid.dy, EDGE_SLACK * grid.dx)
            k0 = np.maximum(np.ceil((xlo - grid.x0) / grid.dx), 0).astype(np.int64)
            k1 = np.minimum(np.floor((xhi - grid.x0) / grid.dx), grid.nx - 1).astype(np.int64)
            cols, pair = _ranges(k0, np.maximum(k1 - k0 + 1, 0))
            tp = t[pair]
            # the plane clipped to the triangle's own heights: slack nodes never extrapolate
            zp = np.clip(self.a[tp] * (grid.x0 + cols * grid.dx) + self.b[tp] * y[pair]
                         + self.c[tp], self.zlo[tp], self.zhi[tp])
            yield rows[pair] * grid.nx + cols, zp


def _undercut(mesh: _Footprints, grid: ZMapGrid, top: NDArray[np.float64],
              bottom: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Nodes whose vertical line meets the mesh at three or more distinct heights.

    Orientation-free (STL windings are often inconsistent): a closed part meets the
    line at its top and its bottom, an open relief at one height; a third height is
    a surface hidden under another (an overhang, a cavity, a fold). A second pass
    scans only the triangles over nodes with two heights or more. Faces inside the
    material count too: two bodies that touch without being merged (a boss standing
    on a block as two shells) report the contact face, a conservative warning.
    """
    zr = float(np.ptp(mesh.tri[:, :, 2])) if len(mesh.tri) else 0.0
    tol = 1e-6 * max(zr, 1.0)
    spread = np.isfinite(top) & (top - bottom > 2 * tol)
    out = np.zeros(grid.ny * grid.nx, dtype=bool)
    if not spread.any():
        return out.reshape(grid.ny, grid.nx)
    # A summed-area table answers "any such node under this triangle's box?" per triangle.
    sat = np.zeros((grid.ny + 1, grid.nx + 1), dtype=np.int64)
    sat[1:, 1:] = spread.reshape(grid.ny, grid.nx).cumsum(0).cumsum(1)
    xs = (mesh.tri[:, :, 0] - grid.x0) / grid.dx
    k0 = np.clip(np.ceil(xs.min(axis=1) - EDGE_SLACK), 0, grid.nx).astype(np.int64)
    k1 = np.clip(np.floor(xs.max(axis=1) + EDGE_SLACK) + 1, 0, grid.nx).astype(np.int64)
    r0 = np.clip(mesh.i0, 0, grid.ny)
    r1 = np.clip(mesh.i0 + mesh.nrows, 0, grid.ny)
    k1, r1 = np.maximum(k1, k0), np.maximum(r1, r0)
    count = sat[r1, k1] - sat[r0, k1] - sat[r1, k0] + sat[r0, k0]
    for node, zp in mesh.hits(grid, np.flatnonzero(count > 0)):
        between = (zp > bottom[node] + tol) & (zp < top[node] - tol)
        out[node[between]] = True
    return out.reshape(grid.ny, grid.nx)


def _exact_pairs(tri: NDArray[np.float64], i0: NDArray[np.int64], nrows: NDArray[np.int64],
                 grid: ZMapGrid) -> float:
    """(triangle, node) pairs the scan conversion would make, counted without making them
    (rows are counted first: a refusal must not cost what it refuses)."""
    if float(nrows.sum()) > 64 * (grid.nx * grid.ny + len(tri)):
        return math.inf
    total = 0.0
    for part in _chunks(np.maximum(nrows, 1), CHUNK_PAIRS):
        rows, owner = _ranges(i0[part], nrows[part])
        t = owner + part.start
        xlo, xhi = _row_spans(tri[t], grid.y0 + rows * grid.dy, EDGE_SLACK * grid.dy,
                                EDGE_SLACK * grid.dx)
        k0 = np.maximum(np.ceil((xlo - grid.x0) / grid.dx), 0)
        k1 = np.minimum(np.floor((xhi - grid.x0) / grid.dx), grid.nx - 1)
        total += float(np.maximum(k1 - k0 + 1, 0).sum())
    return total
