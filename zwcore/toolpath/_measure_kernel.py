"""Measure-only sweeps: the gouge of each move against one surface (the part), what the
sweep kernels return as ``over_ref`` for moves that cut nothing, without the stock they
also read and keep.

**Tools too narrow for block bounds** (:func:`measure_plain`): what
:func:`~zwcore.toolpath._sweep_plain.plain_kernel` returns, without the stock. The nodes
within reach of a move are gathered row by row by the plain kernel's own gathering
(:func:`~zwcore.toolpath._sweep_plain.gather`, inlined into both) and their envelope comes
from the same function (:func:`~zwcore.toolpath._sweep_plain._envelopes`, one call per
move over all its nodes), so every node's envelope, and so the maximum, is the plain
kernel's bit for bit (tests compare them); both read the surface a row's contiguous run
at a time.

**Tools with block bounds** (:func:`measure_bounded`): the sweep kernel's values wherever
they are positive (the only ones a path reads: a lift, a split), for less. The part's
block bounds cost a scan-line chord much of its time (a Ø20 ball's short finishing chords:
some 40 coarse and 180 block bounds a chord, bounded alone), and the chords come
chained along grid lines: a group of them (:func:`_group_end`, at most
:data:`GROUP_MAX`) is bounded once as the straight move from its first start to its last
end lowered by the group's sag (at most :data:`GROUP_SAG` under it: a chord's envelope lies
at most that much under the straight move's), and each chord bounds only the blocks the
group keeps. Per chord the block of the largest bound is read first: what it finds
(positive where the chord gouges) clears every block whose bound lies below, and the
sweep kernel's runs without the stock (:func:`_kept_runs`, the nodes' values from the
same :func:`~zwcore.toolpath._sweep_kernel._row_run`) read the rest; the row spans are
worked out only over the candidate blocks' rows.
"""

from __future__ import annotations

import itertools
import math
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np
from numba import njit, uint64
from numpy.typing import NDArray

from zwcore.toolpath._sweep_kernel import (
    MARGIN,
    TIE_REACH,
    VECTOR,
    _max_of,
    _move_box,
    _spans,
    move_constants,
    plane_bound,
    run_envelope,
    segment_distance2,
)
from zwcore.toolpath._sweep_plain import _envelopes, gather
from zwcore.toolpath.sweep import BlockBounds, GridFrame

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]


@njit(cache=True, nogil=True, fastmath={"contract", "arcp", "reassoc"})
def measure_plain(x0: float, y0: float, dx: float, dy: float, p0: F64, p1: F64, r: float,
                  ball: bool, ref: F64, out: F64) -> None:
    """``out[s]``: the largest ``ref`` minus the envelope of move ``p0[s] -> p1[s]`` over
    the nodes it reaches (``-inf``: none), tool radius ``r``."""
    ny, nx = ref.shape
    rflat = ref.reshape(-1)
    cap = 1024
    wxs, wys, env, sws = np.empty(cap), np.empty(cap), np.empty(cap), np.empty(cap)
    first = np.empty(ny, np.int64)  # per row of the move's box: where its run starts
    ks = np.empty(ny, np.int64)
    rows = np.empty(ny, np.int64)
    for s in range(p0.shape[0]):
        sx, sy, sz = p0[s, 0], p0[s, 1], p0[s, 2]
        ax, ay, vz = p1[s, 0] - sx, p1[s, 1] - sy, p1[s, 2] - sz
        k0, k1, i0, i1 = _move_box(x0, y0, dx, dy, nx, 0, ny, sx, sy, ax, ay, r)
        out[s] = -math.inf
        if k1 < k0 or i1 < i0:
            continue
        box = (k1 - k0 + 1) * (i1 - i0 + 1)
        if box > cap:
            cap = 2 * box
            wxs, wys, env, sws = np.empty(cap), np.empty(cap), np.empty(cap), np.empty(cap)
        m, nr = gather(x0, y0, dx, dy, nx, k0, k1, i0, i1, sx, sy, ax, ay, r, wxs, wys, sws,
                       first, ks, rows)
        _envelopes(m, wxs, wys, sws, sx, sy, sz, ax, ay, vz, r, ball, env)
        best = -math.inf
        for t in range(nr):
            j0 = first[t]
            j1 = first[t + 1] if t + 1 < nr else m
            base = rows[t] + ks[t] - j0
            for j in range(j0, j1):
                best = max(best, rflat[base + j] - env[j])
        out[s] = best


