"""How far the bilinear drop-cutter CL stands above the truth beside steep walls.

Mount Rushmore's z-map (../shared/data, 0.1 mm; a 120 x 120 window with cliffs) and the
same window at 0.2 mm: the CL of Ø1, Ø2, Ø3 balls by :func:`zwcore.sim.drop_cutter`
against the CL on the same bilinear surface refined 8 times (bilinear interpolation: the
same surface, so a much tighter bound of the same truth), read at the window's nodes.
Printed with the corners outside the disc raised (the profile since session 9) and without
(``_outside_corners_raised`` bypassed, the profile before), in the same run.
Run: ``.venv/bin/python bench/bench_cl_walls.py``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from scipy.interpolate import RegularGridInterpolator

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import zwcore.sim._profiles as profiles  # noqa: E402
from zwcore import ZMap, default_tools  # noqa: E402
from zwcore.sim import drop_cutter  # noqa: E402

REFINE = 8
EDGE = 8  # nodes left out at the window's border (the refined grid's own border effects)


def data() -> np.ndarray:
    for d in (ROOT.parent / "shared" / "data", ROOT.parent.parent / "shared" / "data"):
        f = d / "mount_rush_zmap_0.1mm.npy"
        if f.exists():
            return np.load(f).astype(np.float64)
    sys.exit("no ../shared/data/mount_rush_zmap_0.1mm.npy")


def refined_cl(z: np.ndarray, d: float, tool) -> np.ndarray:  # type: ignore[no-untyped-def]
    ny, nx = z.shape
    f = RegularGridInterpolator((np.arange(ny), np.arange(nx)), z)
    yy = np.linspace(0, ny - 1, (ny - 1) * REFINE + 1)
    xx = np.linspace(0, nx - 1, (nx - 1) * REFINE + 1)
    fine = np.ascontiguousarray(f(np.stack(np.meshgrid(yy, xx, indexing="ij"), -1)))
    return drop_cutter(ZMap(fine, dx=d / REFINE, dy=d / REFINE), tool)[::REFINE, ::REFINE]


def main() -> None:
    window = np.ascontiguousarray(data()[200:320, 300:420])
    tools = {t.id: t for t in default_tools("ball")}
    raise_corners = profiles._outside_corners_raised
    print("| grid mm | ball | profile | p95 mm | p99 mm | max mm |")
    print("| --- | --- | --- | --- | --- | --- |")
    for step in (1, 2):
        z, d = np.ascontiguousarray(window[::step, ::step]), 0.1 * step
        for tid in ("BEM-D1", "BEM-D2", "BEM-D3"):
            tool = tools[tid]
            ref = refined_cl(z, d, tool)
            for name, fn in (("before (plane only)", lambda t, g, dx, dy, best: best),
                             ("outside corners raised", raise_corners)):
                profiles._outside_corners_raised = fn
                profiles._drop_profile_cached.cache_clear()
                try:
                    cl = drop_cutter(ZMap(z, dx=d, dy=d), tool)
                finally:
                    profiles._outside_corners_raised = raise_corners
                    profiles._drop_profile_cached.cache_clear()
                ex = (cl - ref)[EDGE:-EDGE, EDGE:-EDGE]
                print(f"| {d:.1f} | {tid} | {name} | {np.percentile(ex, 95):.4f} | "
                      f"{np.percentile(ex, 99):.4f} | {ex.max():.3f} |")


if __name__ == "__main__":
    main()
