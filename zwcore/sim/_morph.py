"""Grey dilation by a structuring function symmetric in both axes, exact at the nodes.

``out[i, k] = max over (a, b) of z[i + a, k + b] + s[a, b]`` (nodes off the grid
hold -inf). The structuring function is mirror-symmetric in ``a`` and in ``b`` (every
tool profile is), so the four offsets ``(±a, ±b)`` share one value: per column offset
``b`` one pass folds ``z`` shifted by ``+b`` and ``-b`` (``X_b``), and each ``(a, b)``
then costs one fold of ``X_b`` shifted by ``±a``, one add and one max: three vector
passes for four offsets instead of eight. Output rows go in strips sized to stay in
the CPU cache, which keeps the cost linear in the grid at 2049² as at 513².

Arithmetic runs in float32 when the heights' span allows a rounding bound under
:data:`FLOAT32_MARGIN`, else in float64; inputs are rounded up and the result is
raised by the rounding bound, so the result is never below the exact max.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from numba import njit
from numpy.typing import NDArray

F64 = NDArray[np.float64]

#: Largest upward rounding (mm) accepted for float32 arithmetic; beyond it float64.
FLOAT32_MARGIN = 1.0e-5

#: Bytes of one strip array: small enough for the L2 cache of common CPUs.
_STRIP_BYTES = 1 << 18


def _round_up_f32(x: F64) -> NDArray[np.float32]:
    f = x.astype(np.float32)
    below = f.astype(np.float64) < x
    if below.any():
        f[below] = np.nextafter(f[below], np.float32(np.inf))
    return f


def _dilate_rows(zp: NDArray[np.floating], s: NDArray[np.floating], ny: int, nx: int,
                 threads: int | None = None) -> NDArray[np.floating]:
    """The symmetric dilation of a padded grid (``A`` rows, ``B`` columns of -inf each side)
    by each of ``V`` structuring functions ``s`` (V, 2A+1, 2B+1), least of the ``V`` results.

    An offset where all ``V`` functions agree is added once into a shared accumulator;
    only the offsets where they differ cost one add and max per function.
    """
    nv = s.shape[0]
    A, B = (s.shape[1] - 1) // 2, (s.shape[2] - 1) // 2
    dtype = zp.dtype
    acc = np.full((nv + 1, ny, nx), -np.inf, dtype=dtype)  # [0]: offsets all share
    rows = max(8, _STRIP_BYTES // (dtype.itemsize * max(nx, 1)))
    quarter = np.ascontiguousarray(s[:, A:, B:])
    alive = np.isfinite(quarter).any(axis=0)
    same = (quarter == quarter[:1]).all(axis=0) | ~np.isfinite(quarter).any(axis=0)
    # the live offsets column by column (``b`` ascending, then ``a``), as flat lists
    ob, oa = np.nonzero(alive.T)
    zc = np.ascontiguousarray(zp)
    obl, oal, shared = ob.astype(np.int64), oa.astype(np.int64), same.T[ob, oa].copy()

    def strips(r0: int, r1: int) -> None:
        _dilate_kernel(zc, quarter, obl, oal, shared, int(ny), int(nx), int(rows), acc,
                       r0, r1)

    # strips are independent (their own output rows): two threads take two runs of them
    # on a large dilation (the kernel releases the GIL), the same values
    strip_count = -(-ny // rows)
    two = (THREADS if threads is None else threads) > 1
    if two and strip_count >= 2 and ny * nx * max(ob.size, 1) >= THREAD_WORK:
        mid = (strip_count // 2) * rows
        with ThreadPoolExecutor(1, thread_name_prefix="zw-dilate") as pool:
            fut = pool.submit(strips, mid, ny)
            strips(0, mid)
            fut.result()
    else:
        strips(0, ny)
    return np.min(np.maximum(acc[0], acc[1:]), axis=0)


#: Node-offset pairs (output nodes times live offsets) from which a dilation's strips run
#: on two threads (below, starting the thread costs more than the second core saves).
THREAD_WORK = 1 << 24

#: Threads a large dilation uses: 2 where the process may run on two cores or more (its
#: affinity mask, not the machine's count; 1: one thread, the tests' and the bench's
#: reference).
THREADS = 2 if (len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity")
                else os.cpu_count() or 1) >= 2 else 1


@njit([f"void({t}[:, ::1], {t}[:, :, ::1], i8[::1], i8[::1], b1[::1], i8, i8, i8, "
        f"{t}[:, :, ::1], i8, i8)" for t in ("f4", "f8")], cache=True, nogil=True)
def _dilate_kernel(zp: NDArray[np.floating], quarter: NDArray[np.floating],
                   ob: NDArray[np.int64], oa: NDArray[np.int64], shared: NDArray[np.bool_],
                   ny: int, nx: int, rows: int, acc: NDArray[np.floating], r_lo: int,
                   r_hi: int) -> None:
    """The strips starting at ``r_lo, r_lo + rows, ...`` below ``r_hi`` (``r_lo`` a
    multiple of ``rows``: two threads take two runs of strips). Per strip of ``rows``
    output rows and column offset ``b``: ``X_b`` (the padded grid
    folded at ``±b``); then per output row and row offset ``a`` the fold of ``X_b`` at
    ``±a`` once, and per function one add and max into its accumulator. The same
    rounded adds, in the grid's own precision, as vector passes over whole strips would
    make (max is exact), with the folds kept in the cache instead of strip temporaries."""
    nv = quarter.shape[0]
    A, B = (zp.shape[0] - ny) // 2, (zp.shape[1] - nx) // 2
    X = np.empty((rows + 2 * A, nx), dtype=zp.dtype)
    Y = np.empty(nx, dtype=zp.dtype)
    for r0 in range(r_lo, min(r_hi, ny), rows):
        h = min(ny, r0 + rows) - r0
        n = 0
        while n < ob.size:
            b = ob[n]
            for r in range(h + 2 * A):
                zr = zp[r0 + r]
                xr = X[r]
                for k in range(nx):
                    u, w = zr[B + b + k], zr[B - b + k]
                    xr[k] = u if u > w else w
            m = n
            while m < ob.size and ob[m] == b:
                m += 1
            for r in range(h):
                for j in range(n, m):
                    a = oa[j]
                    x1 = X[A + a + r]
                    x2 = X[A - a + r]
                    for k in range(nx):
                        u, w = x1[k], x2[k]
                        Y[k] = u if u > w else w
                    for v in range(1 if shared[j] else nv):
                        value = quarter[v, a, b]
                        if not np.isfinite(value):
                            continue
                        tr = acc[0 if shared[j] else v + 1, r0 + r]
                        for k in range(nx):
                            t = Y[k] + value
                            if t > tr[k]:
                                tr[k] = t
            n = m


def _dilate_bounded(z: F64, s: F64, threads: int | None = None) -> tuple[F64, float]:
    """The dilation (least over a stack of functions) and its rounding bound ``delta``:
    exact <= out <= exact + 2 delta."""
    s = s[None] if s.ndim == 2 else s
    if not (np.array_equal(s, s[:, ::-1]) and np.array_equal(s, s[:, :, ::-1])):
        raise ValueError("structuring function must be mirror-symmetric in both axes")
    ny, nx = z.shape
    A, B = (s.shape[1] - 1) // 2, (s.shape[2] - 1) // 2
    # An offset whose value lies more than the heights' span below its function's centre
    # never wins (the centre's term is larger wherever both are on the grid): dropped,
    # the dilation is the same, and far-raised corners of drop profiles
    # (:mod:`._profiles`) do not widen the span that decides the float32 rounding.
    centre = s[:, A, B]
    if np.isfinite(centre).all():
        floor = centre - float(z.max() - z.min()) - 1.0
        s = np.where(s < floor[:, None, None], -np.inf, s)
    shift = float(z.max())
    span = float(shift - z.min()) + float(np.abs(s[np.isfinite(s)]).max(initial=0.0))
    # float32: inputs rounded up (1 ulp) and one rounded add (half an ulp) of values
    # below the span; float64: the shift back and the subtraction, a few ulps
    margin32 = 2.0 ** -22 * (span + 1.0)
    use32 = margin32 <= FLOAT32_MARGIN
    delta = (margin32 if use32 else 0.0) + 8.0 * float(np.finfo(np.float64).eps) * (
        abs(shift) + span + 1.0)
    dtype = np.float32 if use32 else np.float64
    zp = np.full((ny + 2 * A, nx + 2 * B), -np.inf, dtype=dtype)
    rel = z - shift
    if use32:
        zp[A:A + ny, B:B + nx] = _round_up_f32(rel)
        sd: NDArray[np.floating] = _round_up_f32(s)
    else:
        zp[A:A + ny, B:B + nx] = rel
        sd = s
    out = _dilate_rows(zp, sd, ny, nx, threads).astype(np.float64)
    out += shift + delta
    return out, delta


def dilate(z: F64, s: F64, threads: int | None = None) -> F64:
    """Grey dilation of ``z`` by the structuring function ``s``, never below the exact value.

    Parameters
    ----------
    z : (ny, nx) float64
        Finite heights; nodes beyond the grid count as -inf (no surface there).
    s : (2A + 1, 2B + 1) or (V, 2A + 1, 2B + 1) float64
        ``s[A + a, B + b]`` is added to ``z[i + a, k + b]``; -inf outside the element.
        Must be symmetric under ``a -> -a`` and ``b -> -b``. A stack of ``V``
        functions (each an upper bound of the same thing) gives the least of their
        dilations, cheaper than ``V`` runs where they share values.

    Returns
    -------
    (ny, nx) float64
        ``max over (a, b) of z[i + a, k + b] + s[A + a, B + b]``, raised by rounding
        by at most about twice :data:`FLOAT32_MARGIN`; -inf where the element meets no node.
    """
    return _dilate_bounded(z, s, threads)[0]


def erode(z: F64, e: F64) -> F64:
    """Grey erosion ``min over (a, b) of z[i + a, k + b] + e[A + a, B + b]``, rounded up.

    Parameters
    ----------
    z : (ny, nx) float64
    e : (2A + 1, 2B + 1) float64
        Additive profile, +inf outside the element, mirror-symmetric.

    Returns
    -------
    (ny, nx) float64
        Never below the exact value (the safe side for a machined surface), above it
        by at most about twice :data:`FLOAT32_MARGIN`; +inf where the element meets no node.
    """
    # min(z + e) = -max(-z - e): the dilation's upward rounding lands downward here
    out, delta = _dilate_bounded(-z, -e)
    return -out + 2.0 * delta
