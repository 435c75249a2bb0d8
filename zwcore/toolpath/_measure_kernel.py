"""A measure-only sweep for tools too narrow for block bounds: the gouge of each move against
one surface (:func:`measure_plain`), what :func:`~zwcore.toolpath._sweep_plain.plain_kernel`
returns as ``over_ref`` for moves that cut nothing, without the stock it also reads and
the node indices it gathers (the measure's stock is the part itself).

The nodes within reach of a move are gathered row by row as the plain kernel gathers them
and their envelope comes from the same function
(:func:`~zwcore.toolpath._sweep_plain._envelopes`, one call per move over all its
nodes), so every node's envelope, and so the maximum, is the plain kernel's bit for bit
(tests compare them); only the comparison reads the surface a row's contiguous run at a
time instead of through gathered indices.
"""

from __future__ import annotations

import itertools
import math
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from numba import njit
from numpy.typing import NDArray

from zwcore.toolpath._sweep_kernel import _move_box, _row_span
from zwcore.toolpath._sweep_plain import _envelopes

F64 = NDArray[np.float64]


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
        ylo, yhi = min(sy, sy + ay), max(sy, sy + ay)
        m = 0
        nr = 0
        for i in range(i0, i1 + 1):
            qy = y0 + i * dy
            ka, kb = _row_span(qy, x0, dx, k0, k1, sx, sy, ax, ay, ylo, yhi, r)
            if kb < ka:  # never a range from a huge negative bound (it would wrap around)
                continue
            wy = sy - qy
            sw = math.sqrt(max(r * r * (1.0 - 1e-10) - wy * wy, 0.0))
            first[nr], ks[nr], rows[nr] = m, ka, i * nx
            nr += 1
            for k in range(ka, kb + 1):
                wxs[m] = sx - (x0 + k * dx)
                wys[m] = wy
                sws[m] = sw
                m += 1
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
