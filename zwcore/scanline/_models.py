"""Nested stage targets for the scan-line plan: clip the lifted levels, then repair.

The lifted single-knot MRR (design section 2) contains the part at every
level, but the lift ``a'_i = a_i + max(0, w_{i-1}, w_i)``, applied in x then
in y at every level, compounds at cliffs: on a part with 28 mm walls the coarse
levels rise hundreds of millimetres above the part's top. Such a level can
neither be cut from the stock nor contain the finer stages sensibly. The
planner therefore does not use ``A_j`` itself but a *target*

``T_j = repair(min(A_j, C_j))``, with ``C_j = T_{j-1}`` at the level's nodes
(``C`` of the first level: the stock top), lowered by a guard ``g`` of a
few ulps where the clip binds. Clipped nodes drop to the part's own height at
the node (the lowest value any containing model can take there).

- Clip: ``min`` node by node. A bilinear surface is a non-negative
  combination of its node values, so ``min(A, C)`` lies below ``C``
  everywhere: the targets nest, ``T_j <= T_{j-1}``, at every point.
- Repair: where a cell has a clipped corner, the minimum of two containing
  surfaces need not contain the part (``min`` is concave). Each such cell is
  checked at all the input nodes it covers (a coarse bilinear surface
  restricted to a finer cell is bilinear, so checking the input nodes is
  checking the surface), and where ``B = min(A, C)`` falls short of the part
  (plus a margin ``m_j``) its corners are blended towards the ceiling:
  ``T = B + lambda (C - B)`` with, per node, ``lambda`` the largest over its
  cells of ``max_x deficit(x) / (C(x) - B(x))``. Since ``C`` contains the part
  with a larger margin, ``lambda <= 1``, the repair only raises, never above
  ``C``, and it is the smallest *uniform-per-cell* blend that restores
  containment at every input node of the cell. Cells whose corners are all
  unclipped are ``A_j`` and contain the part by the lift.
- Rounding: the margins shrink from level to level (``m_j = (J-j) * 4g``) and
  the clip lowers by ``g``, so the float evaluation of the nested models at the
  input nodes keeps the order exactly (checked node by node in
  :mod:`zwcore.scanline._checks`).

Only cells with a clipped corner are visited at input resolution, so the cost
follows the length of the clip boundary, not the grid.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from zwcore.grid.sampling import bilinear_at_fine_nodes

__all__ = ["Target", "nested_targets", "repair"]

F64 = NDArray[np.float64]

#: Input nodes gathered at once during a repair (bounds the temporaries).
_BATCH_NODES = 1 << 20


@dataclass
class Target:
    """The clipped and repaired model of one level.

    Attributes
    ----------
    level : int
    model : (my, mx) float64
        ``T_j`` at the level's nodes.
    clipped : int
        Nodes where the clip bound (the lifted level rose above the ceiling).
    raised : int
        Nodes the repair raised.
    margin : float
        ``m_j``: every input node lies at least this far below ``T_j``.
    """

    level: int
    model: F64
    clipped: int
    raised: int
    margin: float


def _axis(cells: NDArray[np.intp], s: int, n_fine: int,
          degenerate: bool) -> tuple[NDArray[np.intp], F64, NDArray[np.bool_]]:
    """Input indices, weights ``t`` and validity of the input nodes of each cell along an axis."""
    off = np.zeros(1, dtype=np.intp) if degenerate else np.arange(s + 1)
    idx = cells[:, None] * s + off[None, :]
    valid = idx <= n_fine - 1
    t = np.broadcast_to(off / s, idx.shape).astype(np.float64)
    return np.minimum(idx, n_fine - 1), t, valid


def repair(low: F64, ceiling: F64, check: NDArray[np.bool_], part: F64, scale: int,
           margin: float) -> tuple[F64, int]:
    """Raise ``low`` towards ``ceiling`` until it contains ``part + margin``.

    Parameters
    ----------
    low, ceiling : (my, mx) float64
        Node values, ``low <= ceiling``; the ceiling contains ``part + margin``.
    check : (my, mx) bool
        Nodes whose cells must be checked (cells with at least one such
        corner); the others contain the part already.
    part : (ny, nx) float64
        The input grid; level node ``(c, d)`` sits on input node ``(c*s, d*s)``.
    scale : int
        ``s``, input nodes per level cell.
    margin : float

    Returns
    -------
    model : (my, mx) float64
    raised : int
        Number of nodes raised.
    """
    if not check.any():
        return low, 0
    lam = _cell_blends(low, ceiling, check, part, scale, margin)
    if not lam.any():
        return low, 0
    return _blend_nodes(low, ceiling, lam)


def _flagged_cells(check: NDArray[np.bool_], scale: int,
                   fine_shape: tuple[int, int]) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Rows and columns of the cells with a flagged corner that cover input nodes."""
    my, mx = check.shape
    ny, nx = fine_shape
    # A one-row or one-column level has degenerate cells: both "corners" on
    # the same row or column.
    cy, cx = max(my - 1, 1), max(mx - 1, 1)
    hi_r = np.minimum(np.arange(cy) + 1, my - 1)
    hi_c = np.minimum(np.arange(cx) + 1, mx - 1)
    flag = (check[:cy][:, :cx] | check[hi_r][:, :cx] | check[:cy][:, hi_c]
            | check[hi_r][:, hi_c])
    flag &= (np.arange(cy) * scale <= ny - 1)[:, None]
    flag &= (np.arange(cx) * scale <= nx - 1)[None, :]
    rows, cols = np.nonzero(flag)
    return rows, cols


