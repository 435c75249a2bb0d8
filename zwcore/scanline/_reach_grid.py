"""Lattices of the reach estimate (:mod:`zwcore.scanline._regions`): a fine mask pooled
onto a coarser lattice, and a coarse lattice's rest carried onto a finer one."""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__: list[str] = []

F64 = NDArray[np.float64]
B8 = NDArray[np.bool_]


def _pool_any(fine: B8, k: int) -> B8:
    """``ndimage.maximum_filter(fine, size=k)[::k, ::k]`` for an even ``k`` (the window
    ``[i - k/2, i + k/2 - 1]`` about every ``k``-th node; the filter's reflected edges add
    nothing outside it), by blocks instead of a full-size filter: ``(ny, nx)`` bool to
    ``(ceil(ny / k), ceil(nx / k))``."""
    ny, nx = fine.shape
    h = k // 2
    my, mx = -(-ny // k), -(-nx // k)
    pad = np.zeros(((my + 1) * k, (mx + 1) * k), dtype=bool)
    pad[h:h + ny, h:h + nx] = fine
    blocks: B8 = np.asarray(pad.reshape(my + 1, k, mx + 1, k).any(axis=(1, 3)))
    return blocks[:my, :mx]


@njit("void(f8[:, :], f8[:, :], f8[:, :], i8, f8, f8[:, :])", cache=True, nogil=True)
def _upsample_kernel(coarse: F64, zc: F64, zf: F64, f: int, tol: float, out: F64) -> None:
    my, mx = coarse.shape
    ny, nx = out.shape
    for i in range(ny):
        a0 = min(i // f, my - 1)
        a1 = min(a0 + 1, my - 1)
        wa = (i % f) / f
        for k in range(nx):
            b0 = min(k // f, mx - 1)
            b1 = min(b0 + 1, mx - 1)
            wb = (k % f) / f
            c00, c01 = coarse[a0, b0], coarse[a0, b1]
            c10, c11 = coarse[a1, b0], coarse[a1, b1]
            if c00 > tol or c01 > tol or c10 > tol or c11 > tol:
                w00, w01 = (1.0 - wa) * (1.0 - wb), (1.0 - wa) * wb
                w10, w11 = wa * (1.0 - wb), wa * wb
                rest = c00 * w00 + c01 * w01 + c10 * w10 + c11 * w11
                closed = ((zc[a0, b0] + c00) * w00 + (zc[a0, b1] + c01) * w01
                          + (zc[a1, b0] + c10) * w10 + (zc[a1, b1] + c11) * w11)
                out[i, k] = min(rest, max(closed - zf[i, k], 0.0))
            else:
                out[i, k] = 0.0


def _plain(a: NDArray[np.floating]) -> F64:
    """``a`` as a writable C-ordered float64 array (the kernels' signatures; a read-only
    grid, a stored z-map say, is copied)."""
    return np.require(a, dtype=np.float64, requirements=["C", "W"])


def _upsample_where(coarse: F64, zc: F64, f: int, zf: F64, tol: float) -> F64:
    """A coarse lattice's rest ``(my, mx)`` (over the part ``zc`` there) at the fine
    lattice's nodes ``zf`` ``(ny, nx)`` (``f`` times finer), where a cell corner exceeds
    ``tol`` (0 elsewhere: there the interpolant is at most ``tol`` anyway), in one
    compiled pass: the lesser of the rest interpolated bilinearly and the closing
    (part plus rest) interpolated bilinearly less the fine part. Each alone makes up
    material: the rest interpolated across a narrow slot's edge stands over the plate
    beside it, the closing's chord over a concave wall stands above the wall."""
    out = np.empty(zf.shape)
    _upsample_kernel(_plain(coarse), _plain(zc), _plain(zf), int(f), float(tol), out)
    return out
