"""Ball reach against a z-map's nodes: drop-cutter and closing by branch and bound.

The *nodal* meaning: the part is its node samples, a ball position is a node ``c``
with its tip at ``CL(c) = max over nodes q with |q - c| <= R of z(q) - h(|q - c|)``
(``h(d) = R - sqrt(R² - d²)``, the ball above its tip), and the ball leaves at
node ``p`` the closing ``min over positions c with |p - c| <= R of CL(c) + h(|p - c|)``.
That is what the tool-path layer sweeps (tools against the part's nodes), and it
gives the known answers (an R 8 ball centred on an R 8 spherical pocket reaches
every node), where the bilinear interpolant's rim chords would hold it 0.5 mm up.

Both are computed exactly (to float rounding) by branch and bound over a pyramid
of block extremes: a block of ``2^l x 2^l`` nodes bounds ``z(q) - h`` from above by
its largest height less ``h`` at its nearest point (``CL``), and ``CL + h`` from
below by its smallest ``CL`` plus ``h`` at its nearest point (closing). Blocks that
cannot beat the best value found so far are skipped; each query starts from its
neighbour's answer (contact node or best position), which is usually already the
answer, so a query visits a few dozen blocks whatever the ball's footprint (a Ø20
ball at 0.1 mm spans 31,000 nodes). Queries run only at the nodes asked for.

The kernels are compiled (or loaded from numba's cache) when this module is imported,
not at the first plan: loading holds the interpreter lock for a good fraction of a
second, which a service must not spend while it answers requests.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

__all__ = ["nodal_closing", "nodal_drop_cutter", "pyramid"]

#: Entries of a query's block stack (top blocks plus four per level per branch).
_STACK = 4096


def _plain(a: NDArray[np.floating]) -> F64:
    """``a`` as a writable C-ordered float64 array (the kernels' signatures; a read-only
    input, a stored grid say, is copied)."""
    return np.require(a, dtype=np.float64, requirements=["C", "W"])


def pyramid(z: F64, levels: int, high: bool) -> tuple[F64, I64]:
    """Block maxima (``high``) or minima of ``z`` over ``2^l x 2^l`` blocks, l = 0..levels.

    Returns
    -------
    flat : (n,) float64
        All levels one after the other, row-major.
    meta : (levels + 1, 3) int64
        Offset, rows and columns of each level in ``flat``.
    """
    fill = -np.inf if high else np.inf
    pick = np.maximum if high else np.minimum
    parts = [np.ascontiguousarray(z, dtype=np.float64)]
    for _ in range(levels):
        a = parts[-1]
        ny, nx = a.shape
        py, px = ny + (ny & 1), nx + (nx & 1)
        b = np.full((py, px), fill)
        b[:ny, :nx] = a
        parts.append(pick(pick(b[0::2, 0::2], b[0::2, 1::2]), pick(b[1::2, 0::2], b[1::2, 1::2])))
    meta = np.zeros((levels + 1, 3), dtype=np.int64)
    off = 0
    for lv, a in enumerate(parts):
        meta[lv] = (off, a.shape[0], a.shape[1])
        off += a.size
    return np.concatenate([a.ravel() for a in parts]), meta


def levels_for(radius: float, dx: float, dy: float) -> int:
    """Pyramid levels so that the top blocks are about half the ball's footprint."""
    n = max(1.0, radius / min(dx, dy))
    return max(0, math.floor(math.log2(n)))


@njit("i8(i8, i8, i8)", cache=True, nogil=True)
def _gap(lo: int, hi: int, at: int) -> int:
    if at < lo:
        return lo - at
    if at > hi:
        return at - hi
    return 0


_SIG_CL = "void(f8[:, :], f8[:], i8[:, :], f8, f8, f8, i8[:], i8[:], f8[:, :], i8[:, :])"
_SIG_CLOSE = "void(f8[:, :], f8[:, :], f8[:], i8[:, :], f8, f8, f8, i8[:], i8[:], f8, f8[:, :])"


