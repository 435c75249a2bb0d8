"""Plan the Mount Rushmore relief (../shared/data) and print what the README shows.

The z-map (float32 (432, 859), dx = dy = 0.1 mm) comes from OpenCAMLib's
``stl/mount_rush.stl`` (LGPL 2.1, see ../shared/data/README.md); it is read in
place, not copied. Run: ``.venv/bin/python bench/rushmore.py``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from zwcore import ZMap, plan_contour, plan_scanline  # noqa: E402

DATA = ROOT.parent / "shared" / "data" / "mount_rush_zmap_0.1mm.npy"


def main() -> None:
    if not DATA.exists():
        sys.exit(f"no data at {DATA}")
    z = np.load(DATA).astype(np.float64)
    zmap = ZMap(z, x0=-40.958, y0=-24.696, dx=0.1, dy=0.1)
    print(f"Mount Rushmore {z.shape[0]} x {z.shape[1]}, heights {z.min():.2f} .. {z.max():.2f} mm")

    t = time.perf_counter()
    plan = plan_scanline(zmap)
    took = time.perf_counter() - t
    print(f"\nscan-line plan ({took:.2f} s): stock_top {plan.stock_top:.3f} "
          f"({plan.stock_top_source}),"
          f" checks ok {plan.checks.ok}, {len(plan.stages)} stages")
    print(f"tool_sequence: {' > '.join(plan.tool_sequence)}")
    print("| tool | level | spacing mm | passes | pick-feed min..max mm | scallop mm "
          "| max depth mm | removed cm³ | max stock left mm |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for s in plan.stages:
        if s.pass_index != s.pass_count:
            continue  # one row per tool and level: its last pass
        group = [g for g in plan.stages if g.tool.id == s.tool.id and g.level == s.level]
        print(f"| {s.tool.id} | {s.level} | {s.spacing[0]:.1f} | {s.pass_count} "
              f"| {min(g.pick_feed for g in group):.4f}..{max(g.pick_feed_max for g in group):.2f} "
              f"| {max(g.scallop_height for g in group):.3f} "
              f"| {max(g.max_depth_of_cut for g in group):.2f} "
              f"| {sum(g.removed_volume for g in group) / 1000:.1f} | {s.max_stock_left:.3f} |")
    for note in plan.notes:
        print(f"note: {note}")
    _simulated(plan)

    t = time.perf_counter()
    cplan = plan_contour(zmap)
    took = time.perf_counter() - t
    print(f"\ncontour plan ({took:.2f} s): stock_top {cplan.stock_top:.3f}, checks ok "
          f"{cplan.checks.ok}, max volume spread {cplan.checks.max_volume_spread:.2e}")
    print("| tool | level | cell mm | spacings mm | slab volumes cm³ | max stock left mm |")
    print("| --- | --- | --- | --- | --- | --- |")
    for s in cplan.stages:
        sp = ", ".join(f"{v:.3f}" for v in s.spacings)
        vol = ", ".join(f"{v / 1000:.2f}" for v in s.slab_volumes)
        print(f"| {s.tool.id} | {s.level} | {s.cell_size[0]:.1f} | {sp} | {vol} "
              f"| {s.max_stock_left:.2f} |")
    for note in cplan.notes:
        print(f"note: {note}")


def _simulated(plan: object) -> None:
    """Per pass, the figures from the simulated stock (issue 11 part 4)."""
    c = plan.checks  # type: ignore[attr-defined]
    print(f"\nsimulated stock: depth_of_cut {c.depth_of_cut} (max over flute "
          f"{c.max_depth_over_flute:+.3f} mm), gouge {c.sim_max_gouge:.1e} mm, models nested "
          f"{c.models_nested} (max rise {c.max_model_rise:.2f} mm), left over part max "
          f"{c.sim_left_over_part_max:.3f} p95 {c.sim_left_over_part_p95:.4f} mm")
    print("| pass | tool | level | positions | ds mm | real depth max / mean mm | flutes mm "
          "| lifted nodes | left over next max / p95 mm | left over part max / p95 mm |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for n, s in enumerate(plan.stages):  # type: ignore[attr-defined]
        print(f"| {n} | {s.tool.id} {s.pass_index}/{s.pass_count} | {s.level} "
              f"| {s.sim_positions} | {s.sim_position_spacing:.2f} "
              f"| {s.sim_max_depth_of_cut:.2f} / {s.sim_mean_depth_of_cut:.2f} "
              f"| {s.tool.flute_length:g} | {s.sim_lifted_nodes} "
              f"| {s.sim_left_over_next_max:.2f} / {s.sim_left_over_next_p95:.3f} "
              f"| {s.sim_left_over_part_max:.2f} / {s.sim_left_over_part_p95:.3f} |")


if __name__ == "__main__":
    main()
