"""The plain sweep: every node within a tool's reach of each move gathered into flat arrays,
the closed-form envelope over them in one vectorised loop, then the stock compared and
lowered. No block bounds, no runs: the reference :func:`~zwcore.toolpath._sweep_kernel.
sweep_kernel` is tested against (its envelope formulas are written out again here, so the
two share only :func:`~zwcore.toolpath._sweep_kernel.node_envelope` and the row spans), and
the sweep of tools too narrow for block bounds.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from zwcore.toolpath._sweep_kernel import TIE_REACH, _move_box, _row_span, node_envelope

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

# The per-node envelope loops are compiled without FMA contraction or reassociation: a
# node's place in the gathered arrays depends on the rows gathered (a thread's band, or the
# whole grid), and with contraction the vector body and the loop's scalar tail round one
# ulp apart, so a threaded sweep differed from the single-thread one. IEEE per lane costs
# ~5 % of the plain sweep.
_PER_NODE = {"nsz"}


@njit(cache=True, nogil=True, fastmath=_PER_NODE,
      inline="always")
def _lowest(t0: float, dmin2: float, sw: float, sz: float, vz: float, r: float, ball: bool,
            inv_sa: float, kz: float, a: float) -> tuple[float, float, float]:
    """The tool's lowest height over one node and the move's reached stretch ``lo, hi``
    (written apart from the block kernel's on purpose: this module is its reference)."""
    half = sw * inv_sa
    lo, hi = max(0.0, t0 - half), min(1.0, t0 + half)
    if ball:
        ts = min(max(t0 - vz * sw * kz, lo), hi)
        d2 = a * (ts - t0) ** 2 + dmin2
        e = sz + vz * ts + r - math.sqrt(max(r * r - d2, 0.0))
    else:
        e = sz + vz * (lo if vz >= 0.0 else hi)
    return e, lo, hi


@njit(cache=True, nogil=True, fastmath=_PER_NODE)
def flat_envelope(m: int, wxs: F64, wys: F64, sz: float, ax: float, ay: float, vz: float,
                  r: float, ball: bool, inv_a: float, inv_sa: float, kz: float, env: F64
                  ) -> None:
    """``env[j]`` over the ``m`` gathered nodes (offsets ``wxs, wys`` from the move's start)
    of one (not vertical) move: the closed form of :func:`node_envelope` without branches
    (unreached nodes get ``inf``), one flat loop so that it vectorises."""
    a = 1.0 / inv_a
    reach2 = r * r * TIE_REACH
    for j in range(m):
        wx, wy = wxs[j], wys[j]
        c = wx * wx + wy * wy
        b = ax * wx + ay * wy
        t0 = -b * inv_a
        dmin2 = max(c + b * t0, 0.0)
        w2 = reach2 - dmin2
        sw = math.sqrt(max(w2, 0.0))
        e, lo, hi = _lowest(t0, dmin2, sw, sz, vz, r, ball, inv_sa, kz, a)
        env[j] = e if (w2 > 0.0 and lo <= hi) else math.inf


@njit(cache=True, nogil=True, fastmath=_PER_NODE)
def row_envelope(m: int, wxs: F64, wys: F64, sws: F64, sz: float, ax: float, vz: float,
                 r: float, ball: bool, inv_a: float, inv_sa: float, kz: float, env: F64
                 ) -> None:
    """:func:`flat_envelope` of a move along x (``ay = 0``): a node's distance from the
    move's line is ``|w_y|``, and ``sws[j] = sqrt(R² TIE_REACH - w_y²)`` (clamped at 0)
    comes once per row from the gathering, so one root per node is left."""
    a = 1.0 / inv_a
    reach2 = r * r * TIE_REACH
    for j in range(m):
        wy = wys[j]
        t0 = -ax * wxs[j] * inv_a
        dmin2 = wy * wy
        sw = sws[j]
        e, lo, hi = _lowest(t0, dmin2, sw, sz, vz, r, ball, inv_sa, kz, a)
        env[j] = e if (dmin2 < reach2 and lo <= hi) else math.inf


@njit(cache=True, nogil=True, fastmath={"contract", "arcp", "reassoc"})
def _envelopes(m: int, wxs: F64, wys: F64, sws: F64, sx: float, sy: float, sz: float,
               ax: float, ay: float, vz: float, rr: float, ball: bool, env: F64) -> None:
    """``env[j]`` of the ``m`` gathered nodes for one move: :func:`node_envelope` per node
    for a vertical move, :func:`row_envelope` along x (``sws`` from the gathering), else
    :func:`flat_envelope`."""
    a = ax * ax + ay * ay
    if a <= 1e-18:
        for j in range(m):
            env[j] = node_envelope(sx - wxs[j], sy - wys[j], sx, sy, sz, ax, ay, vz, rr, ball)
    elif m and ay == 0.0:
        inv_a = 1.0 / a
        row_envelope(m, wxs, wys, sws, sz, ax, vz, rr, ball, inv_a, math.sqrt(inv_a),
                     1.0 / math.sqrt(a * (a + vz * vz)), env)
    elif m:
        inv_a = 1.0 / a
        flat_envelope(m, wxs, wys, sz, ax, ay, vz, rr, ball, inv_a, math.sqrt(inv_a),
                      1.0 / math.sqrt(a * (a + vz * vz)), env)


@njit(cache=True, nogil=True, fastmath={"contract", "arcp", "reassoc"}, inline="always")
def gather(x0: float, y0: float, dx: float, dy: float, nx: int, k0: int, k1: int, i0: int,
           i1: int, sx: float, sy: float, ax: float, ay: float, r: float, wxs: F64, wys: F64,
           sws: F64, first: I64, ks: I64, rows: I64) -> tuple[int, int]:
    """The nodes within ``r`` of a move's xy shadow, row by row over its box (rows
    ``i0..i1``, columns ``k0..k1``): their offsets ``wxs, wys`` from the move's start and
    each row's ``sws = sqrt(r² TIE_REACH - w_y²)`` (clamped at 0), for :func:`_envelopes`;
    per row that has any, ``first`` (where its nodes start in the gathered arrays), ``ks``
    (its first column) and ``rows`` (``i * nx``). Returns the nodes ``m`` and the rows
    ``nr`` gathered. Inlined into both kernels that gather (:func:`plain_kernel` and the
    measure-only :func:`~zwcore.toolpath._measure_kernel.measure_plain`): the same
    nodes, the same offsets."""
    ylo, yhi = min(sy, sy + ay), max(sy, sy + ay)
    m = 0
    nr = 0
    for i in range(i0, i1 + 1):
        qy = y0 + i * dy
        ka, kb = _row_span(qy, x0, dx, k0, k1, sx, sy, ax, ay, ylo, yhi, r)
        if kb < ka:  # never a range from a huge negative bound (it would wrap around)
            continue
        wy = sy - qy
        sw = math.sqrt(max(r * r * TIE_REACH - wy * wy, 0.0))
        first[nr], ks[nr], rows[nr] = m, ka, i * nx
        nr += 1
        for k in range(ka, kb + 1):
            wxs[m] = sx - (x0 + k * dx)
            wys[m] = wy
            sws[m] = sw
            m += 1
    return m, nr


@njit(cache=True, nogil=True, fastmath={"contract", "arcp", "reassoc"})
def plain_kernel(x0: float, y0: float, dx: float, dy: float, p0: F64, p1: F64, r: F64,
                 ball: bool, apply: NDArray[np.bool_], stock: F64, ref: F64,
                 over_stock: F64, over_ref: F64, row_lo: int, row_hi: int) -> None:
    """Moves in order over the rows ``row_lo..row_hi - 1`` (a band: bands are independent).

    Per move: gather the nodes within R of its xy shadow (row by row, :func:`gather`),
    evaluate the envelope over all of them in one flat loop, then compare with and lower
    the stock, a row's contiguous run of nodes at a time."""
    nx = stock.shape[1]
    sflat = stock.reshape(-1)
    rflat = ref.reshape(-1)
    cap = 1024
    wxs, wys, env, sws = np.empty(cap), np.empty(cap), np.empty(cap), np.empty(cap)
    first = np.empty(stock.shape[0], np.int64)  # per row of the move's box: its run
    ks = np.empty(stock.shape[0], np.int64)
    rows = np.empty(stock.shape[0], np.int64)
    for s in range(p0.shape[0]):
        sx, sy, sz = p0[s, 0], p0[s, 1], p0[s, 2]
        ax, ay, vz = p1[s, 0] - sx, p1[s, 1] - sy, p1[s, 2] - sz
        rr = r[s]
        k0, k1, i0, i1 = _move_box(x0, y0, dx, dy, nx, row_lo, row_hi, sx, sy, ax, ay, rr)
        over_stock[s] = over_ref[s] = -math.inf
        if k1 < k0 or i1 < i0:
            continue
        box = (k1 - k0 + 1) * (i1 - i0 + 1)
        if box > cap:
            cap = 2 * box
            wxs, wys, env, sws = np.empty(cap), np.empty(cap), np.empty(cap), np.empty(cap)
        m, nr = gather(x0, y0, dx, dy, nx, k0, k1, i0, i1, sx, sy, ax, ay, rr, wxs, wys, sws,
                       first, ks, rows)
        _envelopes(m, wxs, wys, sws, sx, sy, sz, ax, ay, vz, rr, ball, env)
        best_s, best_r = -math.inf, -math.inf
        cut = apply[s]
        for t in range(nr):
            j0 = first[t]
            j1 = first[t + 1] if t + 1 < nr else m
            base = rows[t] + ks[t] - j0  # node ``base + j`` for gathered ``j``
            if cut:
                for j in range(j0, j1):
                    q, e = base + j, env[j]
                    best_s = max(best_s, sflat[q] - e)
                    best_r = max(best_r, rflat[q] - e)
                    sflat[q] = min(sflat[q], e)
            else:
                for j in range(j0, j1):
                    q, e = base + j, env[j]
                    best_s = max(best_s, sflat[q] - e)
                    best_r = max(best_r, rflat[q] - e)
        over_stock[s] = best_s
        over_ref[s] = best_r