def measure_moves(x0: float, y0: float, dx: float, dy: float, p0: F64, p1: F64,
                  radius: float, ball: bool, ref: F64) -> F64:
    """:func:`measure_plain` of every move, in chunks on the sweep's threads (as
    :func:`~zwcore.toolpath.sweep.sweep_moves` runs measurements: the kernel releases the
    GIL, and each move's value is its own).

    Returns
    -------
    (n,) float64
        Per move, the largest ``ref`` minus its envelope over the nodes it reaches (> 0: it
        gouges by that much); ``-inf`` where it reaches none.
    """
    from zwcore.toolpath import sweep as sweep_mod  # its thread settings, as tests set them

    p0 = np.ascontiguousarray(p0, dtype=np.float64).reshape(-1, 3)
    p1 = np.ascontiguousarray(p1, dtype=np.float64).reshape(-1, 3)
    ref = np.ascontiguousarray(ref, dtype=np.float64)
    n = len(p0)
    out = np.empty(n)
    args = (float(x0), float(y0), float(dx), float(dy))
    threads = min(sweep_mod.SWEEP_THREADS, max(1, n // sweep_mod.MIN_MOVES_PER_THREAD))
    if threads <= 1:
        measure_plain(*args, p0, p1, float(radius), bool(ball), ref, out)
        return out
    cut = np.linspace(0, n, min(n, threads * sweep_mod.BANDS_PER_THREAD) + 1).astype(np.int64)
    with ThreadPoolExecutor(threads) as pool:
        list(pool.map(lambda ac: measure_plain(*args, p0[ac[0]:ac[1]], p1[ac[0]:ac[1]],
                                               float(radius), bool(ball), ref,
                                               out[ac[0]:ac[1]]),
                      itertools.pairwise(cut)))
    return out


@njit(cache=True, nogil=True, fastmath={"contract", "arcp", "reassoc"})
def block_bound(bx: float, by: float, hx: float, hy: float, pxb: float, pyb: float,
                e: float, m: float, sx: float, sy: float, sz: float, ax: float, ay: float,
                vz: float, r: float, ball: bool, hd: float) -> float:
    """An upper bound of ``U - env`` over the nodes of a block for one move (``-inf``: it
    reaches none): the least of the bounds
    :func:`~zwcore.toolpath._sweep_kernel.skip_block` tests against ``-MARGIN``, as
    values (a caller compares them with other thresholds): ``m`` less the move's lowest
    tip height (the envelope
    never lies under the tip), for a ball the rim bound (a node at least ``d`` from the
    move's segment sees the ball no lower than ``zlow + R - sqrt(R² - d²)``), and off the
    vertical the tangent-plane bound (the envelope is convex on the move's footprint:
    :mod:`zwcore.toolpath.sweep`); ``hd``: at least the block's half diagonal."""
    a, inv_a, _, kz, _, zlow, slack = move_constants(sx, sy, sz, ax, ay, vz, r)
    low = m - zlow  # the envelope never dips below the lowest tip height
    if low < -MARGIN:
        return low
    # the block's distance from the segment, at least: its centre's, less its half diagonal
    dc2 = segment_distance2(bx, by, sx, sy, ax, ay, a, inv_a)
    if dc2 > ((r + hd) * (1.0 + 1e-12)) ** 2:  # the footprint misses the block: no node
        return -math.inf
    if not ball:
        return low
    if dc2 > hd * hd:  # the rim bound (the slack under the root: a node's d² rounding)
        dblk = min(math.sqrt(dc2) - hd, r)
        low = min(low, m - (zlow + r - math.sqrt(max(r * r - dblk * dblk, 0.0) + slack)))
        if low < -MARGIN:
            return low
    if a <= 1e-18:
        return low
    return min(low, plane_bound(bx, by, hx, hy, pxb, pyb, e, sx, sy, sz, ax, ay, vz, r, a,
                                inv_a, kz))


@njit(cache=True, nogil=True, fastmath={"contract", "arcp", "reassoc"})
def _block_nodes(x0: float, y0: float, dx: float, dy: float, b: int, i0: int, i1: int,
                 rka: I64, rkb: I64, rsw: F64, bi: int, bk: int, sx: float, sy: float,
                 sz: float, ax: float, ay: float, vz: float, r: float, ball: bool,
                 rflat: F64, nx: int, env: F64) -> float:
    """The largest ``ref`` minus envelope over the nodes of block ``(bi, bk)`` within the
    move's row spans (``-inf``: none), each row's run as the sweep kernel's runs compute
    it (:func:`~zwcore.toolpath._sweep_kernel._row_run`: the same values bit for bit)."""
    best = -math.inf
    vertical = ax * ax + ay * ay <= 1e-18
    _, inv_a, inv_sa, kz, aa, _, _ = move_constants(sx, sy, sz, ax, ay, vz, r)
    reach2 = r * r * TIE_REACH
    for i in range(max(i0, bi * b), min(i1, bi * b + b - 1) + 1):
        ka, kb = max(bk * b, rka[i - i0]), min(bk * b + b - 1, rkb[i - i0])
        if kb < ka:  # never a range from a huge negative bound (it would wrap)
            continue
        n = kb - ka + 1
        wy = sy - (y0 + i * dy)
        run_envelope(n, ka, vertical, sx, sy, x0, dx, wy, rsw[i - i0], sz, ax, ay, vz, r,
                     ball, env, inv_a, inv_sa, kz, aa, reach2)  # as the sweep kernel's runs
        row = i * nx + ka
        for j in range(n):
            best = max(best, rflat[row + j] - env[j])
    return best


@njit(cache=True, nogil=True, fastmath={"contract", "arcp", "reassoc"})
def _kept_runs(x0: float, y0: float, dx: float, dy: float, b: int, i0: int, i1: int, k0: int,
               k1: int, rka: I64, rkb: I64, rsw: F64, sx: float, sy: float, sz: float,
               ax: float, ay: float, vz: float, r: float, ball: bool, rflat: F64, nx: int,
               keep: NDArray[np.bool_], env: F64, dr: F64) -> float:
    """The largest ``ref`` minus envelope over the nodes of the blocks marked in ``keep``:
    :func:`~zwcore.toolpath._sweep_kernel._runs` without the stock (each run of kept
    blocks side by side in a row one contiguous stretch of nodes, its envelope from
    :func:`~zwcore.toolpath._sweep_kernel._row_run`: the same values bit for bit; the
    differences into ``dr``, room for every node of the box and one more, their maximum
    by :func:`~zwcore.toolpath._sweep_kernel._max_of`)."""
    pos = 0
    vertical = ax * ax + ay * ay <= 1e-18
    _, inv_a, inv_sa, kz, aa, _, _ = move_constants(sx, sy, sz, ax, ay, vz, r)
    reach2 = r * r * TIE_REACH
    for bi in range(i0 // b, i1 // b + 1):
        bk = k0 // b
        while bk <= k1 // b:
            if not keep[bi, bk]:
                bk += 1
                continue
            bk_end = bk
            while bk_end + 1 <= k1 // b and keep[bi, bk_end + 1]:
                bk_end += 1
            for i in range(max(i0, bi * b), min(i1, bi * b + b - 1) + 1):
                ka, kb = max(bk * b, rka[i - i0]), min(bk_end * b + b - 1, rkb[i - i0])
                if kb < ka:  # never a range from a huge negative bound (it would wrap)
                    continue
                n = kb - ka + 1
                wy = sy - (y0 + i * dy)
                run_envelope(n, ka, vertical, sx, sy, x0, dx, wy, rsw[i - i0], sz, ax, ay, vz,
                             r, ball, env, inv_a, inv_sa, kz, aa, reach2)
                row = i * nx + ka
                for j in range(n):  # the maximum once per move: this loop vectorises
                    dr[uint64(pos + j)] = rflat[uint64(row + j)] - env[j]
                pos += n
            bk = bk_end + 1
    return _max_of(dr, pos)


#: Most moves measured as one group (:func:`_group_end`).
GROUP_MAX = 8
#: Largest sag (mm) of a group's moves below the straight move from its first start to its
#: last end: the group's block bound is raised by it, so a larger sag clears fewer blocks.
GROUP_SAG = 0.05


@njit(cache=True, nogil=True)
def _group_end(p0: F64, p1: F64, s: int, gmax: int, sag: float) -> tuple[int, float]:
    """``e, delta``: moves ``s..e - 1`` chain (each starts where the one before ends) on
    one line of the grid (``y`` fixed and ``x`` running one way, or the other way round),
    and every one's tip lies at most ``delta`` (``<= sag``, with a rounding slack) under the
    straight move from ``p0[s]`` to ``p1[e - 1]`` at the same point: over any node, each
    move's envelope lies at most ``delta`` under that move's (the tool at a point of a move
    is the tool at the same point of the straight move, lowered by at most ``delta``)."""
    n = p0.shape[0]
    dx0, dy0 = p1[s, 0] - p0[s, 0], p1[s, 1] - p0[s, 1]
    if dx0 != 0.0 and dy0 == 0.0:
        w, o = 0, 1  # along x
    elif dy0 != 0.0 and dx0 == 0.0:
        w, o = 1, 0
    else:
        return s + 1, 0.0
    up = (p1[s, w] - p0[s, w]) > 0.0
    e, delta = s + 1, 0.0
    while e < n and e - s < gmax:
        if not (p0[e, 0] == p1[e - 1, 0] and p0[e, 1] == p1[e - 1, 1]
                and p0[e, 2] == p1[e - 1, 2] and p1[e, o] == p0[e, o]
                and ((p1[e, w] - p0[e, w]) > 0.0) == up and p1[e, w] != p0[e, w]):
            break
        # the sag of moves s..e under the straight move p0[s] -> p1[e]: the gap is linear
        # along each move, so its largest value is at a vertex between two moves
        pw, pz = p0[s, w], p0[s, 2]
        slope = (p1[e, 2] - pz) / (p1[e, w] - pw)
        d = 0.0
        for t in range(s, e):
            d = max(d, pz + (p1[t, w] - pw) * slope - p1[t, 2])
        d += 1e-12 * (1.0 + abs(pz) + abs(p1[e, 2]))  # the gap's own rounding
        if d > sag:
            break
        delta = d
        e += 1
    return e, delta


@njit(cache=True, nogil=True, fastmath={"contract", "arcp", "reassoc"})
def measure_bounded(x0: float, y0: float, dx: float, dy: float, p0: F64, p1: F64, r: float,
                    ball: bool, ref: F64, above: F64, b: int, f: int, cx: F64, cy: F64,
                    hx: F64, hy: F64, st: F64, ccx: F64, ccy: F64, chx: F64, chy: F64,
                    cst: F64, out: F64, gmax: int, sag: float) -> None:
    """``out[s]``: the gouge of move ``p0[s] -> p1[s]`` against ``ref`` (block bounds of
    ``ref`` against itself): the sweep kernel's value wherever it is positive, else a value
    ``<= 0`` or ``-inf``.

    Moves that chain along one grid line are taken in groups (:func:`_group_end`): the
    blocks :func:`block_bound` cannot clear for the group's straight move, its bound raised
    by the group's sag, are found once (coarse blocks first), and each move of the group
    tests only those. Per move, the block of the largest bound is read first; then the
    others whose bound is not below the largest value found (less ``MARGIN``: those below
    hold no larger one, so a positive result is the exact maximum), as the sweep kernel
    reads them (:func:`_kept_runs`: the same node values bit for bit; the row spans of the
    candidates' rows only). A move whose first block already exceeds ``above[s]`` stops
    there (a lower bound over the threshold: its caller needs no more)."""
    ny, nx = ref.shape
    rflat = ref.reshape(-1)
    nb = st.shape[0] * st.shape[1]
    gb = np.empty(nb)
    gbi = np.empty(nb, np.int64)
    gbk = np.empty(nb, np.int64)
    cand = np.empty(nb)
    cbi = np.empty(nb, np.int64)
    cbk = np.empty(nb, np.int64)
    env = np.empty(b + VECTOR)  # (runs padded to whole vector widths)
    wide = np.empty(nx + VECTOR)
    keep = np.zeros((st.shape[0], st.shape[1]), np.bool_)
    rka, rkb = np.empty(ny, np.int64), np.empty(ny, np.int64)
    rsw = np.empty(ny)
    big = b * f
    # the largest half diagonal of a block and of a coarse block (the last ones are cut)
    hdf = math.sqrt(np.max(hx) ** 2 + np.max(hy) ** 2)
    hdc = math.sqrt(np.max(chx) ** 2 + np.max(chy) ** 2)
    dr = np.empty(1024)  # per move, grown to its box (:func:`_kept_runs`)
    g = 0
    while g < p0.shape[0]:
        e, delta = _group_end(p0, p1, g, gmax, sag)
        # the group's straight move: its blocks that may hold a positive value
        gx, gy, gz = p0[g, 0], p0[g, 1], p0[g, 2]
        gax, gay, gvz = p1[e - 1, 0] - gx, p1[e - 1, 1] - gy, p1[e - 1, 2] - gz
        ng = 0
        k0, k1, i0, i1 = _move_box(x0, y0, dx, dy, nx, 0, ny, gx, gy, gax, gay, r)
        if k1 >= k0 and i1 >= i0:
            for ci in range(i0 // big, i1 // big + 1):
                for ck in range(k0 // big, k1 // big + 1):
                    cb = delta + block_bound(ccx[ck], ccy[ci], chx[ck], chy[ci],
                                             cst[ci, ck, 0], cst[ci, ck, 1], cst[ci, ck, 2],
                                             cst[ci, ck, 3], gx, gy, gz, gax, gay, gvz, r,
                                             ball, hdc)
                    if cb < -MARGIN:
                        continue
                    for bi in range(max(i0 // b, ci * f), min(i1 // b, ci * f + f - 1) + 1):
                        for bk in range(max(k0 // b, ck * f),
                                        min(k1 // b, ck * f + f - 1) + 1):
                            fb = min(cb, delta + block_bound(
                                cx[bk], cy[bi], hx[bk], hy[bi], st[bi, bk, 0],
                                st[bi, bk, 1], st[bi, bk, 2], st[bi, bk, 3], gx, gy, gz,
                                gax, gay, gvz, r, ball, hdf))
                            if fb < -MARGIN:
                                continue
                            gb[ng], gbi[ng], gbk[ng] = fb, bi, bk
                            ng += 1
        for s in range(g, e):
            sx, sy, sz = p0[s, 0], p0[s, 1], p0[s, 2]
            ax, ay, vz = p1[s, 0] - sx, p1[s, 1] - sy, p1[s, 2] - sz
            out[s] = -math.inf
            k0, k1, i0, i1 = _move_box(x0, y0, dx, dy, nx, 0, ny, sx, sy, ax, ay, r)
            if k1 < k0 or i1 < i0 or not ng:
                continue
            if e - g == 1:  # a move alone: the group's blocks are its own
                nt = ng
                cand[:ng], cbi[:ng], cbk[:ng] = gb[:ng], gbi[:ng], gbk[:ng]
            else:
                nt = 0
                for t in range(ng):
                    bi, bk = gbi[t], gbk[t]
                    if bi < i0 // b or bi > i1 // b or bk < k0 // b or bk > k1 // b:
                        continue
                    fb = min(gb[t], block_bound(cx[bk], cy[bi], hx[bk], hy[bi],
                                                st[bi, bk, 0], st[bi, bk, 1], st[bi, bk, 2],
                                                st[bi, bk, 3], sx, sy, sz, ax, ay, vz, r, ball,
                                                hdf))
                    if fb < -MARGIN:
                        continue
                    cand[nt], cbi[nt], cbk[nt] = fb, bi, bk
                    nt += 1
            if not nt:
                continue
            # the row spans of the candidates' rows only (the box's other rows are not read)
            lo_b, hi_b = cbi[0], cbi[0]
            for t in range(1, nt):
                lo_b, hi_b = min(lo_b, cbi[t]), max(hi_b, cbi[t])
            i0, i1 = max(i0, lo_b * b), min(i1, hi_b * b + b - 1)
            _spans(x0, y0, dx, dy, i0, i1, i0, k0, k1, sx, sy, ax, ay, r, 0.0, 0.0, -math.inf,
                   rka, rkb, rsw)
            # the block of the largest bound first: where a move gouges it mostly gouges
            # most, and what it finds there clears every block whose bound lies below
            top = 0
            for t in range(1, nt):
                if cand[t] > cand[top]:
                    top = t
            best = _block_nodes(x0, y0, dx, dy, b, i0, i1, rka, rkb, rsw, cbi[top],
                                cbk[top], sx, sy, sz, ax, ay, vz, r, ball, rflat, nx, env)
            if best > above[s]:
                out[s] = best
                continue
            # the others that may hold more, as the sweep kernel reads them (runs of blocks
            # side by side in a row: long contiguous stretches of nodes)
            floor = max(best, 0.0) - MARGIN
            more = False
            for t in range(nt):
                if t != top and cand[t] >= floor:
                    keep[cbi[t], cbk[t]] = True
                    more = True
            if more:
                if (k1 - k0 + 2) * (i1 - i0 + 1) > len(dr):  # every node of the box, + 1
                    dr = np.empty(2 * (k1 - k0 + 2) * (i1 - i0 + 1))
                rest = _kept_runs(x0, y0, dx, dy, b, i0, i1, k0, k1, rka, rkb, rsw, sx, sy,
                                  sz, ax, ay, vz, r, ball, rflat, nx, keep, wide, dr)
                best = max(best, rest)
                for t in range(nt):
                    keep[cbi[t], cbk[t]] = False
            out[s] = best
        g = e


def measure_moves_bounded(frame: GridFrame, p0: F64, p1: F64, radius: float, ball: bool,
                          ref: F64, bounds: BlockBounds, above: F64 | None = None) -> F64:
    """:func:`measure_bounded` of every move, in chunks on the sweep's threads.

    Parameters
    ----------
    frame : GridFrame
    p0, p1 : (n, 3) float64
    radius : float
    ball : bool
    ref : (ny, nx) float64
        The part.
    bounds : BlockBounds
        Of ``ref`` against itself (never remeasured: nothing is cut).
    above : (n,) float64, optional
        Per move, a threshold: a move that gouges by more may get a lower bound above it
        instead of its exact gouge (default: none, every positive value exact).

    Returns
    -------
    (n,) float64
        Per move, its gouge against ``ref``: ``> 0`` exact (or, above its threshold, a
        lower bound above it), else ``<= 0`` or ``-inf``.
    """
    from zwcore.toolpath import sweep as sweep_mod  # its thread settings, as tests set them

    p0 = np.ascontiguousarray(p0, dtype=np.float64).reshape(-1, 3)
    p1 = np.ascontiguousarray(p1, dtype=np.float64).reshape(-1, 3)
    n = len(p0)
    thr = (np.full(n, np.inf) if above is None
           else np.ascontiguousarray(above, dtype=np.float64).reshape(n))
    ref = np.ascontiguousarray(ref, dtype=np.float64)
    out = np.empty(n)
    if not n:
        return out
    bb = bounds
    args = (float(frame.x0), float(frame.y0), float(frame.dx), float(frame.dy))
    tail = (int(bb.block), int(bb.coarse), bb.cx, bb.cy, bb.hx, bb.hy, bb.st, bb.ccx, bb.ccy,
            bb.chx, bb.chy, bb.cst)
    kernel: Any = measure_bounded  # (numba's dispatcher types no arguments)
    threads = min(sweep_mod.SWEEP_THREADS, max(1, n // sweep_mod.MIN_MOVES_PER_THREAD))
    if threads <= 1:
        kernel(*args, p0, p1, float(radius), bool(ball), ref, thr, *tail, out, GROUP_MAX,
               GROUP_SAG)
        return out
    cut = np.linspace(0, n, min(n, threads * sweep_mod.BANDS_PER_THREAD) + 1).astype(np.int64)
    with ThreadPoolExecutor(threads) as pool:
        list(pool.map(lambda ac: kernel(*args, p0[ac[0]:ac[1]], p1[ac[0]:ac[1]],
                                        float(radius), bool(ball), ref, thr[ac[0]:ac[1]],
                                        *tail, out[ac[0]:ac[1]], GROUP_MAX, GROUP_SAG),
                      itertools.pairwise(cut)))
    return out
