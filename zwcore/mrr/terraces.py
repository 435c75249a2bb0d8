"""Terraced stage models by Haar coefficient editing (seed 000, 5.2 and Fig. 8;
design section 4, step 5).

A contour stage's model is its level model with every cell raised to the
lowest contour height at or above it, capped by the previous stage model (a
cell the stage does not reach keeps the earlier height). It is produced from
the part's lifted Haar representation from the stage level up, the level's
approximation coefficients (block maxima) and the finer detail bands: the
approximation coefficients are raised onto the contour grid and the finer
details set to zero, and synthesis of that edited representation gives the
terraced model at every input node, each cell flat (:func:`edit_coefficients`).
The lifted Haar synthesis of zero details is exact (``a - |0| ± 0``), so the
synthesised model equals the terrace rule bit for bit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from zwcore.mrr.wavelets import Bands, Multiresolution, synthesis_step

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
    """The part's lifted Haar representation from one level up, with edited coefficients.

    Attributes
    ----------
    level : int
        The stage level ``j``.
    approximation : (my, mx) float64
        Edited level-``j`` approximation: the part's block maxima raised onto the
        contour grid (the terraces, one value per cell).
    details : list of Bands
        Edited bands for levels ``j .. J-1`` (``details[i]`` turns level ``j + i``
        into ``j + i + 1``): all zero, so every cell stays flat.
    edited : int
        Coefficients that differ from the part's: raised approximation
        coefficients plus non-zero detail coefficients set to zero.
    """

    level: int
    approximation: F64
    details: list[Bands]
    edited: int

    def synthesize(self, to_level: int | None = None) -> F64:
        """The stage model at the input nodes (or at ``to_level``): synthesis of the
        edited representation, the lifted Haar steps with the edited bands."""
        z = self.approximation
        stop = len(self.details) if to_level is None else to_level - self.level
        for bands in self.details[:stop]:
            z = synthesis_step(z, bands, "haar", lifted=True)
        return z


def _zero_bands(b: Bands) -> Bands:
    zero = np.zeros(b.lh.shape)
    return Bands(lh=zero, hl=zero, hh=zero, fine_shape=b.fine_shape, padding=b.padding)


def edit_coefficients(mrr: Multiresolution, level: int, previous: F64,
                      heights_desc: F64) -> EditedMRR:
    """Edit the part's lifted Haar coefficients into a terraced stage model (Fig. 8).

    Parameters
    ----------
    mrr : Multiresolution
        Lifted Haar MRR of the part.
    level : int
        Stage level ``j``.
    previous : (my, mx) float64
        Previous stage model on the level-``j`` cells (``>= mrr.approximations[j]``).
    heights_desc : (n,) float64
        Contour heights, descending.

    Returns
    -------
    EditedMRR

    Notes
    -----
    The representation of the part from level ``j`` up is its level-``j``
    approximation (block maxima) and the detail bands of levels ``j .. J-1``.
    The edit raises every approximation coefficient to the lowest contour height
    at or above it, capped by ``previous`` (:func:`terrace`), and sets every
    finer detail coefficient to zero. In a lifted Haar step a coarse value
    ``a`` and details ``w`` give the children ``a - |w| ± w``, so zero details
    copy ``a`` to all four children: synthesis of the edited representation is
    the terraced model at every input node, each cell flat (cell semantics).
    The part's own representation is not changed.
    """
    if mrr.wavelet != "haar" or not mrr.lifted:
        raise ValueError("coefficient editing needs a lifted Haar MRR")
    approx = mrr.approximations[level]
    if previous.shape != approx.shape:
        raise ValueError(f"previous model shape {previous.shape} differs from level "
                         f"{level}'s {approx.shape}")
    raised = terrace(approx, previous, heights_desc)
    details = mrr.details[level:]
    edited = int(np.count_nonzero(raised != approx)) + sum(b.count_nonzero() for b in details)
    return EditedMRR(level, raised, [_zero_bands(b) for b in details], edited)
