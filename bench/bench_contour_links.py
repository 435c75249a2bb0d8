"""Contour stages: feed links between rings against retracting between every ring.

Plans a 40 x 40 mm pocket with an island and a step (flat Ø10, Ø6, Ø3), emits its
contour tool paths and program, reads the program back with the project's NC reader and
prints, with links and with every link refused (``link_is_clear`` patched to False, same
run, same ring order): retracts to clearance (rapids upwards), rapid length, air-feed
length, machining-time estimate, and the verification's gouge and rapids in material.
Usage: ``python bench/bench_contour_links.py``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from zwcore import ZMap  # noqa: E402
from zwcore.contour import plan_contour  # noqa: E402
from zwcore.grid.tools import default_tools  # noqa: E402
from zwcore.toolpath import contour_paths, contour_toolpaths  # noqa: E402
from zwcore.toolpath.parse import parse_program  # noqa: E402


def pocket_part() -> ZMap:
    """A 40 x 40 mm plate (0.25 mm grid): a 6 mm pocket, a 1 mm island, a 3 mm step."""
    n, dx = 161, 0.25
    y, x = np.mgrid[0:n, 0:n] * dx
    z = np.where((abs(x - 20) < 14) & (abs(y - 20) < 12), -6.0, 0.0)
    z = np.where(np.hypot(x - 14, y - 20) < 4, -1.0, z)
    z = np.where(np.hypot(x - 28, y - 22) < 5, -3.0, z)
    return ZMap(z, 0.0, 0.0, dx, dx)


def run(label: str, part: ZMap) -> None:
    tools = [t for t in default_tools("flat") if t.diameter in (10, 6, 3)]
    plan = plan_contour(part, tools)
    t = time.perf_counter()
    tp = contour_toolpaths(part, plan, tolerance=0.02)
    seconds = time.perf_counter() - t
    prog = parse_program(tp.program)  # the first rapid starts from an unknown position (nan)
    d = prog.end - prog.start
    rapid = prog.motion == 0
    chk = tp.check
    print(f"| {label} | {int((rapid & (d[:, 2] > 0)).sum())} | "
          f"{np.nansum(np.linalg.norm(d[rapid], axis=1)):.1f} | "
          f"{sum(s.air_feed_length for s in chk.stages):.1f} | {tp.time_min:.2f} | "
          f"{chk.gouge:.1e} | {chk.rapid_in_material:.1e} | {seconds:.2f} |")


def main() -> None:
    part = pocket_part()
    print("| links | retracts | rapid mm | air feed mm | time min | gouge mm | "
          "rapid in material mm | paths+verify s |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    run("on", part)
    keep = contour_paths.link_is_clear
    contour_paths.link_is_clear = lambda *a, **k: False  # type: ignore[assignment]
    try:
        run("off (retract between rings)", part)
    finally:
        contour_paths.link_is_clear = keep


if __name__ == "__main__":
    main()
