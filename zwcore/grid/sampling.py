"""Evaluate a level model at the nodes of a finer grid.

A level-``j`` model of a ``J``-level MRR has one node per ``s = 2**(J-j)``
fine nodes along each axis: its node ``c`` sits on fine node ``c*s``
(single-knot) or its cell covers fine nodes ``c*s .. c*s + s - 1`` (Haar).
These functions put a coarse model back on the fine nodes, in the coarse
model's own surface meaning, so it can be compared with the part node by node.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from zwcore.grid.zmap import Interpolation

__all__ = ["at_fine_nodes", "bilinear_at_fine_nodes", "cells_at_fine_nodes"]

F64 = NDArray[np.float64]


def cells_at_fine_nodes(coarse: F64, scale: int, fine_shape: tuple[int, int]) -> F64:
    """Flat cells: every fine node takes the value of the coarse cell over it.

    Parameters
    ----------
    coarse : (my, mx) float64
    scale : int
        Fine nodes per coarse cell along an axis (a power of two).
    fine_shape : (ny, nx)

    Returns
    -------
    (ny, nx) float64
    """
    ny, nx = fine_shape
    if scale == 1:
        return coarse[:ny, :nx]
    return np.repeat(np.repeat(coarse, scale, axis=0)[:ny], scale, axis=1)[:, :nx]


def _linear_along(c: F64, scale: int, n: int, axis: int) -> F64:
    idx = np.arange(n)
    lo = idx // scale
    t = (idx % scale) / scale
    hi = np.minimum(lo + 1, c.shape[axis] - 1)
    if axis == 0:
        return c[lo] * (1.0 - t)[:, None] + c[hi] * t[:, None]
    return c[:, lo] * (1.0 - t) + c[:, hi] * t


def bilinear_at_fine_nodes(coarse: F64, scale: int, fine_shape: tuple[int, int]) -> F64:
    """Bilinear surface through the coarse nodes, sampled at the fine nodes.

    Parameters
    ----------
    coarse : (my, mx) float64
        Node values; coarse node ``(c, d)`` sits on fine node ``(c*scale, d*scale)``.
    scale : int
    fine_shape : (ny, nx)

    Returns
    -------
    (ny, nx) float64
    """
    ny, nx = fine_shape
    if scale == 1:
        return coarse[:ny, :nx]
    return _linear_along(_linear_along(coarse, scale, ny, 0), scale, nx, 1)


def at_fine_nodes(coarse: F64, scale: int, fine_shape: tuple[int, int],
                  interpolation: Interpolation) -> F64:
    """Dispatch on the surface meaning (``"cell"`` or ``"bilinear"``)."""
    if interpolation == "cell":
        return cells_at_fine_nodes(coarse, scale, fine_shape)
    return bilinear_at_fine_nodes(coarse, scale, fine_shape)
