"""Where a scan-line stage's stretches run, and how low a rapid may come down before one.

Two pieces of :mod:`zwcore.toolpath.scanline_paths`, in the frame where lines run along
``u`` at offsets ``v`` (mm from the grid's first node):

- :func:`region_stretches`: the stretches of lines inside a stage's region mask (at the
  stage's resolution);
- :func:`entry_heights`: an upper bound of the stock within the tool's reach of each
  entry point, after the stage's whole lines, from those lines' final paths alone: a ball
  whose tip passes over ``(u, v_line)`` at height ``z`` leaves nothing above
  ``z + R - sqrt(R^2 - d^2)`` at the node ``(u, v)``, ``d = |v - v_line| < R``. No sweep
  of the stock is needed to know that a rapid down to above it runs in air.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

F64 = NDArray[np.float64]


def region_stretches(region: NDArray[np.bool_], offset: F64, start: F64, stop: F64,
                     su: float, sv: float) -> tuple[NDArray[np.int64], F64, F64]:
    """The stretches of lines inside a region.

    Parameters
    ----------
    region : (mv, mu) bool
        Where the stage cuts, on its model's nodes (rows across the lines).
    offset, start, stop : (n,) float64
        The lines (mm).
    su, sv : float
        The model's spacing along and across the lines, mm.

    Returns
    -------
    line : (m,) int64
        The line of each stretch (in order).
    start, stop : (m,) float64
        Stretches: a cell between two model nodes along a line is cut when any of the
        (up to four) model nodes around it lies in the region.
    """
    mv, mu = region.shape
    pos = offset / sv
    r0 = np.clip(np.floor(pos + 1e-9).astype(np.int64), 0, mv - 1)
    r1 = np.where(pos - r0 > 1e-9, np.minimum(r0 + 1, mv - 1), r0)
    node = region[r0] | region[r1]  # (n, mu)
    cell = node[:, :-1] | node[:, 1:]  # (n, mu - 1), cell c spans [c su, (c + 1) su]
    pad = np.zeros((len(offset), mu + 1), np.int8)
    pad[:, 1:-1] = cell
    edge = np.diff(pad, axis=1)
    li, c0 = np.nonzero(edge == 1)
    _, c1 = np.nonzero(edge == -1)  # same row order: one end per start
    a = np.maximum(c0 * su, start[li])
    b = np.minimum(c1 * su, stop[li])
    keep = b > a
    return li[keep], a[keep], b[keep]


def entry_heights(entries: F64, line_v: F64, line_paths: list[F64], du: float, dv: float,
                  shape_uv: tuple[int, int], radius: float, stock_top: float) -> F64:
    """Highest stock within a ball's reach of each entry point, bounded from above.

    Parameters
    ----------
    entries : (m, 2) float64
        Entry points ``(u, v)``, mm.
    line_v : (nl,) float64
        Offsets of the stage's whole lines, increasing.
    line_paths : list of (k, 2) float64
        Each whole line's final path ``(u, z)``, ``u`` increasing.
    du, dv : float
        The part's spacing along and across the lines.
    shape_uv : (int, int)
        The part's nodes along and across the lines.
    radius : float
    stock_top : float
        The stock before the program (an upper bound everywhere).

    Returns
    -------
    (m,) float64
        A height the stock within ``radius`` of each entry point does not exceed.
    """
    n_u = shape_uv[0]
    u_nodes = np.arange(n_u) * du
    z_line = (np.array([np.interp(u_nodes, p[:, 0], p[:, 1]) for p in line_paths])
              if len(line_v) else np.zeros((0, n_u)))
    out = np.empty(len(entries))
    _entry_kernel(np.ascontiguousarray(entries, np.float64), np.ascontiguousarray(line_v,
                  np.float64), np.ascontiguousarray(z_line, np.float64), float(du), float(dv),
                  int(shape_uv[0]), int(shape_uv[1]), float(radius),
                  float(stock_top), out)
    return out


@njit(cache=True, nogil=True)
def _entry_kernel(entries: F64, line_v: F64, z_line: F64, du: float, dv: float, n_u: int,
                  n_v: int, radius: float, stock_top: float, out: F64) -> None:
    """Per entry, the max over the nodes within ``radius`` (a box holding them) of
    ``min(stock_top, z_line[j] + rise(d_j))`` over the nearest whole line on either side
    within reach."""
    nl = len(line_v)
    r2 = radius * radius
    for e in range(len(entries)):
        ue, ve = entries[e, 0], entries[e, 1]
        k0 = max(0, math.floor((ue - radius) / du))
        k1 = min(n_u - 1, math.ceil((ue + radius) / du))
        i0 = max(0, math.floor((ve - radius) / dv))
        i1 = min(n_v - 1, math.ceil((ve + radius) / dv))
        best = -math.inf
        for i in range(i0, i1 + 1):
            v = i * dv
            below = np.searchsorted(line_v, v, side="right") - 1
            for k in range(k0, k1 + 1):
                bound = stock_top
                for j in (below, below + 1):
                    if 0 <= j < nl:
                        d = abs(line_v[j] - v)
                        if d < radius:
                            rise = radius - math.sqrt(max(r2 - d * d, 0.0))
                            bound = min(bound, z_line[j, k] + rise)
                best = max(best, bound)
        out[e] = best
