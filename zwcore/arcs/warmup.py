"""Importing this module makes the arc fit's compiled kernels ready in this process.

The kernels (:mod:`zwcore.arcs._kernels` and its siblings) are compiled by numba on
first use and cached on disk next to their modules; loading them from that cache takes
about a second of CPU, compiling them (no cache, or a read-only install) about ten. The
service's worker processes fork from a process that imported this module
(``service/compute.py`` preloads it), so no request pays for either.
"""

from __future__ import annotations

import numpy as np

from zwcore.arcs.fit import fit_arcs

__all__ = ["warm_up"]


def warm_up() -> None:
    """Fit two small curves that take every compiled path of the fit: a noisy closed
    rounded rectangle (straight runs, fillets, a loop closure) and an open wave."""
    rng = np.random.default_rng(0)
    s = np.linspace(0.0, 1.0, 400, endpoint=False)
    th = 2.0 * np.pi * s
    rect = np.stack([np.clip(12.0 * np.cos(th), -10.0, 10.0),
                     np.clip(7.0 * np.sin(th), -5.0, 5.0)], 1)
    fit_arcs(rect + rng.uniform(-0.002, 0.002, rect.shape), 0.01, closed=True)
    x = np.linspace(0.0, 40.0, 300)
    fit_arcs(np.stack([x, 3.0 * np.sin(x / 4.0)], 1), 0.05)


warm_up()
