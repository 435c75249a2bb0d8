"""Fast single-knot analysis step and grid extremes (private; see :mod:`zwcore.mrr._pyramid`).

The same floating-point operations as ``_hat_split`` in :mod:`zwcore.mrr.wavelets`
on an edge-padded grid, strip by strip, on the shared two-thread schedule of
:mod:`zwcore.mrr._pyramid` (its knobs, read at call time, govern both kernels).
Single-knot bands are computed level by level (each level's guard needs the
previous level's extremes), each strip reading the two rows of halo it needs.
"""

from __future__ import annotations

from functools import partial

import numpy as np
from numpy.typing import NDArray

from zwcore.mrr import _pyramid

F64 = NDArray[np.float64]




def _hat_w(e0: F64, e1: F64, odd: F64, out: F64) -> None:
    """``w = (e0 + e1) * -0.5 + odd``, the operations of ``_hat_split``."""
    np.add(e0, e1, out=out)
    out *= -0.5
    out += odd


class _HatLevel:
    """One single-knot step: the grid, its outputs and the lift's guard."""

    def __init__(self, z: F64, lifted: bool, guard: float) -> None:
        self.z, self.lifted, self.guard = z, lifted, guard
        ny, nx = z.shape
        self.ny, self.nx = ny, nx
        big_y, big_x = ny + 1 - ny % 2, nx + 1 - nx % 2  # padded to odd counts
        self.big_y = big_y
        self.my, self.mx = (big_y + 1) // 2, (big_x + 1) // 2
        my, mx = self.my, self.mx
        self.ll = np.empty((my, mx))
        self.lh = np.empty((my - 1, mx))
        self.hl = np.empty((my, mx - 1))
        self.hh = np.empty((my - 1, mx - 1))
        self.strip = _pyramid.strip_rows(big_x) // 2  # coarse rows per strip

    def band(self, c0: int, c1: int) -> tuple[float, float]:
        """Coarse rows ``[c0, c1)`` strip by strip; returns the min and max of ``ll``
        over them."""
        rows = min(self.strip, c1 - c0)
        fine = 2 * rows + 3  # 2 rows of halo above, the shared row below
        mx = self.mx
        scratch = {name: np.empty((fine, width)) for name, width in
                   (("e", mx), ("hi", mx - 1), ("lo", mx), ("wg", mx - 1))}
        scratch["wgy"] = np.empty((rows + 1, mx))
        scratch["lift"] = np.empty((rows, mx))
        lo_v, hi_v = np.inf, -np.inf
        for s0 in range(c0, c1, rows):
            s1 = min(s0 + rows, c1)
            self._strip(s0, s1, scratch)
            part = self.ll[s0:s1]
            lo_v = min(lo_v, float(part.min()))
            hi_v = max(hi_v, float(part.max()))
        return lo_v, hi_v

    def _strip(self, c0: int, c1: int, scratch: dict[str, F64]) -> None:
        z, ny, nx, my, guard = self.z, self.ny, self.nx, self.my, self.guard
        # Fine rows [f0, f1) of the padded grid: coarse row i is fine row 2i and its
        # lift needs w_{i-1} and w_i, i.e. fine rows 2i-2 .. 2i+2.
        f0 = max(0, 2 * c0 - 2)
        f1 = min(2 * c1 + 1, self.big_y)
        n = f1 - f0
        real = min(f1, ny) - f0  # rows of z; a padded last row repeats row ny-1
        zr = z[f0:f0 + real]
        # x step on every row: even columns (the padded last one repeats column nx-1)
        e, hi = scratch["e"][:n], scratch["hi"][:n]
        np.copyto(e[:real, :(nx + 1) // 2], zr[:, 0::2])
        if nx % 2 == 0:
            e[:real, -1] = zr[:, -1]
        _hat_w(e[:real, :-1], e[:real, 1:], zr[:, 1::2], hi[:real])
        if self.lifted:
            lo = scratch["lo"][:n]
            wg = scratch["wg"][:real]
            np.add(hi[:real], guard, out=wg)
            # lift = max(guard, w_{k-1} + guard, w_k + guard), then lo = even + lift
            np.maximum(wg, guard, out=lo[:real, :-1])
            lo[:real, -1] = guard
            np.maximum(lo[:real, 1:], wg, out=lo[:real, 1:])
            lo[:real] += e[:real]
        else:
            lo = e
        if real < n:  # the padded row
            lo[real] = lo[real - 1]
            hi[real] = hi[real - 1]
        # y step. Local even rows are coarse rows g0 .. ; w rows g0 .. too.
        g0 = f0 // 2
        lo_e, lo_o, hi_e, hi_o = lo[0::2], lo[1::2], hi[0::2], hi[1::2]
        a, b = c0 - g0, c1 - g0  # local indices of the strip's coarse rows
        nh = min(c1, my - 1) - c0  # w rows written by this strip
        _hat_w(lo_e[a:a + nh], lo_e[a + 1:a + nh + 1], lo_o[a:a + nh], self.lh[c0:c0 + nh])
        np.copyto(self.hl[c0:c1], hi_e[a:b])
        _hat_w(hi_e[a:a + nh], hi_e[a + 1:a + nh + 1], hi_o[a:a + nh], self.hh[c0:c0 + nh])
        if not self.lifted:
            np.copyto(self.ll[c0:c1], lo_e[a:b])
            return
        # lift_i = max(guard, w_{i-1} + guard, w_i + guard) over the w that exist
        halo = 1 if c0 > 0 else 0
        wgy = scratch["wgy"][:halo + nh]
        if halo:
            _hat_w(lo_e[0:1], lo_e[1:2], lo_o[0:1], wgy[0:1])
            wgy[0:1] += guard
        np.add(self.lh[c0:c0 + nh], guard, out=wgy[halo:])
        lift = scratch["lift"][:b - a]
        lift.fill(guard)
        np.maximum(lift[:nh], wgy[halo:], out=lift[:nh])
        t = 1 - halo  # row 0 has no w_{-1}
        np.maximum(lift[t:], wgy[:b - a - t], out=lift[t:])
        np.add(lo_e[a:b], lift, out=self.ll[c0:c1])


def hat_step(z: F64, lifted: bool, guard: float,
             ) -> tuple[F64, F64, F64, F64, float, float]:
    """One single-knot analysis step of ``z``: ``(ll, lh, hl, hh, min, max)``, the
    last two over ``ll`` (the next level's guard needs them)."""
    lev = _HatLevel(z, lifted, guard)
    my = lev.my
    threaded = _pyramid.worker_count() > 1 and z.size >= _pyramid.THREAD_MIN_ELEMENTS
    parts = _pyramid.bands(my, _pyramid.BANDS if threaded else 1, 1)
    res: list[tuple[float, float]] = []

    def task(c0: int, c1: int) -> None:
        res.append(lev.band(c0, c1))

    _pyramid.run_shared([partial(task, c0, c1) for c0, c1 in parts])
    lo_v, hi_v = min(r[0] for r in res), max(r[1] for r in res)
    return lev.ll, lev.lh, lev.hl, lev.hh, lo_v, hi_v


def extremes(z: F64) -> tuple[float, float]:
    """``(z.min(), z.max())`` (NaN if ``z`` holds one), strip by strip so each
    strip is read from memory once, on two threads for large grids."""

    def part(r0: int, r1: int, res: list[tuple[float, float]]) -> None:
        rows = max(1, _pyramid.STRIP_ELEMENTS // z.shape[1])
        lo, hi = [], []
        for s in range(r0, r1, rows):
            strip = z[s:min(s + rows, r1)]
            lo.append(strip.min())
            hi.append(strip.max())
        res.append((float(np.min(lo)), float(np.max(hi))))

    threaded = _pyramid.worker_count() > 1 and z.size >= _pyramid.THREAD_MIN_ELEMENTS
    parts = _pyramid.bands(z.shape[0], _pyramid.BANDS if threaded else 1, 1)
    res: list[tuple[float, float]] = []
    _pyramid.run_shared([partial(part, r0, r1, res) for r0, r1 in parts])
    return float(np.min([r[0] for r in res])), float(np.max([r[1] for r in res]))
