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

Both skip most of that work with bounds that cannot change the answer: :func:`cl_lines`
takes rows coarse to fine and leaves out the nodes whose arc cannot rise above the CL
found so far, :func:`cut_lines` sweeps the rows near each line first and passes over the
chunks of a row whose stock lies under a lower bound of the line's balls (both bounds:
``h`` is convex in ``d²``, so a ball at along-distance ``t`` stands at least
``h(e) + t² / (2 sqrt(R² - e²))`` above its tip over a row ``e`` away; a lower envelope
of parabolas gives the least over the line's positions). On the 1025² bench part's Ø20
finishing pass: drop 0.49 -> 0.28 s, envelope 0.46 -> 0.30 s CPU.

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

__all__ = ["cl_lines", "cut_lines", "line_starts", "line_work", "sweep_work"]

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


#: Nodes per chunk of a row whose bound is tested whole (:func:`cl_lines`, :func:`_cut_row`).
_CHUNK = 8


#: Rows of the drop go every this many rows first, then halving (:func:`_row_offset`).
_ROW_STEP = 8


@njit(cache=True, nogil=True)
def _row_count(span: int) -> int:
    """Offsets :func:`_row_offset` enumerates for rows ``-span..span``."""
    return 2 * span + 1


@njit(cache=True, nogil=True)
def _row_offset(t: int, span: int) -> int:
    """The ``t``-th row offset in ``-span..span``, coarse to fine: ``0, ±s, ±2s, ...`` for
    ``s = _ROW_STEP``, then the odd multiples of ``s/2``, of ``s/4``, ... (each once): the
    rows near the contact, wherever it lies, come early, so the bounds prune the rest."""
    step = _ROW_STEP
    n = 2 * (span // step) + 1  # 0, ±step, ±2 step, ...
    if t < n:
        m = (t + 1) // 2
        return m * step if t % 2 else -m * step
    t -= n
    while step > 1:
        half = step // 2
        # odd multiples of half within span: half, 3 half, ... both signs
        cnt = (span // half + 1) // 2
        if t < 2 * cnt:
            m = (t // 2) * step + half
            return m if t % 2 == 0 else -m
        t -= 2 * cnt
        step = half
    return 0


#: What the row bounds (:func:`_parabolas`) give away to the rounding, mm.
_SLACK = 1e-9


@njit(cache=True, nogil=True)
def _parabolas(pu: F64, f: F64, j0: int, j1: int, a: float, pp: F64, pf: F64,
               start: F64) -> int:
    """Lower envelope of ``f[j] + a (x - pu[j])²`` over positions ``j0..j1-1`` (sorted by
    ``pu``): ``pp, pf`` the winners' places and values left to right, ``start`` where
    each begins. Returns their count. A value of -inf (or far below) wins everywhere."""
    m = 0
    for j in range(j0, j1):
        u, v = pu[j], min(max(f[j], -1e200), 1e200)
        if m > 0 and u == pp[m - 1]:
            if v >= pf[m - 1]:
                continue
            m -= 1
        s = -np.inf
        while m > 0:
            du = u - pp[m - 1]
            s = 0.5 * (u + pp[m - 1]) + (v - pf[m - 1]) / (2.0 * a * du)
            if m > 1 and s <= start[m - 1]:
                m -= 1
                continue
            break
        pp[m], pf[m] = u, v
        start[m] = s if m > 0 else -np.inf
        m += 1
    return m


@njit(cache=True, nogil=True)
def _row_chunk_max(z: F64, c: int, i_lo: int = 0, i_hi: int = -1) -> F64:
    """``(nv, ceil(nu / c))``: the largest node of every ``c`` consecutive nodes of a row,
    for the rows ``i_lo..i_hi-1`` (``i_hi < 0``: to the last; the others left unset)."""
    nv, nu = z.shape
    nc = (nu + c - 1) // c
    out = np.empty((nv, nc))
    for i in range(i_lo, nv if i_hi < 0 else i_hi):
        for m in range(nc):
            hi = -np.inf
            for k in range(m * c, min(nu, m * c + c)):
                hi = max(hi, z[i, k])
            out[i, m] = hi
    return out


@njit(cache=True, nogil=True)
def _chunk_low(pp: F64, pf: F64, ps: F64, npar: int, pa: int, xa: float, xb: float,
               curv: float) -> tuple[float, int]:
    """The least of the envelope ``pf[e] + curv (x - pp[e])²`` (:func:`_parabolas`: ``npar``
    pieces beginning at ``ps``) over ``xa <= x <= xb``, from its pieces over that span, and
    the first of them (``pa``: the first at or before it; the spans come left to right)."""
    while pa + 1 < npar and ps[pa + 1] <= xa:
        pa += 1
    lo = np.inf
    e = pa
    while e < npar and (e == pa or ps[e] <= xb):
        t = max(0.0, xa - pp[e], pp[e] - xb)
        lo = min(lo, pf[e] + curv * t * t)
        e += 1
    return lo, pa


@njit(cache=True, nogil=True)
def _chunk_bounds(pu: F64, pc: F64, j0: int, j1: int, curv: float, k0: int, k1: int,
                  du: float, pp: F64, pf: F64, ps: F64, out: F64) -> None:
    """``out[ch]``: the least of ``pc[j] + curv t²`` over the line's positions, ``t`` their
    distance along the line from chunk ``ch``'s nodes (for the chunks of nodes
    ``k0..k1``; :func:`_parabolas`)."""
    npar = _parabolas(pu, pc, j0, j1, curv, pp, pf, ps)
    pa = 0
    for ch in range(k0 // _CHUNK, k1 // _CHUNK + 1):
        xa = max(k0, ch * _CHUNK) * du
        xb = min(k1, ch * _CHUNK + _CHUNK - 1) * du
        out[ch], pa = _chunk_low(pp, pf, ps, npar, pa, xa, xb, curv)


@njit(cache=True, nogil=True)
def _cut_row(row: F64, i: int, b: int, ey2: float, floor: float, pu: F64, pc: F64,
             j0: int, j1: int, st: I64, start: F64, built: I64, w_env: float,
             rho2_env: float, w: float, r: float, du: float,
             touched: NDArray[np.bool_], skip: NDArray[np.bool_], rowmax: F64,
             curv: float, pp: F64, pf: F64, ps: F64, gline: F64) -> None:
    """Lower one row (``ey2`` from the line) by the lower envelope of the line's balls
    (positions ``j0..j1-1``; not in the blocks ``skip`` marks).

    The envelope (``st``, ``start``: :func:`_envelope` with ``w_env``, ``rho2_env``) and
    the bound's parabolas (``pp, pf, ps``) are built when a chunk first needs them,
    once for a row and its mirror (``built``: their counts, -1 until built).
    ``rowmax`` holds an upper bound of the row's stock per chunk of :data:`_CHUNK`
    nodes (kept one here). The line's balls stand at least ``he + curv t²`` over the
    positions' CLs ``t`` along the line away (the lower envelope of
    ``pc + curv (x - pu)²``, :func:`_parabolas`; h is convex in d²): a chunk whose stock
    lies under that nowhere is lowered nowhere, and is not visited. ``gline``: the same
    bound per chunk with the least curvature ``1 / (2R)`` (every row's), computed once
    for the line, tried first."""
    nu = row.size
    r2, rin = r * r, r * r * RIM
    # the envelope's first and last winners are the line's first and last positions
    k0, _ = _span(pu[j0], w, du, nu)
    _, k1 = _span(pu[j1 - 1], w, du, nu)
    near = _NEAR * du
    he = r - math.sqrt(max(r2 - ey2, 0.0))
    at = 0
    pa = 0
    sk = skip[i // b]
    m, npar = built[0], built[1]
    for ch in range(k0 // _CHUNK, k1 // _CHUNK + 1):
        if rowmax[ch] <= max(floor, gline[ch] + he - _SLACK):
            continue
        if npar < 0:
            npar = _parabolas(pu, pc, j0, j1, curv, pp, pf, ps)
            built[1] = npar
        ka, kb = max(k0, ch * _CHUNK), min(k1, ch * _CHUNK + _CHUNK - 1)
        lo, pa = _chunk_low(pp, pf, ps, npar, pa, ka * du, kb * du, curv)
        low = max(floor, lo + he - _SLACK)  # no node at or under it is lowered
        if rowmax[ch] <= low:
            continue
        if m < 0:
            m = _envelope(pu, pc, j0, j1, w_env, rho2_env, st, start)
            built[0] = m
        for k in range(ka, kb + 1):
            if row[k] <= low or sk[k // b]:
                continue
            x = k * du
            while at + 1 < m and start[at + 1] <= x:
                at += 1
            # the winner; its neighbours too where a crossing lies close (its rounding)
            lo_, hi_ = at, at
            if at > 0 and x - start[at] <= near:
                lo_ = at - 1
            if at + 1 < m and start[at + 1] - x <= near:
                hi_ = at + 1
            best = np.inf
            for e in range(lo_, hi_ + 1):
                j = st[e]
                ex = x - pu[j]
                d2 = ex * ex + ey2
                if d2 <= rin:
                    best = min(best, pc[j] + (r - math.sqrt(max(r2 - d2, 0.0))))
            if best < row[k]:
                row[k] = best
                touched[i // b, k // b] = True
        top = -np.inf
        for k in range(ch * _CHUNK, min(nu, ch * _CHUNK + _CHUNK)):
            top = max(top, row[k])
        rowmax[ch] = top


#: Each band of rows :func:`cut_lines` sweeps reaches this many times as far from the
#: line as the one before.
_BAND_GROWTH = 2.0

#: A node this close to a crossing of the envelope (in spacings) is also tried with the
#: arc on the crossing's other side: the crossing's rounding, with room to spare.
_NEAR = 1e-6


@njit(cache=True, nogil=True)
def cut_lines(s: F64, pu: F64, pv: F64, pc: F64, starts: I64, r: float, du: float,
              dv: float, b: int, touched: NDArray[np.bool_], skip: NDArray[np.bool_],
              i_lo: int = 0, i_hi: int = -1) -> None:
    """``s = min(s, c + h(|p - c|))`` at every node within ``r`` of each position, in
    place; ``touched`` (blocks of ``b x b`` nodes, ``(ceil(nv/b), ceil(nu/b))``) is set
    where a node was lowered. Blocks ``skip`` marks (the same shape) are left alone, and
    a row none of whose blocks in a line's reach is left is not swept for that line.
    Only the rows ``i_lo..i_hi-1`` (``i_hi < 0``: to the last) are lowered: two threads
    sweep two bands of rows (starting at multiples of ``b``) at once, and every row's
    values are those of one call over all rows (each row sees the same lines in the same
    order, and a line's envelope and bounds do not depend on which row builds them).

    A line on a node row sees the rows ``a`` above and below it alike (to the rounding of
    ``e``): one envelope serves both.

    The rows within half the usual line spacing of their line go first, the others
    after, and a chunk of a row (:data:`_CHUNK` nodes) is visited only where its stock
    (an upper bound kept per chunk) may stand above the line's balls
    (:func:`_cut_row`): a far line's balls then rarely reach below what the near ones
    left. The stock is the minimum over the same values whatever the order, and a chunk
    is passed over only where no node of it would be lowered: the result is that of
    every row in line order, bit for bit.

    Parameters
    ----------
    s : (nv, nu) float64
        Stock, lines along axis 1.
    pu, pv, pc : (n,) float64
        Positions sorted by line (``pv``) then along it (``pu``), and their CL.
    starts : (lines + 1,) int64
        Each line's first position, and ``n``.
    """
    rin = r * r * RIM
    n = pu.size
    st = np.empty(n, dtype=np.int64)
    start = np.empty(n)
    # per block row, blocks left to sweep before each block column
    mb, nb = skip.shape
    left = np.zeros((mb, nb + 1), dtype=np.int64)
    for bi in range(mb):
        for bk in range(nb):
            left[bi, bk + 1] = left[bi, bk] + (0 if skip[bi, bk] else 1)
    nv = s.shape[0]
    ilo, ihi = max(i_lo, 0), nv if i_hi < 0 else min(i_hi, nv)
    rowmax = _row_chunk_max(s, _CHUNK, ilo, ihi)
    pp = np.empty(max(n, 1))
    pf = np.empty(max(n, 1))
    ps = np.empty(max(n, 1))
    # Rows within half the usual line spacing first (each row by its nearest lines), then
    # in bands of growing distance: the stock is low early and the bounds skip most far
    # rows.
    half = r
    if starts.size > 2:
        half = max(0.5 * np.median(np.diff(pv[starts[:-1]])), 1e-9)
    lo2 = -1.0
    hi = half
    while lo2 < rin:
        hi2 = hi * hi if hi < r else rin
        _cut_phase(s, pu, pv, pc, starts, r, du, dv, b, touched, skip, left, rowmax, st,
                   start, pp, pf, ps, lo2, hi2, ilo, ihi)
        lo2 = hi2
        hi *= _BAND_GROWTH


@njit(cache=True, nogil=True)
def _cut_phase(s: F64, pu: F64, pv: F64, pc: F64, starts: I64, r: float, du: float,
               dv: float, b: int, touched: NDArray[np.bool_], skip: NDArray[np.bool_],
               left: I64, rowmax: F64, st: I64, start: F64, pp: F64, pf: F64, ps: F64,
               lo2: float, hi2: float, ilo: int, ihi: int) -> None:
    """:func:`cut_lines` over the rows ``ilo..ihi-1`` whose squared distance from their
    line lies in ``(lo2, hi2]``."""
    nv, nu = s.shape
    r2, rin = r * r, r * r * RIM
    built = np.empty(2, dtype=np.int64)
    gline = np.empty(nu // _CHUNK + 1)
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
        gdone = False
        for i in range(i0, i1 + 1):
            if mirror and i < iq and 2 * iq - i <= i1:
                continue  # done with its mirror row below
            other = 2 * iq - i
            two = mirror and other != i and i0 <= other <= i1
            mine = ilo <= i < ihi
            theirs = two and ilo <= other < ihi
            if not (mine or theirs):
                continue  # the other thread's rows
            if (left[i // b, bb] == left[i // b, ba]
                    and not (two and left[other // b, bb] > left[other // b, ba])):
                continue  # every block of the row (and its mirror) in reach is settled
            ey = i * dv - q
            ey2 = ey * ey
            if ey2 > rin or ey2 <= lo2 or ey2 > hi2:
                continue
            rho2 = r2 - ey2
            w = math.sqrt(rin - ey2)
            curv = 0.5 / math.sqrt(max(rho2, rin * 1e-30))
            built[0], built[1] = -1, -1
            if not gdone:
                _chunk_bounds(pu, pc, j0, j1, 0.5 / r, ka, kb, du, pp, pf, ps, gline)
                gdone = True
            if mine:
                _cut_row(s[i], i, b, ey2, cmin + (r - math.sqrt(max(rho2, 0.0))), pu, pc,
                         j0, j1, st, start, built, w, rho2, w, r, du, touched, skip,
                         rowmax[i], curv, pp, pf, ps, gline)
            if theirs:
                ey_o = other * dv - q
                e2 = ey_o * ey_o
                if e2 <= rin:
                    # the mirror's own curvature differs by the rounding (_SLACK covers it)
                    _cut_row(s[other], other, b, e2,
                             cmin + (r - math.sqrt(max(r2 - e2, 0.0))), pu, pc, j0, j1,
                             st, start, built, w, rho2, math.sqrt(rin - e2), r, du,
                             touched, skip, rowmax[other], curv, pp, pf, ps, gline)


@njit(cache=True, nogil=True)
def cl_lines(z: F64, pu: F64, pv: F64, cl0: F64, starts: I64, r: float, du: float,
             dv: float) -> F64:
    """``max(cl0, max over nodes q within r of z[q] - h(|q - c|))`` per position (the
    drop against the nodes, :func:`_stock_kernels.cl_part`); arguments as
    :func:`cut_lines`. Per row the nodes are the arcs (``-z + h``, a lower envelope as
    in :func:`cut_lines`), read at the line's positions.

    Rows go nearest the line first, and a node whose arc cannot rise above the CL found
    so far at every position within its reach (its height less ``h`` at the row's
    distance, against the least CL of the pieces of positions around it) is left out of
    the row's envelope; a row with none left is not swept. What is left out is never the
    answer anywhere (at most equal to it), so the CLs are those of every node.
    """
    nv, nu = z.shape
    r2, rin = r * r, r * r * RIM
    out = cl0.copy()
    su = np.empty(nu)
    sc = np.empty(nu)
    sk = np.empty(nu, dtype=np.int64)
    st = np.empty(nu, dtype=np.int64)
    start = np.empty(nu)
    npos = max(1, pu.size)
    zc = _row_chunk_max(z, _CHUNK)
    pp = np.empty(npos)
    pf = np.empty(npos)
    pstart = np.empty(npos)
    for ln in range(starts.size - 1):
        j0, j1 = starts[ln], starts[ln + 1]
        q = pv[j0]
        i0, i1 = _span(q, r, dv, nv)
        if i0 > i1:
            continue
        iq = min(max(round(q / dv), i0), i1)
        span = max(iq - i0, i1 - iq)
        for t in range(_row_count(span)):
            i = iq + _row_offset(t, span)
            if i < i0 or i > i1:
                continue
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
            he = r - math.sqrt(max(rho2, 0.0))  # no node of the row is nearer the axis
            # h over the row at along-distance t is at least he + t² / (2 sqrt(rho2))
            # (h convex in d²): an arc below out[j] + that at every position is left out
            curv = 0.5 / math.sqrt(max(rho2, rin * 1e-30))
            np_ = _parabolas(pu, out, j0, j1, curv, pp, pf, pstart)
            row = z[i]
            m = 0
            at = 0
            for ch in range(k0 // _CHUNK, k1 // _CHUNK + 1):
                ka, kb = max(k0, ch * _CHUNK), min(k1, ch * _CHUNK + _CHUNK - 1)
                # the bound's least over the chunk: the envelope's pieces over it
                lo, at = _chunk_low(pp, pf, pstart, np_, at, ka * du, kb * du, curv)
                if zc[i, ch] - he <= lo - _SLACK:
                    continue
                pe = at
                for k in range(ka, kb + 1):
                    if row[k] - he <= lo - _SLACK:
                        continue
                    # the bound at the node itself (the pieces about it: rounding)
                    x = k * du
                    while pe + 1 < np_ and pstart[pe + 1] <= x:
                        pe += 1
                    here = np.inf
                    for e in range(max(pe - 1, 0), min(pe + 2, np_)):
                        t = x - pp[e]
                        here = min(here, pf[e] + curv * t * t)
                    if row[k] - he > here - _SLACK:
                        su[m] = x
                        sc[m] = -row[k]
                        sk[m] = k
                        m += 1
            if m == 0:
                continue
            # only positions within reach of a node kept (a spacing to spare) can rise
            xlo, xhi = su[0] - w - du, su[m - 1] + w + du
            m = _envelope(su, sc, 0, m, w, rho2, st, start)
            at = 0
            for j in range(j0, j1):
                p = pu[j]
                if p < xlo:
                    continue
                if p > xhi:
                    break
                while at + 1 < m and start[at + 1] <= p:
                    at += 1
                best = out[j]
                for e in range(max(at - 1, 0), min(at + 2, m)):
                    k = sk[st[e]]
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
    return float(line_work(pu, starts, r, du, dv).sum())


def line_work(pu: F64, starts: I64, r: float, du: float, dv: float) -> F64:
    """:func:`sweep_work` per line, ``(lines,)``."""
    first, last = pu[starts[:-1]], pu[starts[1:] - 1]
    per_row = (starts[1:] - starts[:-1]) + (last - first + 2.0 * r) / du
    out: F64 = per_row * (2.0 * r / dv + 1.0)
    return out
