"""Numba kernels of the simulated stock (:mod:`zwcore.scanline._stock`).

Positions are ``(px, py)`` in mm from the grid's first node; node ``(i, k)`` sits at
``(k dx, i dy)``. The kernels visit, per position, the input nodes within ``r`` in blocks
of ``b x b`` nodes and skip a block whose maximum (``zmax``, ``smax``) cannot change the
answer. A node exactly ``r`` away counts as within (:data:`RIM`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = ["block_max", "blocks_diff_max", "blocks_lowered", "cl_part", "cut", "diff_max_p95",
           "disc_max", "in_region", "interpolate", "lift_nodes", "lower", "may_cut", "near_blocks",
           "node_index", "on_nodes", "points", "positive_max_mean", "raise_box",
           "top"]

F64 = NDArray[np.float64]

#: A node counts as within ``r`` of a position when ``d² <= r² RIM``: a node exactly ``r``
#: away (``(3, 4)`` spacings of 0.1 mm from a Ø1 ball's axis) is then within whatever the
#: rounding of ``k dx - p``, as in the whole-grid envelope (:mod:`zwcore.sim`) and
#: :func:`zwcore.scanline._stock_grid._half_widths`; heights use the exact ``r²``.
RIM = 1.0 + 1e-12


@njit(cache=True, nogil=True)
def _span(p: float, r: float, d: float, n: int) -> tuple[int, int]:
    """Node indices ``lo..hi`` (inclusive) within ``r`` of ``p`` along an axis."""
    lo = max(0, math.ceil((p - r) / d - 1e-9))
    hi = min(n - 1, math.floor((p + r) / d + 1e-9))
    return lo, hi
@njit(cache=True, nogil=True)
def _block_dist2(p: float, q: float, bi: int, bk: int, b: int, ny: int, nx: int,
                 dx: float, dy: float) -> float:
    """Squared xy distance from ``(p, q)`` (x, y in mm) to block ``(bi, bk)``'s nodes' box."""
    x0, x1 = bk * b * dx, (min(bk * b + b, nx) - 1) * dx
    y0, y1 = bi * b * dy, (min(bi * b + b, ny) - 1) * dy
    ex = max(0.0, x0 - p, p - x1)
    ey = max(0.0, y0 - q, q - y1)
    return ex * ex + ey * ey
@njit(cache=True, nogil=True)
def cl_part(z: F64, zmax: F64, b: int, px: F64, py: F64, cl0: F64, r: float, dx: float,
             dy: float) -> F64:
    """``max(cl0, max over nodes q within r of z[q] - h(|q - c|))`` per position (ball)."""
    ny, nx = z.shape
    r2, rin = r * r, r * r * RIM
    out = cl0.copy()
    for n in range(px.size):
        p, q = px[n], py[n]
        best = out[n]
        k0, k1 = _span(p, r, dx, nx)
        i0, i1 = _span(q, r, dy, ny)
        if k0 > k1 or i0 > i1:
            continue
        for bi in range(i0 // b, i1 // b + 1):
            for bk in range(k0 // b, k1 // b + 1):
                dm2 = _block_dist2(p, q, bi, bk, b, ny, nx, dx, dy)
                if dm2 > rin or zmax[bi, bk] - (r - math.sqrt(max(r2 - dm2, 0.0))) <= best:
                    continue
                for i in range(max(i0, bi * b), min(i1, bi * b + b - 1) + 1):
                    ey = i * dy - q
                    for k in range(max(k0, bk * b), min(k1, bk * b + b - 1) + 1):
                        ex = k * dx - p
                        d2 = ex * ex + ey * ey
                        if d2 <= rin:
                            v = z[i, k] - (r - math.sqrt(max(r2 - d2, 0.0)))
                            if v > best:
                                best = v
        out[n] = best
    return out
@njit(cache=True, nogil=True, inline="always")
def _sq(x: float) -> float:
    return x * x


@njit(cache=True, nogil=True)
def top(s: F64, smax: F64, b: int, px: F64, py: F64, r: float, dx: float,
         dy: float) -> F64:
    """Highest stock node within ``r`` of each position (-inf: none).

    The node nearest the axis is read first (a bound that skips most blocks at once),
    and per row of a block the nodes within ``r`` are one run (``d²`` grows with the
    distance along the row either way), found at its ends and read without a test each.
    """
    ny, nx = s.shape
    rin = r * r * RIM
    out = np.full(px.size, -np.inf)
    for n in range(px.size):
        p, q = px[n], py[n]
        best = -np.inf
        k0, k1 = _span(p, r, dx, nx)
        i0, i1 = _span(q, r, dy, ny)
        if k0 > k1 or i0 > i1:
            continue
        kc = min(max(round(p / dx), k0), k1)
        ic = min(max(round(q / dy), i0), i1)
        if _sq(kc * dx - p) + _sq(ic * dy - q) <= rin:
            best = s[ic, kc]
        for bi in range(i0 // b, i1 // b + 1):
            for bk in range(k0 // b, k1 // b + 1):
                if smax[bi, bk] <= best or _block_dist2(p, q, bi, bk, b, ny, nx, dx,
                                                        dy) > rin:
                    continue
                ka, kb = max(k0, bk * b), min(k1, bk * b + b - 1)
                for i in range(max(i0, bi * b), min(i1, bi * b + b - 1) + 1):
                    ey = i * dy - q
                    ey2 = ey * ey
                    lo, hi = ka, kb
                    while lo <= hi and _sq(lo * dx - p) + ey2 > rin:
                        lo += 1
                    while hi >= lo and _sq(hi * dx - p) + ey2 > rin:
                        hi -= 1
                    row = s[i]
                    for k in range(lo, hi + 1):
                        if row[k] > best:
                            best = row[k]
        out[n] = best
    return out


@njit(cache=True, nogil=True)
def cut(s: F64, smax: F64, b: int, px: F64, py: F64, cl: F64, r: float, dx: float,
        dy: float, touched: NDArray[np.bool_], skip: NDArray[np.bool_]) -> None:
    """``s = min(s, cl + h(|p - c|))`` at every node within ``r`` of each position, in place.

    ``smax`` is the block maximum of ``s`` before the pass: a block whose stock lies at or
    under the ball's lowest point over it is left alone, and so is a block ``skip``
    marks (settled already, :func:`zwcore.scanline._stock_bounds.settle`). ``touched``
    (blocks) is set where a node was lowered.
    """
    ny, nx = s.shape
    r2, rin = r * r, r * r * RIM
    for n in range(px.size):
        p, q, c = px[n], py[n], cl[n]
        k0, k1 = _span(p, r, dx, nx)
        i0, i1 = _span(q, r, dy, ny)
        if k0 > k1 or i0 > i1:
            continue
        for bi in range(i0 // b, i1 // b + 1):
            for bk in range(k0 // b, k1 // b + 1):
                if skip[bi, bk]:
                    continue
                dm2 = _block_dist2(p, q, bi, bk, b, ny, nx, dx, dy)
                if dm2 > rin or smax[bi, bk] <= c + (r - math.sqrt(max(r2 - dm2, 0.0))):
                    continue
                for i in range(max(i0, bi * b), min(i1, bi * b + b - 1) + 1):
                    ey = i * dy - q
                    for k in range(max(k0, bk * b), min(k1, bk * b + b - 1) + 1):
                        ex = k * dx - p
                        d2 = ex * ex + ey * ey
                        if d2 <= rin:
                            v = c + (r - math.sqrt(max(r2 - d2, 0.0)))
                            if v < s[i, k]:
                                s[i, k] = v
                                touched[bi, bk] = True
@njit(cache=True, nogil=True)
def interpolate(grid: F64, isx: float, isy: float, px: F64, py: F64) -> F64:
    my, mx = grid.shape
    out = np.empty(px.size)
    for n in range(px.size):
        fx, fy = px[n] * isx, py[n] * isy
        c0 = min(max(math.floor(fx), 0), max(mx - 2, 0))
        r0 = min(max(math.floor(fy), 0), max(my - 2, 0))
        c1, r1 = min(c0 + 1, mx - 1), min(r0 + 1, my - 1)
        tx = min(max(fx - c0, 0.0), 1.0)
        ty = min(max(fy - r0, 0.0), 1.0)
        lo = grid[r0, c0] * (1.0 - tx) + grid[r0, c1] * tx
        hi = grid[r1, c0] * (1.0 - tx) + grid[r1, c1] * tx
        out[n] = lo * (1.0 - ty) + hi * ty
    return out


@njit(cache=True, nogil=True)
def in_region(px: F64, py: F64, region: NDArray[np.bool_], sx: float,
              sy: float) -> NDArray[np.bool_]:
    """Positions whose nearest node of spacing ``sx, sy`` (clamped to ``region``'s shape)
    is in ``region``: ``region[rint(y / sy), rint(x / sx)]``, without the index arrays."""
    my, mx = region.shape
    out = np.empty(px.size, dtype=np.bool_)
    for n in range(px.size):
        c = min(max(int(np.rint(px[n] / sx)), 0), mx - 1)
        r = min(max(int(np.rint(py[n] / sy)), 0), my - 1)
        out[n] = region[r, c]
    return out


@njit(cache=True, nogil=True)
def may_cut(grown: F64, b: int, px: F64, py: F64, cl: F64, idx: float,
             idy: float) -> NDArray[np.bool_]:
    """Positions whose CL lies under the highest stock its ball may reach (block bound)."""
    my, mx = grown.shape
    out = np.empty(px.size, dtype=np.bool_)
    for n in range(px.size):
        bi = min(max(round(py[n] * idy) // b, 0), my - 1)
        bk = min(max(round(px[n] * idx) // b, 0), mx - 1)
        out[n] = grown[bi, bk] > cl[n]
    return out
@njit(cache=True, nogil=True)
def _slide_max(s: F64, w: int, out: F64) -> None:
    """``out[i, k] = max(s[i, k-w..k+w])`` (clamped to the row), by the van Herk /
    Gil-Werman scheme: the row padded with ``w`` -inf each side, per block of
    ``W = 2w+1`` a running maximum from its start (``g``) and from its end (``h``); every
    window is one block's tail and the next block's head, ``max(h[k], g[k + 2w])``:
    three operations per node whatever ``w``."""
    ny, nx = s.shape
    big_w = 2 * w + 1
    m = nx + 2 * w
    p = np.empty(m)
    g = np.empty(m)
    h = np.empty(m)
    for i in range(ny):
        for j in range(m):
            p[j] = s[i, j - w] if w <= j < w + nx else -np.inf
        for j in range(m):
            g[j] = p[j] if j % big_w == 0 else max(g[j - 1], p[j])
        for j in range(m - 1, -1, -1):
            h[j] = p[j] if (j % big_w == big_w - 1 or j == m - 1) else max(h[j + 1], p[j])
        for k in range(nx):
            out[i, k] = max(h[k], g[k + 2 * w])


@njit(cache=True, nogil=True)
def disc_max(s: F64, widths: NDArray[np.int64]) -> F64:
    """Highest ``s`` within the disc of half-widths ``widths`` (per row offset ``a = 0..A``,
    -1: none) of every node: per distinct width a sliding maximum along the rows
    (:func:`_slide_max`), then its rows shifted by each offset with that width folded
    into the result."""
    ny, nx = s.shape
    out = np.full((ny, nx), -np.inf)
    slide = np.empty((ny, nx))
    a_max = widths.size - 1
    done = np.zeros(widths[0] + 2, dtype=np.bool_)
    for w0 in widths:
        if w0 < 0 or done[w0]:
            continue
        done[w0] = True
        _slide_max(s, w0, slide)
        for a in range(-a_max, a_max + 1):
            if widths[abs(a)] != w0:
                continue
            for i in range(max(0, -a), min(ny, ny - a)):
                ii = i + a
                for k in range(nx):
                    if slide[ii, k] > out[i, k]:
                        out[i, k] = slide[ii, k]
    return out


@njit(cache=True, nogil=True)
def on_nodes(px: F64, py: F64, isx: float, isy: float) -> NDArray[np.bool_]:
    """Positions on a node of spacing ``1/isx, 1/isy`` (to 1e-9 of the spacing)."""
    out = np.empty(px.size, dtype=np.bool_)
    for n in range(px.size):
        fx, fy = px[n] * isx, py[n] * isy
        out[n] = abs(fx - round(fx)) <= 1e-9 and abs(fy - round(fy)) <= 1e-9
    return out


@njit(cache=True, nogil=True)
def points(offset: F64, start: F64, stop: F64, step: float) -> tuple[F64, F64]:
    """Points ``(u along, v across)`` of segments: each start, the multiples of ``step``
    strictly inside, each stop (when longer than a point)."""
    n = 0
    for j in range(offset.size):
        a, b = start[j], stop[j]
        n += 1
        if b > a:
            lo = math.ceil(a / step - 1e-9)
            hi = math.floor(b / step + 1e-9)
            for m in range(lo, hi + 1):
                if a < m * step < b:
                    n += 1
            n += 1
    u = np.empty(n)
    v = np.empty(n)
    n = 0
    for j in range(offset.size):
        a, b = start[j], stop[j]
        u[n], v[n] = a, offset[j]
        n += 1
        if b > a:
            lo = math.ceil(a / step - 1e-9)
            hi = math.floor(b / step + 1e-9)
            for m in range(lo, hi + 1):
                t = m * step
                if a < t < b:
                    u[n], v[n] = t, offset[j]
                    n += 1
            u[n], v[n] = b, offset[j]
            n += 1
    return u, v


@njit(cache=True, nogil=True)
def raise_box(model: F64, sx: float, sy: float, px: F64, py: F64, need: F64,
              half: float) -> int:
    """Raise every model node within ``half`` (each axis) of each position to its
    ``need``; returns the number of distinct nodes raised."""
    my, mx = model.shape
    raised = np.zeros((my, mx), dtype=np.bool_)
    count = 0
    for n in range(px.size):
        c0 = max(math.floor((px[n] - half) / sx), 0)
        c1 = min(math.ceil((px[n] + half) / sx), mx - 1)
        r0 = max(math.floor((py[n] - half) / sy), 0)
        r1 = min(math.ceil((py[n] + half) / sy), my - 1)
        for r in range(r0, r1 + 1):
            for c in range(c0, c1 + 1):
                if model[r, c] < need[n]:
                    model[r, c] = need[n]
                    if not raised[r, c]:
                        raised[r, c] = True
                        count += 1
    return count


@njit(cache=True, nogil=True)
def lower(s: F64, env: F64, b: int, touched: NDArray[np.bool_]) -> None:
    """``s = min(s, env)`` in place; ``touched[i // b, k // b]`` set where a node was lowered."""
    ny, nx = s.shape
    for i in range(ny):
        for k in range(nx):
            if env[i, k] < s[i, k]:
                s[i, k] = env[i, k]
                touched[i // b, k // b] = True


@njit(cache=True, nogil=True)
def near_blocks(grown: F64, b: int, px: F64, py: F64, top: F64, base: F64, idx: float,
                idy: float) -> NDArray[np.intp]:
    """Indices of the positions with ``top > base`` whose block has ``grown > 0``."""
    my, mx = grown.shape
    out = np.empty(px.size, dtype=np.intp)
    n = 0
    for j in range(px.size):
        if not top[j] > base[j]:
            continue
        bi = min(max(round(py[j] * idy) // b, 0), my - 1)
        bk = min(max(round(px[j] * idx) // b, 0), mx - 1)
        if grown[bi, bk] > 0.0:
            out[n] = j
            n += 1
    return out[:n]


@njit(cache=True, nogil=True)
def block_max(z: F64, b: int) -> F64:
    """``(ceil(ny/b), ceil(nx/b))``: the largest value of every ``b x b`` block."""
    ny, nx = z.shape
    my, mx = -(-ny // b), -(-nx // b)
    out = np.full((my, mx), -np.inf)
    for i in range(ny):
        row = out[i // b]
        for bk in range(mx):
            m = row[bk]
            for k in range(bk * b, min(bk * b + b, nx)):
                m = max(m, z[i, k])
            row[bk] = m
    return out


@njit(cache=True, nogil=True)
def blocks_diff_max(a: F64, s: F64, touched: NDArray[np.bool_], b: int) -> float:
    """``max(a - s)`` over the nodes of the ``touched`` blocks (-inf: none)."""
    ny, nx = a.shape
    best = -np.inf
    for bi in range(touched.shape[0]):
        for bk in range(touched.shape[1]):
            if not touched[bi, bk]:
                continue
            for i in range(bi * b, min(bi * b + b, ny)):
                for k in range(bk * b, min(bk * b + b, nx)):
                    d = a[i, k] - s[i, k]
                    if d > best:
                        best = d
    return best


@njit(cache=True, nogil=True)
def blocks_lowered(s: F64, before: F64, touched: NDArray[np.bool_], b: int,
                   guard: float) -> int:
    """Nodes of the ``touched`` blocks with ``s < before - guard``."""
    ny, nx = s.shape
    n = 0
    for bi in range(touched.shape[0]):
        for bk in range(touched.shape[1]):
            if not touched[bi, bk]:
                continue
            for i in range(bi * b, min(bi * b + b, ny)):
                for k in range(bk * b, min(bk * b + b, nx)):
                    if s[i, k] < before[i, k] - guard:
                        n += 1
    return n


@njit(cache=True, nogil=True)
def diff_max_p95(a: F64, s: F64) -> tuple[float, float]:
    """Largest and 95th percentile (numpy's linear method) of ``a - s``, without the
    difference as an array: a histogram of 65536 bins finds the bins of the two order
    statistics, whose values alone are sorted."""
    fa, fs = a.ravel(), s.ravel()
    n = fa.size
    lo_v, hi_v = np.inf, -np.inf
    for j in range(n):
        d = fa[j] - fs[j]
        lo_v = min(lo_v, d)
        hi_v = max(hi_v, d)
    if n == 1 or not hi_v > lo_v:
        return hi_v, hi_v
    nb = 65536
    scale = nb / (hi_v - lo_v)
    counts = np.zeros(nb, dtype=np.int64)
    for j in range(n):
        counts[min(int(((fa[j] - fs[j]) - lo_v) * scale), nb - 1)] += 1
    virtual = 0.95 * (n - 1)
    r0 = math.floor(virtual)
    r1 = min(r0 + 1, n - 1)
    t = virtual - r0
    below, b0 = 0, 0  # b0: bin holding rank r0; below: ranks before it
    while below + counts[b0] <= r0:
        below += counts[b0]
        b0 += 1
    b1 = b0
    upto = below + counts[b0]
    while upto <= r1:
        b1 += 1
        upto += counts[b1]
    vals = np.empty(upto - below)
    m = 0
    for j in range(n):
        d = fa[j] - fs[j]
        k = min(int((d - lo_v) * scale), nb - 1)
        if b0 <= k <= b1:
            vals[m] = d
            m += 1
    vals.sort()
    x0, x1 = vals[r0 - below], vals[r1 - below]
    diff = x1 - x0
    p95 = x1 - diff * (1.0 - t) if t >= 0.5 else x0 + diff * t
    return hi_v, p95


@njit(cache=True, nogil=True)
def lift_nodes(model: F64, isx: float, isy: float, px: F64, py: F64, need: F64,
               on: NDArray[np.bool_]) -> int:
    """Raise to ``need``: the node under each position ``on`` a node, else every corner
    that carries weight in the bilinear value there (a position on a grid line leaves the
    other row of its cell alone). Returns the number of distinct nodes raised."""
    my, mx = model.shape
    raised = np.empty(4 * px.size, dtype=np.int64)
    m = 0
    for n in range(px.size):
        fx, fy = px[n] * isx, py[n] * isy
        if on[n]:
            r, c = min(max(round(fy), 0), my - 1), min(max(round(fx), 0), mx - 1)
            if model[r, c] < need[n]:
                model[r, c] = need[n]
                raised[m] = r * mx + c
                m += 1
            continue
        c0 = min(max(math.floor(fx), 0), max(mx - 2, 0))
        r0 = min(max(math.floor(fy), 0), max(my - 2, 0))
        tx, ty = fx - c0, fy - r0
        for r in (r0, min(r0 + 1, my - 1)):
            if (r != r0 and ty <= 0.0) or (r == r0 and r0 + 1 < my and ty >= 1.0):
                continue
            for c in (c0, min(c0 + 1, mx - 1)):
                if (c != c0 and tx <= 0.0) or (c == c0 and c0 + 1 < mx and tx >= 1.0):
                    continue
                if model[r, c] < need[n]:
                    model[r, c] = need[n]
                    raised[m] = r * mx + c
                    m += 1
    return np.unique(raised[:m]).size


@njit(cache=True, nogil=True)
def positive_max_mean(d: F64) -> tuple[float, float]:
    """``max(d, 0)`` and the mean of the positive values (0 without any)."""
    best, total, n = 0.0, 0.0, 0
    for j in range(d.size):
        v = d[j]
        if v > 0.0:
            total += v
            n += 1
            if v > best:
                best = v
    return best, (total / n if n else 0.0)


@njit(cache=True, nogil=True)
def node_index(px: F64, py: F64, isx: float, isy: float,
               ) -> tuple[NDArray[np.bool_], NDArray[np.intp], NDArray[np.intp]]:
    """:func:`on_nodes`, and the row and column of the positions on a node."""
    on = np.empty(px.size, dtype=np.bool_)
    rows = np.empty(px.size, dtype=np.intp)
    cols = np.empty(px.size, dtype=np.intp)
    m = 0
    for n in range(px.size):
        fx, fy = px[n] * isx, py[n] * isy
        rx, ry = round(fx), round(fy)
        on[n] = abs(fx - rx) <= 1e-9 and abs(fy - ry) <= 1e-9
        if on[n]:
            rows[m], cols[m] = ry, rx
            m += 1
    return on, rows[:m], cols[:m]
