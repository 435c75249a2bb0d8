"""Benchmark of the G-code rewrite on a waterline program of the Mount Rushmore relief.

Run: ``.venv/bin/python bench/bench_gcode.py [--levels N] [--tolerance T]``.

The program is what a CAM system's waterline finishing writes: at each of N Z levels
the relief's contours (contourpy, matplotlib's contour engine, on the z-map of
``../shared/data``), each as G01 moves between points about 0.1 mm apart, entered by a
rapid and a plunge. Printed, from one run: motion blocks and bytes before and after,
the largest two-sided deviation, the wall time of the rewrite, and as a same-run
reference the time to merely read the program's lines with the same parser
(``program_runs``: no fitting).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from zwcore.io.gcode_program import program_runs, rewrite_program  # noqa: E402

# ../shared/data beside the checkout (or beside a parent of it, for worktrees)
DATA = next((p / "shared" / "data" / "mount_rush_zmap_0.1mm.npy" for p in ROOT.parents
             if (p / "shared" / "data" / "mount_rush_zmap_0.1mm.npy").exists()),
            ROOT.parent / "shared" / "data" / "mount_rush_zmap_0.1mm.npy")
X0, Y0, D = -40.958, -24.696, 0.1


def waterline_program(z: np.ndarray, levels: int) -> str:
    import contourpy

    gen = contourpy.contour_generator(z=z, line_type="Separate")
    lines = ["%", "O0100 (waterline finishing, Mount Rushmore relief)", "G17 G21 G90 G40",
             "T2 M06 (ball D2)", "S18000 M03"]
    heights = np.linspace(float(z.min()) + 0.5, float(z.max()) - 0.2, levels)
    for h in heights:
        for c in gen.lines(float(h)):
            if len(c) < 8:
                continue
            pts = np.c_[X0 + c[:, 0] * D, Y0 + c[:, 1] * D]
            lines += ["G00 Z5.", f"G00 X{pts[0, 0]:.4f} Y{pts[0, 1]:.4f}",
                      f"G01 Z{h:.4f} F300"]
            lines += [f"G01 X{x:.4f} Y{y:.4f} F1500" if i == 0 else f"X{x:.4f} Y{y:.4f}"
                      for i, (x, y) in enumerate(pts[1:])]
    lines += ["G00 Z5.", "M05", "M30", "%"]
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--levels", type=int, default=12)
    ap.add_argument("--tolerance", type=float, default=0.01)
    args = ap.parse_args()
    if not DATA.exists():
        sys.exit(f"no data at {DATA}")
    z = np.load(DATA, allow_pickle=False).astype(np.float64)
    text = waterline_program(z, args.levels)
    t = time.perf_counter()
    runs = program_runs(text)
    t_read = time.perf_counter() - t
    t = time.perf_counter()
    out = rewrite_program(text, args.tolerance)
    t_fit = time.perf_counter() - t
    print(f"waterline program of the relief: {args.levels} Z levels, {len(runs)} contours, "
          f"{sum(len(r) - 1 for r in runs)} G01 moves in runs")
    print(f"tolerance {args.tolerance} mm: motion blocks {out.moves_before} -> "
          f"{out.moves_after} ({out.moves_after / out.moves_before:.3f}x), bytes "
          f"{out.bytes_before} -> {out.bytes_after} ({out.bytes_after / out.bytes_before:.3f}x)")
    arcs = sum(s.kind == "arc" for r in out.runs for s in r.segments)
    print(f"runs rewritten {sum(r.rewritten for r in out.runs)}/{len(out.runs)}, arcs {arcs}, "
          f"max two-sided deviation {out.max_deviation:.5f} mm")
    print(f"rewrite {t_fit:.2f} s; reading alone {t_read:.2f} s "
          f"(rewrite / read = {t_fit / t_read:.1f}x)")


if __name__ == "__main__":
    main()
