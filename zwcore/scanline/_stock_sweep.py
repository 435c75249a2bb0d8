"""Line-sweep kernels of the simulated stock for large balls (:mod:`zwcore.scanline._stock`).

A pass's positions lie on scan lines. Seen from one node row at across-distance ``e``
from a line, every ball on that line is the same circular arc
``c + R - sqrt(R² - e² - t²)`` shifted along the row (``t`` the distance along it): one
convex function, translated. So per (line, row) the envelope of the line's balls is a
1-D lower envelope of translates of one convex function, built in one pass over the
line's positions with a stack (two translates cross at most once: the later one wins
from the crossing on), then read at the row's nodes in one more pass
(:func:`cut_lines`). The drop against the nodes is the same with the roles swapped: the
row's nodes are the arcs (``-z + h``), read at the line's positions (:func:`cl_lines`).
The cost per pass is (lines x rows within ``R``) x (positions on the line + nodes the
line's balls span) instead of positions x the ball's footprint: a Ø20 ball on a 0.1 mm
grid spans 31,000 nodes but 205 rows.

Both give what the per-position kernels (:func:`_stock_kernels.cut`,
:func:`_stock_kernels.cl_part`) give, to the last bits: a node's value is the same
expression of one position's CL (the envelope's winner, checked against its neighbours on
the stack, so a crossing rounded across a node cannot pick a worse ball), and a node
counts as within ``R`` by the same test (``d² <= R² RIM``). Where many balls reach a
node at the same height (a node every ball touches, on a wall's top edge say) their
values differ only in the rounding, and the winner may be one rounded a few ulps higher
than the least: the envelope is then that much higher (never lower) than the
per-position kernel's, the drop that much lower.

Lines run along axis 1 of the arrays (``u`` along, ``v`` across, ``du``, ``dv`` the
spacings); lines along y go through transposed views.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from zwcore.scanline._stock_kernels import RIM, _span

__all__ = ["cl_lines", "cut_lines", "line_starts", "sweep_work"]

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]


@njit(cache=True, nogil=True)
def _arc(u: float, c: float, x: float, rho2: float) -> float:
    """Height of the arc of the ball at ``u`` (tip ``c``) over ``x``, less ``R``."""
    t = x - u
    return c - math.sqrt(max(rho2 - t * t, 0.0))


@njit(cache=True, nogil=True)
def _cross(u1: float, c1: float, u2: float, c2: float, w: float, rho2: float) -> float:
    """Where the arc at ``u2 > u1`` starts to lie under the one at ``u1`` (their lower
    envelope switches there, once); each arc is defined within ``w`` of its centre."""
    if u2 - u1 > 2.0 * w:
        return 0.5 * (u1 + u2)
    a, b = u2 - w, u1 + w  # where both are defined
    # The arcs' circles (equal radii) meet on the bisector of their centres; where the
    # lower meeting point lies under both centres and over the common span, the lower
    # arcs cross there (the usual case, one square root).
    du, dz = u2 - u1, c2 - c1
    q = rho2 / (du * du + dz * dz) - 0.25
    if q >= 0.0:
        t = math.sqrt(q)
        x = 0.5 * (u1 + u2) + dz * t
        if a <= x <= b and 0.5 * (c1 + c2) - du * t <= min(c1, c2):
            return x
    # else one arc lies under the other over the whole common span
    if _arc(u2, c2, a, rho2) <= _arc(u1, c1, a, rho2):
        return a
    if _arc(u2, c2, b, rho2) >= _arc(u1, c1, b, rho2):
        return b
    return min(max(0.5 * (u1 + u2) + dz * math.sqrt(max(q, 0.0)), a), b)


@njit(cache=True, nogil=True)
def _envelope(pu: F64, pc: F64, j0: int, j1: int, w: float, rho2: float, st: I64,
              start: F64) -> int:
    """Lower envelope of the arcs of positions ``j0..j1-1`` (sorted along the line):
    ``st[0..m-1]`` the winners left to right, ``start[k]`` where ``st[k]`` begins.
    Returns ``m``."""
    m = 0
    for j in range(j0, j1):
        if m > 0 and pu[j] == pu[st[m - 1]]:
            if pc[j] >= pc[st[m - 1]]:
                continue
            m -= 1
        s = -np.inf
        while m > 0:
            s = _cross(pu[st[m - 1]], pc[st[m - 1]], pu[j], pc[j], w, rho2)
            # the first arc is the only one defined left of the others: never all beaten
            if m > 1 and s <= start[m - 1]:
                m -= 1
                continue
            break
        st[m] = j
        start[m] = s if m > 0 else -np.inf
        m += 1
    return m


@njit(cache=True, nogil=True)
def _cut_row(row: F64, i: int, b: int, ey2: float, floor: float, pu: F64, pc: F64,
             st: I64, start: F64, m: int, w: float, r: float, du: float,
             touched: NDArray[np.bool_], skip: NDArray[np.bool_]) -> None:
    """Lower one row (``ey2`` from the line) by the envelope ``st[:m]``, ``start[:m]``
    (not in the blocks ``skip`` marks)."""
    nu = row.size
    r2, rin = r * r, r * r * RIM
    k0, _ = _span(pu[st[0]], w, du, nu)
    _, k1 = _span(pu[st[m - 1]], w, du, nu)
    near = _NEAR * du
    at = 0
    sk = skip[i // b]
    for k in range(k0, k1 + 1):
        if row[k] <= floor or sk[k // b]:
            continue
        x = k * du
        while at + 1 < m and start[at + 1] <= x:
            at += 1
        # the winner; its neighbours too where a crossing lies close (its rounding)
        lo, hi = at, at
        if at > 0 and x - start[at] <= near:
            lo = at - 1
        if at + 1 < m and start[at + 1] - x <= near:
            hi = at + 1
        best = np.inf
        for e in range(lo, hi + 1):
            j = st[e]
            ex = x - pu[j]
            d2 = ex * ex + ey2
            if d2 <= rin:
                best = min(best, pc[j] + (r - math.sqrt(max(r2 - d2, 0.0))))
        if best < row[k]:
            row[k] = best
            touched[i // b, k // b] = True


#: A node this close to a crossing of the envelope (in spacings) is also tried with the
#: arc on the crossing's other side: the crossing's rounding, with room to spare.
_NEAR = 1e-6


@njit(cache=True, nogil=True)
def cut_lines(s: F64, pu: F64, pv: F64, pc: F64, starts: I64, r: float, du: float,
              dv: float, b: int, touched: NDArray[np.bool_], skip: NDArray[np.bool_],
              ) -> None:
    """``s = min(s, c + h(|p - c|))`` at every node within ``r`` of each position, in
    place; ``touched`` (blocks of ``b x b`` nodes, ``(ceil(nv/b), ceil(nu/b))``) is set
    where a node was lowered. Blocks ``skip`` marks (the same shape) are left alone, and
    a row none of whose blocks in a line's reach is left is not swept for that line.

    A line on a node row sees the rows ``a`` above and below it alike (to the rounding of
    ``e``): one envelope serves both.

    Parameters
    ----------
    s : (nv, nu) float64
        Stock, lines along axis 1.
    pu, pv, pc : (n,) float64
        Positions sorted by line (``pv``) then along it (``pu``), and their CL.
    starts : (lines + 1,) int64
        Each line's first position, and ``n``.
    """
    nv, nu = s.shape
    r2, rin = r * r, r * r * RIM
    n = pu.size
    st = np.empty(n, dtype=np.int64)
    start = np.empty(n)
    # per block row, blocks left to sweep before each block column
    mb, nb = skip.shape
    left = np.zeros((mb, nb + 1), dtype=np.int64)
    for bi in range(mb):
        for bk in range(nb):
            left[bi, bk + 1] = left[bi, bk] + (0 if skip[bi, bk] else 1)
    for ln in range(starts.size - 1):
        j0, j1 = starts[ln], starts[ln + 1]
        q = pv[j0]
        cmin = np.inf
        for j in range(j0, j1):
            cmin = min(cmin, pc[j])
        i0, i1 = _span(q, r, dv, nv)
        iq = round(q / dv)
        mirror = abs(q / dv - iq) <= 1e-9  # a line on a node row
        ka, _ = _span(pu[j0], r, du, nu)
        _, kb = _span(pu[j1 - 1], r, du, nu)
        if ka > kb:
            continue
        ba, bb = ka // b, kb // b + 1
        for i in range(i0, i1 + 1):
            if mirror and i < iq and 2 * iq - i <= i1:
                continue  # done with its mirror row below
            other = 2 * iq - i
            two = mirror and other != i and i0 <= other <= i1
            if (left[i // b, bb] == left[i // b, ba]
                    and not (two and left[other // b, bb] > left[other // b, ba])):
                continue  # every block of the row (and its mirror) in reach is settled
            ey = i * dv - q
            ey2 = ey * ey
            if ey2 > rin:
                continue
            rho2 = r2 - ey2
            w = math.sqrt(rin - ey2)
            m = _envelope(pu, pc, j0, j1, w, rho2, st, start)
            _cut_row(s[i], i, b, ey2, cmin + (r - math.sqrt(max(rho2, 0.0))), pu, pc, st,
                     start, m, w, r, du, touched, skip)
            if two:
                ey_o = other * dv - q
                e2 = ey_o * ey_o
                if e2 <= rin:
                    _cut_row(s[other], other, b, e2,
                             cmin + (r - math.sqrt(max(r2 - e2, 0.0))), pu, pc, st,
                             start, m, math.sqrt(rin - e2), r, du, touched, skip)


@njit(cache=True, nogil=True)
def cl_lines(z: F64, pu: F64, pv: F64, cl0: F64, starts: I64, r: float, du: float,
             dv: float) -> F64:
    """``max(cl0, max over nodes q within r of z[q] - h(|q - c|))`` per position (the
    drop against the nodes, :func:`_stock_kernels.cl_part`); arguments as
    :func:`cut_lines`. Per row the nodes are the arcs (``-z + h``, a lower envelope as
    in :func:`cut_lines`), read at the line's positions."""
    nv, nu = z.shape
    r2, rin = r * r, r * r * RIM
    out = cl0.copy()
    su = np.empty(nu)
    sc = np.empty(nu)
    st = np.empty(nu, dtype=np.int64)
    start = np.empty(nu)
    for ln in range(starts.size - 1):
        j0, j1 = starts[ln], starts[ln + 1]
        q = pv[j0]
        i0, i1 = _span(q, r, dv, nv)
        for i in range(i0, i1 + 1):
            ey = i * dv - q
            ey2 = ey * ey
            if ey2 > rin:
                continue
            rho2 = r2 - ey2
            w = math.sqrt(rin - ey2)
            k0, _ = _span(pu[j0], w, du, nu)
            _, k1 = _span(pu[j1 - 1], w, du, nu)
            if k0 > k1:
                continue
            row = z[i]
            for k in range(k0, k1 + 1):
                su[k - k0] = k * du
                sc[k - k0] = -row[k]
            m = _envelope(su, sc, 0, k1 - k0 + 1, w, rho2, st, start)
            at = 0
            for j in range(j0, j1):
                p = pu[j]
                while at + 1 < m and start[at + 1] <= p:
                    at += 1
                best = out[j]
                for e in range(max(at - 1, 0), min(at + 2, m)):
                    k = st[e] + k0
                    ex = k * du - p
                    d2 = ex * ex + ey2
                    if d2 <= rin:
                        v = row[k] - (r - math.sqrt(max(r2 - d2, 0.0)))
                        best = max(best, v)
                out[j] = best
    return out


def line_starts(pv: F64) -> I64:
    """Indices where a new line (another ``pv``) begins in positions sorted by line, and
    the count."""
    cut = np.flatnonzero(pv[1:] != pv[:-1]) + 1
    return np.concatenate(([0], cut, [pv.size])).astype(np.int64)


def sweep_work(pu: F64, starts: I64, r: float, du: float, dv: float) -> float:
    """Node visits of the sweep: per line, rows within ``r`` times (positions on the line
    + nodes its balls span)."""
    first, last = pu[starts[:-1]], pu[starts[1:] - 1]
    per_row = (starts[1:] - starts[:-1]) + (last - first + 2.0 * r) / du
    return float(per_row.sum() * (2.0 * r / dv + 1.0))
