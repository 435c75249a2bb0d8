"""Terraced stage models by Haar coefficient editing (seed 000, 5.2 and Fig. 8;
design section 4, step 5).

A contour stage's model is its level model with every cell raised to the
lowest contour height at or above it, capped by the previous stage model (a
cell the stage does not reach keeps the earlier height). In the Haar MRR of
the part that model is reached by editing coefficients: the approximation
coefficients of the coarser levels become the block maxima of the terraces
(the overcut-free lift, so the edited coarse levels still contain the model)
and the detail coefficients of every level up to the stage level become the
terraces' differences, mostly zero inside a flat terrace. Synthesis of the
edited representation gives the terraces back exactly as long as the terrace
heights are multiples of :data:`zwcore.contour_heights.QUANTUM`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from zwcore.wavelets import Bands, Multiresolution, analysis_step

__all__ = ["EditedMRR", "cell_weights", "edit_coefficients", "terrace"]

F64 = NDArray[np.float64]


def terrace(level_model: F64, previous: F64, heights_desc: F64) -> F64:
    """Raise every cell to the lowest contour height at or above it, capped by ``previous``.

    Parameters
    ----------
    level_model : (my, mx) float64
        The stage's level model (block maxima of the part).
    previous : (my, mx) float64
        The previous stage model on the same cells (``>= level_model``).
    heights_desc : (n,) float64
        Contour heights, descending.

    Returns
    -------
    (my, mx) float64
        ``min(previous, ceil_Z(level_model))``; a cell below the lowest height
        is raised to it, a cell above the highest keeps ``previous``.
    """
    asc = np.asarray(heights_desc, dtype=np.float64)[::-1]
    if asc.size == 0:
        return previous.copy()
    idx = np.searchsorted(asc, level_model, side="left")
    up = np.where(idx < asc.size, asc[np.minimum(idx, asc.size - 1)], np.inf)
    out: F64 = np.minimum(previous, up)
    return out


def cell_weights(shape: tuple[int, int], scale: int, fine_shape: tuple[int, int],
                 node_area: float) -> F64:
    """Area of the input nodes each level cell covers (edge cells cover fewer).

    Parameters
    ----------
    shape : (my, mx)
        Cells at the level.
    scale : int
        Input nodes per cell along an axis.
    fine_shape : (ny, nx)
        The input grid.
    node_area : float
        ``dx * dy``.

    Returns
    -------
    (my, mx) float64
    """
    (my, mx), (ny, nx) = shape, fine_shape
    cy = np.minimum(scale, ny - np.arange(my) * scale).astype(np.float64)
    cx = np.minimum(scale, nx - np.arange(mx) * scale).astype(np.float64)
    out: F64 = np.outer(cy, cx) * node_area
    return out


@dataclass(frozen=True, eq=False)
class EditedMRR:
    """The part's Haar MRR with the coefficients up to one level edited.

    Attributes
    ----------
    coarsest : (1, 1) float64
        Edited level-0 approximation.
    details : list of Bands
        ``details[j]`` turns edited level ``j`` into ``j + 1``, for ``j <
        level``; the part's own bands follow for the finer levels.
    level : int
        The edited level: synthesis up to it gives the stage model.
    edited : int
        Coefficients (approximation and detail) that differ from the part's.
    """

    coarsest: F64
    details: list[Bands]
    level: int
    edited: int

    def synthesize(self, mrr: Multiresolution) -> F64:
        """The stage model: synthesis of the edited representation to ``level``."""
        return mrr.synthesize(self.coarsest, self.details, to_level=self.level)


def edit_coefficients(mrr: Multiresolution, level: int, model: F64) -> EditedMRR:
    """Edit the Haar coefficients of ``mrr`` so that level ``level`` becomes ``model``.

    Parameters
    ----------
    mrr : Multiresolution
        Lifted Haar MRR of the part.
    level : int
        Stage level ``j``.
    model : (my, mx) float64
        Target terraces, shaped like ``mrr.approximations[level]``.

    Returns
    -------
    EditedMRR

    Notes
    -----
    The edit of each band is the difference between the terraces' coefficients
    and the part's (Fig. 8); walking down from ``level`` with the lifted step
    gives the terraces' coefficients. Levels above ``level`` keep the part's
    bands, so the same representation still refines towards the part.
    """
    if mrr.wavelet != "haar" or not mrr.lifted:
        raise ValueError("coefficient editing needs a lifted Haar MRR")
    if model.shape != mrr.approximations[level].shape:
        raise ValueError(f"model shape {model.shape} differs from level {level}'s "
                         f"{mrr.approximations[level].shape}")
    cur = model
    bands: list[Bands] = []
    edited = 0
    for j in range(level - 1, -1, -1):
        cur, b = analysis_step(cur, "haar", lifted=True)
        old = mrr.details[j]
        edited += sum(int(np.count_nonzero(new != prev)) for new, prev in
                      ((b.lh, old.lh), (b.hl, old.hl), (b.hh, old.hh)))
        bands.append(b)
    bands.reverse()
    edited += int(np.count_nonzero(cur != mrr.approximations[0]))
    return EditedMRR(cur, bands + list(mrr.details[level:]), level, edited)
