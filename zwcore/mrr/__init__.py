"""The multiresolution representation (seed 000): one lifted wavelet analysis of a z-map.

- :mod:`zwcore.mrr.wavelets`: Haar and single-knot analysis/synthesis with the
  overcut-free lift;
- :mod:`zwcore.mrr._pyramid`: the fast lifted-Haar pyramid behind ``analyse``;
- :mod:`zwcore.mrr.terraces`: terraced stage models by editing Haar coefficients.
"""

from zwcore.mrr.terraces import EditedMRR, cell_weights, edit_coefficients, terrace
from zwcore.mrr.wavelets import (
    WAVELETS,
    Bands,
    Multiresolution,
    analyse,
    analysis_step,
    level_count,
    synthesis_step,
)

__all__ = [
    "WAVELETS",
    "Bands",
    "EditedMRR",
    "Multiresolution",
    "analyse",
    "analysis_step",
    "cell_weights",
    "edit_coefficients",
    "level_count",
    "synthesis_step",
    "terrace",
]