@njit(_SIG_CL, cache=True, nogil=True)
def _cl_kernel(z: F64, flat: F64, meta: I64, radius: float, dx: float, dy: float,
               rows: I64, cols: I64, cl: F64, contact: I64) -> None:
    ny, nx = z.shape
    r2 = radius * radius
    top = meta.shape[0] - 1
    ra = math.floor(radius / dy)
    rb = math.floor(radius / dx)
    st_l = np.empty(_STACK, dtype=np.int64)
    st_i = np.empty(_STACK, dtype=np.int64)
    st_k = np.empty(_STACK, dtype=np.int64)
    qi, qk = -1, -1
    for n in range(rows.size):
        i, k = rows[n], cols[n]
        best = z[i, k]
        bi, bk = i, k
        if qi >= 0:  # the neighbour's contact node: usually this position's too
            d2 = ((qi - i) * dy) ** 2 + ((qk - k) * dx) ** 2
            if d2 <= r2:
                v = z[qi, qk] - (radius - math.sqrt(r2 - d2))
                if v > best:
                    best, bi, bk = v, qi, qk
        sp = 0
        s = 1 << top
        for ti in range(max(0, i - ra) // s, min(ny - 1, i + ra) // s + 1):
            for tk in range(max(0, k - rb) // s, min(nx - 1, k + rb) // s + 1):
                st_l[sp], st_i[sp], st_k[sp] = top, ti, tk
                sp += 1
        while sp > 0:
            sp -= 1
            lv, a, b = st_l[sp], st_i[sp], st_k[sp]
            s = 1 << lv
            da = _gap(a * s, min(a * s + s - 1, ny - 1), i)
            db = _gap(b * s, min(b * s + s - 1, nx - 1), k)
            d2 = (da * dy) ** 2 + (db * dx) ** 2
            if d2 > r2:
                continue
            off, _, mx = meta[lv, 0], meta[lv, 1], meta[lv, 2]
            ub = flat[off + a * mx + b] - (radius - math.sqrt(r2 - d2))
            if ub <= best:
                continue
            if lv == 0:
                best, bi, bk = ub, a, b
                continue
            cy, cx = meta[lv - 1, 1], meta[lv - 1, 2]
            for ca in range(2 * a, min(2 * a + 2, cy)):
                for cb in range(2 * b, min(2 * b + 2, cx)):
                    st_l[sp], st_i[sp], st_k[sp] = lv - 1, ca, cb
                    sp += 1
        cl[i, k] = best
        contact[i, k] = bi * nx + bk
        qi, qk = bi, bk


@njit(_SIG_CLOSE, cache=True, nogil=True)
def _close_kernel(z: F64, cl: F64, flat: F64, meta: I64, radius: float, dx: float, dy: float,
                  rows: I64, cols: I64, stop: float, out: F64) -> None:
    ny, nx = z.shape
    r2 = radius * radius
    top = meta.shape[0] - 1
    ra = math.floor(radius / dy)
    rb = math.floor(radius / dx)
    st_l = np.empty(_STACK, dtype=np.int64)
    st_i = np.empty(_STACK, dtype=np.int64)
    st_k = np.empty(_STACK, dtype=np.int64)
    pi, pk = -1, -1  # best position of the previous query
    for n in range(rows.size):
        i, k = rows[n], cols[n]
        floor = z[i, k] + stop
        best = cl[i, k]
        ci, ck = i, k
        if pi >= 0:  # the neighbour's best position, and shifted by the step between them
            for ti, tk in ((pi, pk), (pi + i - rows[n - 1], pk + k - cols[n - 1])):
                if 0 <= ti < ny and 0 <= tk < nx:
                    d2 = ((ti - i) * dy) ** 2 + ((tk - k) * dx) ** 2
                    if d2 <= r2:
                        v = cl[ti, tk] + (radius - math.sqrt(r2 - d2))
                        if v < best:
                            best, ci, ck = v, ti, tk
        if best > floor:
            sp = 0
            s = 1 << top
            for ti in range(max(0, i - ra) // s, min(ny - 1, i + ra) // s + 1):
                for tk in range(max(0, k - rb) // s, min(nx - 1, k + rb) // s + 1):
                    st_l[sp], st_i[sp], st_k[sp] = top, ti, tk
                    sp += 1
            while sp > 0 and best > floor:
                sp -= 1
                lv, a, b = st_l[sp], st_i[sp], st_k[sp]
                s = 1 << lv
                da = _gap(a * s, min(a * s + s - 1, ny - 1), i)
                db = _gap(b * s, min(b * s + s - 1, nx - 1), k)
                d2 = (da * dy) ** 2 + (db * dx) ** 2
                if d2 > r2:
                    continue
                off, _, mx = meta[lv, 0], meta[lv, 1], meta[lv, 2]
                lb = flat[off + a * mx + b] + (radius - math.sqrt(r2 - d2))
                if lb >= best:
                    continue
                if lv == 0:
                    best, ci, ck = lb, a, b
                    continue
                cy, cx = meta[lv - 1, 1], meta[lv - 1, 2]
                for ca in range(2 * a, min(2 * a + 2, cy)):
                    for cb in range(2 * b, min(2 * b + 2, cx)):
                        st_l[sp], st_i[sp], st_k[sp] = lv - 1, ca, cb
                        sp += 1
        out[i, k] = best
        pi, pk = ci, ck


#: Footprints (nodes) up to which a plain scan of the ball's nodes beats the search.
BRUTE_NODES = 800


def ball_offsets(radius: float, dx: float, dy: float) -> tuple[I64, F64]:
    """Half-width in columns of the ball's nodes on each row offset, and ``h`` there.

    Returns
    -------
    half : (2A + 1,) int64
        Row offset ``a`` spans columns ``-half[a - A] .. half[a - A]``.
    h : (2A + 1, 2B + 1) float64
        ``h`` at offset ``(a, b)`` (``+inf`` outside the ball).
    """
    ra, rb = math.floor(radius / dy), math.floor(radius / dx)
    a, b = np.mgrid[-ra:ra + 1, -rb:rb + 1]
    d2 = (a * dy) ** 2 + (b * dx) ** 2
    inside = d2 <= radius * radius
    h = np.where(inside, radius - np.sqrt(np.maximum(radius * radius - d2, 0.0)), np.inf)
    half = np.where(inside, np.abs(b), -1).max(axis=1).astype(np.int64)
    return half, np.ascontiguousarray(h)


@njit("void(f8[:, :], i8[:], f8[:, :], i8[:], i8[:], f8[:, :], i8[:, :])", cache=True, nogil=True)
def _cl_brute(z: F64, half: I64, hh: F64, rows: I64, cols: I64, cl: F64,
              contact: I64) -> None:
    ny, nx = z.shape
    ra = (half.size - 1) // 2
    rb = (hh.shape[1] - 1) // 2
    for n in range(rows.size):
        i, k = rows[n], cols[n]
        best = -np.inf
        at = -1
        for a in range(max(-ra, -i), min(ra, ny - 1 - i) + 1):
            w = half[a + ra]
            if w < 0:
                continue
            b0, b1 = max(-w, -k), min(w, nx - 1 - k)
            row = z[i + a]
            hr = hh[a + ra]
            top = -np.inf
            for b in range(b0, b1 + 1):
                top = max(top, row[k + b] - hr[b + rb])
            if top > best:
                best = top
                at = i + a
        if at >= 0:  # the contact column on the winning row
            a = at - i
            w = half[a + ra]
            row = z[at]
            hr = hh[a + ra]
            for b in range(max(-w, -k), min(w, nx - 1 - k) + 1):
                if row[k + b] - hr[b + rb] == best:
                    at = at * nx + k + b
                    break
        cl[i, k] = best
        contact[i, k] = at


@njit("void(f8[:, :], i8[:], f8[:, :], i8[:], i8[:], f8[:, :])", cache=True, nogil=True)
def _close_brute(cl: F64, half: I64, hh: F64, rows: I64, cols: I64, out: F64) -> None:
    ny, nx = cl.shape
    ra = (half.size - 1) // 2
    rb = (hh.shape[1] - 1) // 2
    for n in range(rows.size):
        i, k = rows[n], cols[n]
        best = np.inf
        for a in range(max(-ra, -i), min(ra, ny - 1 - i) + 1):
            w = half[a + ra]
            if w < 0:
                continue
            b0, b1 = max(-w, -k), min(w, nx - 1 - k)
            row = cl[i + a]
            hr = hh[a + ra]
            low = np.inf
            for b in range(b0, b1 + 1):
                low = min(low, row[k + b] + hr[b + rb])
            best = min(best, low)
        out[i, k] = best


def nodal_drop_cutter(z: F64, radius: float, dx: float, dy: float,
                      positions: NDArray[np.bool_] | None = None) -> tuple[F64, I64]:
    """Exact nodal drop-cutter CL of a ball at the asked positions.

    Parameters
    ----------
    z : (ny, nx) float64
        Part heights at the nodes.
    radius, dx, dy : float
        Ball radius and node spacing, mm.
    positions : (ny, nx) bool, optional
        Positions to compute (default: all).

    Returns
    -------
    cl : (ny, nx) float64
        ``max over nodes q within radius of z(q) - h(|q - c|)``; +inf where not asked.
    contact : (ny, nx) int64
        Flat index of a node the ball touches (-1 where not asked).
    """
    z = _plain(z)
    mask = np.ones(z.shape, dtype=bool) if positions is None else positions
    rows, cols = np.nonzero(mask)
    cl = np.full(z.shape, np.inf)
    contact = np.full(z.shape, -1, dtype=np.int64)
    half, hh = ball_offsets(radius, dx, dy)
    if int((2 * half + 1).clip(0).sum()) <= BRUTE_NODES:
        _cl_brute(z, half, hh, rows.astype(np.int64), cols.astype(np.int64), cl, contact)
        return cl, contact
    flat, meta = pyramid(z, levels_for(radius, dx, dy), high=True)
    _cl_kernel(z, flat, meta, float(radius), float(dx), float(dy), rows.astype(np.int64),
               cols.astype(np.int64), cl, contact)
    return cl, contact


def nodal_closing(z: F64, cl: F64, radius: float, dx: float, dy: float,
                  nodes: NDArray[np.bool_], stop: float = 0.0) -> F64:
    """What balls at the CL positions leave at the asked nodes.

    Parameters
    ----------
    z : (ny, nx) float64
    cl : (ny, nx) float64
        Tip heights (+inf: no ball there); every position within ``radius`` of an
        asked node must be given for the result to be the closing.
    radius, dx, dy : float
    nodes : (ny, nx) bool
        Nodes to evaluate.
    stop : float
        A node's search ends once a position leaves at most ``stop`` over ``z`` there
        (the result is then within ``stop`` of the exact value, never below ``z``).

    Returns
    -------
    (ny, nx) float64
        ``min over positions c within radius of cl(c) + h(|p - c|)`` at asked nodes,
        ``z`` elsewhere.
    """
    z = _plain(z)
    cl = _plain(cl)
    rows, cols = np.nonzero(nodes)
    out = z.copy()
    half, hh = ball_offsets(radius, dx, dy)
    if int((2 * half + 1).clip(0).sum()) <= BRUTE_NODES:
        _close_brute(cl, half, hh, rows.astype(np.int64),
                     cols.astype(np.int64), out)
        return out
    flat, meta = pyramid(cl, levels_for(radius, dx, dy), high=False)
    _close_kernel(z, cl, flat, meta, float(radius), float(dx), float(dy),
                  rows.astype(np.int64), cols.astype(np.int64), float(stop), out)
    return out


@njit("void(f8[:, :], f8, f8, f8, i8[:], i8[:], f8[:, :], f8)", cache=True, nogil=True)
def _refine_kernel(z: F64, dx: float, dy: float, radius: float, rows: I64, cols: I64,
                   rest: F64, slack: float) -> None:
    ny, nx = z.shape
    r2 = radius * radius
    for n in range(rows.size):
        i, k = rows[n], cols[n]
        # the surface normal at p from central (one-sided at the edge) differences
        i0, i1 = max(i - 1, 0), min(i + 1, ny - 1)
        k0, k1 = max(k - 1, 0), min(k + 1, nx - 1)
        gy = (z[i1, k] - z[i0, k]) / (max(i1 - i0, 1) * dy)
        gx = (z[i, k1] - z[i, k0]) / (max(k1 - k0, 1) * dx)
        if not (math.isfinite(gx) and math.isfinite(gy)):
            continue
        s = radius / math.sqrt(1.0 + gx * gx + gy * gy)
        # the ball touching p along the normal has its axis here (node units)
        cy0, cx0 = i - gy * s / dy, k - gx * s / dx
        best = rest[i, k]
        # along the normal first; the ring around it only where that found a cusp
        # (a real corner leaves about as much there as at the node positions)
        for t in range(25):
            if t == 0:
                a, b = 0, 0
            else:
                if best > rest[i, k] - 0.5 * slack:
                    break
                a, b = (t - 1) // 5 - 2, (t - 1) % 5 - 2
                if a == 0 and b == 0:
                    continue
            cy, cx = cy0 + 0.25 * a, cx0 + 0.25 * b
            dp2 = ((cy - i) * dy) ** 2 + ((cx - k) * dx) ** 2
            if dp2 > r2:
                continue
            top = -np.inf
            for q in range(max(0, math.ceil(cy - radius / dy)),
                           min(ny - 1, math.floor(cy + radius / dy)) + 1):
                ey = ((q - cy) * dy) ** 2
                for m in range(max(0, math.ceil(cx - radius / dx)),
                               min(nx - 1, math.floor(cx + radius / dx)) + 1):
                    d2 = ey + ((m - cx) * dx) ** 2
                    if d2 <= r2:
                        v = z[q, m] - (radius - math.sqrt(r2 - d2))
                        if v > top:
                            top = v
            left = top + (radius - math.sqrt(r2 - dp2)) - z[i, k]
            if left < best:
                best = max(left, 0.0)
        rest[i, k] = best


def refine_rest(z: F64, dx: float, dy: float, radius: float, rest: F64,
                nodes: NDArray[np.bool_], slack: float) -> F64:
    """Rest at the asked nodes with a ball between the nodes as well (in place).

    Node positions leave *position cusps* between them, large where a concave surface
    nearly fits the ball (its contact points spread out). The machine moves
    continuously, so at each asked node the ball is also tried along the node's
    surface normal (and, where that finds a cusp, around it a quarter and half a
    node off), with its drop-cutter
    height against the nodes: the rest there is the least found.

    Parameters
    ----------
    z : (ny, nx) float64
    dx, dy, radius : float
    rest : (ny, nx) float64
        Rest from node positions; lowered in place.
    nodes : (ny, nx) bool
    slack : float
        The ring around the normal is tried only where the normal itself lowered the
        rest by at least half of this (a cusp, not a corner), mm.

    Returns
    -------
    (ny, nx) float64
        ``rest``.
    """
    rows, cols = np.nonzero(nodes)
    _refine_kernel(_plain(z), float(dx), float(dy),
                   float(radius), rows.astype(np.int64), cols.astype(np.int64), rest,
                   float(slack))
    return rest
