"""Make the scan-line plan's compiled kernels ready in this process.

The simulated stock (:mod:`zwcore.scanline._stock_kernels`) runs numba kernels that are
compiled on first use and cached on disk; loading them from that cache holds the
interpreter lock for a few tenths of a second, compiling them (no cache yet) for
seconds. A server calls :func:`warm_up` before it serves, so no request (and no
``/healthz`` poll behind it) waits for either.
"""

from __future__ import annotations

import numpy as np

from zwcore.grid.zmap import ZMap
from zwcore.scanline.planner import plan_scanline

__all__ = ["warm_up"]


def warm_up() -> None:
    """Plan a small pocketed wave: roughing, lifted passes and finishing, so every
    kernel of the simulated stock is loaded (or compiled) once."""
    y, x = np.mgrid[0:17, 0:17] * 0.5
    pocket = (np.abs(x - 4.0) < 1.0) & (np.abs(y - 4.0) < 2.0)
    z = np.where(pocket, -6.0, 0.0) + np.sin(x)
    plan_scanline(ZMap(z, 0.0, 0.0, 0.5, 0.5))