def _cell_blends(low: F64, ceiling: F64, check: NDArray[np.bool_], part: F64, scale: int,
                 margin: float) -> F64:
    """``(cy, cx)``: per cell, the smallest blend towards the ceiling that contains the part.

    Each flagged cell is evaluated at all the input nodes it covers, in
    batches of cells (bounded temporaries).
    """
    my, mx = low.shape
    ny, nx = part.shape
    cells_r, cells_c = _flagged_cells(check, scale, part.shape)
    lam = np.zeros((max(my - 1, 1), max(mx - 1, 1)))
    span = (1 if my == 1 else scale + 1) * (1 if mx == 1 else scale + 1)
    per = max(1, _BATCH_NODES // span)
    for a in range(0, cells_r.size, per):
        r = cells_r[a:a + per]
        c = cells_c[a:a + per]
        rr = np.minimum(r + 1, my - 1)
        cc = np.minimum(c + 1, mx - 1)
        iy, ty, vy = _axis(r, scale, ny, my == 1)
        ix, tx, vx = _axis(c, scale, nx, mx == 1)
        p = part[iy[:, :, None], ix[:, None, :]]
        valid = vy[:, :, None] & vx[:, None, :]
        ty3 = ty[:, :, None]
        tx3 = tx[:, None, :]

        def ev(m: F64, r: NDArray[np.intp] = r, rr: NDArray[np.intp] = rr,
               c: NDArray[np.intp] = c, cc: NDArray[np.intp] = cc,
               ty3: F64 = ty3, tx3: F64 = tx3) -> F64:
            lo = m[r, c][:, None, None] * (1.0 - tx3) + m[r, cc][:, None, None] * tx3
            up = m[rr, c][:, None, None] * (1.0 - tx3) + m[rr, cc][:, None, None] * tx3
            return np.asarray(lo * (1.0 - ty3) + up * ty3, dtype=np.float64)

        e1 = ev(low)
        deficit = p + margin - e1
        deficit[~valid] = -np.inf
        need = deficit > 0.0
        if not need.any():
            continue
        room = ev(ceiling) - e1
        ratio = np.where(need, deficit / np.where(room > 0.0, room, 1.0), 0.0)
        ratio[need & (room <= 0.0)] = 1.0
        cell_lam = ratio.reshape(ratio.shape[0], -1).max(axis=1)
        lam[r, c] = np.maximum(lam[r, c], cell_lam)
    return lam


def _blend_nodes(low: F64, ceiling: F64, lam: F64) -> tuple[F64, int]:
    """Blend every node towards the ceiling by the largest ``lam`` of its cells."""
    my, mx = low.shape
    cy, cx = lam.shape
    # A little over the exact blend covers the rounding of the evaluation.
    lam = np.minimum(lam * (1.0 + 1e-9) + np.where(lam > 0.0, 1e-12, 0.0), 1.0)
    # Every node takes the largest blend of the (up to four) cells it is a
    # corner of. Cell (r, c) has corners (r or r+1, c or c+1), clamped to the
    # last node; each of the four placements is a plain shifted slice without
    # repeated nodes, so an elementwise maximum does what ``maximum.at`` did.
    node = np.zeros((my, mx))
    r1, c1 = min(1, my - 1), min(1, mx - 1)
    for r0 in (0, r1):
        for c0 in (0, c1):
            view = node[r0:r0 + cy, c0:c0 + cx]
            np.maximum(view, lam, out=view)
    out = low + node * (ceiling - low)
    full = node >= 1.0
    out[full] = ceiling[full]
    out = np.minimum(np.maximum(out, low), ceiling)
    return out, int(np.count_nonzero(out > low))


def nested_targets(approximations: list[F64], part: F64, first: int, stock: float,
                   guard: float) -> list[Target]:
    """``T_j`` for levels ``first .. J`` (``J``: the input), each nested in the one before.

    Parameters
    ----------
    approximations : list of (my, mx) float64
        The lifted single-knot levels, coarsest first; the last one is the input
        (possibly padded).
    part : (ny, nx) float64
    first : int
        Coarsest level to use (the coarser ones are of no use to any tool).
    stock : float
        Ceiling of the first level.
    guard : float
        ``g``, a few ulps of the magnitudes in play.

    Returns
    -------
    list of Target
        One per level ``first .. J``; the last one's model is ``part``.
    """
    depth = len(approximations) - 1
    out: list[Target] = []
    prev: F64 | None = None
    for j in range(first, depth + 1):
        if j == depth:
            out.append(Target(j, part, 0, 0, 0.0))
            break
        a = approximations[j]
        s = 1 << (depth - j)
        margin = (depth - j) * 4.0 * guard
        c0 = np.full(a.shape, stock) if prev is None else bilinear_at_fine_nodes(prev, 2, a.shape)
        # Only real overshoot is clipped: where the lifted level is at or below
        # the level before, the lift's own guard keeps the order.
        clip = a > c0
        ceiling = c0 - guard
        # Clipped nodes drop to the part's own height at the node (the lowest
        # value any containing model can take there); the repair raises them.
        rows = np.minimum(np.arange(a.shape[0]) * s, part.shape[0] - 1)
        cols = np.minimum(np.arange(a.shape[1]) * s, part.shape[1] - 1)
        floor = np.minimum(part[rows[:, None], cols[None, :]] + margin, ceiling)
        low = np.where(clip, floor, a)
        model, raised = repair(low, np.maximum(ceiling, low), clip, part, s, margin)
        out.append(Target(j, model, int(np.count_nonzero(clip)), raised, margin))
        prev = model
    return out
