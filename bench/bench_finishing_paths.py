"""Finishing path length of the scan-line plan: extra lines by region against whole strips.

Issue 16. For each part the plan (``plan_scanline``, default library) is run
once; its finishing pass reports ``path_length`` (extra lines only over the
stretches whose cells need them, plus one tool radius each side). The "before"
figure is computed here, in the same run, by a reference copy of the rule the
planner used before: per strip between two grid lines, the fewest evenly
spaced lines that meet the tolerance on the strip's steepest slope across the
lines, every line running the strip's whole length, in the direction with
fewer line-millimetres. It works on the part alone (the finishing pass's model
is the part), so it shares no code with the planner. Both sides use the same
finishing ball and tolerance.

Parts: Mount Rushmore (``../shared/data``, 432 x 859, 0.1 mm), the bench part
of ``bench_scanline_core.py`` at 513 x 513 (100 mm, 0.195 mm) and the R 8 bowl
(a hemispherical pocket of radius 8 mm in a flat plate, 0.25 mm grid).
Target (issue): Rushmore's finishing path at most a third of before.

Run: ``python bench/bench_finishing_paths.py`` (``--data DIR`` for the z-map's
directory when it is not ``../shared/data``).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.bench_scanline_core import synthetic  # noqa: E402
from zwcore.grid.zmap import ZMap  # noqa: E402
from zwcore.scanline.planner import plan_scanline  # noqa: E402

RUSHMORE = "mount_rush_zmap_0.1mm.npy"


def whole_strip_lines(part: np.ndarray, spacing: float, length: float, radius: float,
                      tolerance: float) -> int:
    """Scan lines of the whole-strip rule for lines along the rows of ``part``.

    ``part`` is ``(strips + 1, nodes)``: row ``i`` and ``i + 1`` bound strip
    ``i``; ``spacing`` is the distance between rows, ``length`` the extent
    across the lines (the last strip may be narrower).
    """
    n = part.shape[0] - 1
    if n <= 0 or length <= 0.0:
        return 1
    slope = np.abs(np.diff(part, axis=0)).max(axis=1) / spacing
    widths = np.full(n, spacing)
    widths[-1] = max(length - (n - 1) * spacing, 0.0) or spacing
    e = 0.5 * widths * np.sqrt(1.0 + slope**2)
    with np.errstate(invalid="ignore"):
        h = np.where(e <= radius, radius - np.sqrt(np.maximum(radius**2 - e**2, 0.0)), np.inf)
    lines = 1 + n
    b = min(tolerance, radius)
    allowed_e = math.sqrt(b * (2.0 * radius - b))
    for i in np.flatnonzero(h > tolerance):
        allowed = 2.0 * allowed_e / math.sqrt(1.0 + slope[i] ** 2) * (1.0 - 1e-9)
        k = max(math.ceil(widths[i] / allowed - 1e-12), 1)
        if widths[i] / k > allowed:
            k += 1
        lines += k - 1
    return lines


def whole_strip_path(zmap: ZMap, radius: float, tolerance: float) -> tuple[str, int, float]:
    """Direction, line count and path length (mm) of the whole-strip rule."""
    z = zmap.z
    ny, nx = z.shape
    lx, ly = (nx - 1) * zmap.dx, (ny - 1) * zmap.dy
    along_x = whole_strip_lines(z, zmap.dy, ly, radius, tolerance)
    along_y = whole_strip_lines(z.T, zmap.dx, lx, radius, tolerance)
    tx, ty = along_x * lx, along_y * ly
    if tx < ty or (tx == ty and zmap.dy <= zmap.dx):
        return "x", along_x, tx
    return "y", along_y, ty


def bowl() -> ZMap:
    x = np.arange(-20.0, 20.0 + 1e-9, 0.25)
    xx, yy = np.meshgrid(x, x)
    r2 = xx**2 + yy**2
    return ZMap(np.where(r2 < 64.0, -np.sqrt(np.clip(64.0 - r2, 0.0, None)), 0.0),
                dx=0.25, dy=0.25)


def report(name: str, zmap: ZMap, tolerance: float) -> float:
    t = time.perf_counter()
    plan = plan_scanline(zmap, tolerance=tolerance)
    seconds = time.perf_counter() - t
    last = plan.stages[-1]
    direction, lines, before = whole_strip_path(zmap, last.tool.radius, tolerance)
    after = last.path_length
    print(f"{name:>16s} {zmap.shape[0]}x{zmap.shape[1]} tol {tolerance:g} {last.tool.id}: "
          f"finishing path before {before / 1e3:9.3f} m ({lines} lines along {direction}), "
          f"after {after / 1e3:8.3f} m ({last.scan_lines} lines along {last.scan_direction}, "
          f"{last.extra_segments} extra segments): {before / after:5.2f}x shorter; "
          f"plan's whole-strip figure {last.path_length_whole_strips / 1e3:.3f} m; "
          f"all stages {sum(s.path_length for s in plan.stages) / 1e3:.3f} m "
          f"(whole strips {sum(s.path_length_whole_strips for s in plan.stages) / 1e3:.3f} m); "
          f"plan {seconds:.2f} s")
    return before / after


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=None)
    args = parser.parse_args()
    places = [args.data] if args.data else [ROOT.parent / "shared" / "data",
                                            ROOT.parents[1] / "shared" / "data"]
    path = next((p / RUSHMORE for p in places if (p / RUSHMORE).exists()), None)
    if path is not None:
        z = np.load(path).astype(np.float64)
        rush = ZMap(z, x0=-40.958, y0=-24.696, dx=0.1, dy=0.1)
        ratio = report("Mount Rushmore", rush, 0.01)
        print(f"target: Rushmore after <= before / 3: {'met' if ratio >= 3.0 else 'NOT met'}")
    else:
        print(f"no {RUSHMORE} in {', '.join(str(p) for p in places)}; skipped")
    report("bench part", synthetic(513), 0.01)
    report("R 8 bowl", bowl(), 0.01)


if __name__ == "__main__":
    main()
