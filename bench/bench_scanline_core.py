"""Time plan_scanline on 513², 1025², 2049² synthetic parts and on Mount Rushmore.

Prints wall and CPU seconds, the per-phase breakdown (the plan's own timings) and the
growth ratios per x4 cells in the same run, for the simulated stock as planned (a
stage's next pass visits only what can change) and, unless ``--no-before``, as before
(``_stock.INCREMENTAL = False``: every pass simulates every position; the kernels are
today's in both). Usage: ``python bench/bench_scanline_core.py [--no-before]``.
``--unthinned [--big]``: instead, the plan with the passes over ``MAX_PASS_WORK``
thinned as far as ``0.7 R`` (the rule before), thinned within the cusp rule (as
planned), and not thinned (257², 513², with ``--big`` also 1025²), same run.
``--before PATH``: instead, the code of another checkout (``PATH``, e.g. ``git archive``
of main) against this one, each in a subprocess, back to back: wall and CPU seconds, the
passes, tools and regions and what the simulated stock leaves, for 513², 1025², 2049²
and Mount Rushmore; the ratios this/before and the growth per x4 cells; for a checkout
with the plan's second thread also the CPU seconds its threads ran side by side (on an
idle machine the wall is the CPU less that) and one plan on one thread.
"""

from __future__ import annotations

import itertools
import json
import os
import pathlib
import subprocess
import sys
import time

import numpy as np

from zwcore.grid.zmap import ZMap
from zwcore.scanline import _stock
from zwcore.scanline.planner import ScanlinePlan, plan_scanline

DATA = pathlib.Path(__file__).resolve().parents[2] / "shared" / "data"


def synthetic(n: int) -> ZMap:
    """A 100 mm free-form part at any resolution: bumps, a fillet pocket, a wall."""
    x = np.linspace(0.0, 100.0, n)
    xx, yy = np.meshgrid(x, x)
    z = 8.0 * np.sin(xx / 9.0) * np.cos(yy / 13.0) + 0.002 * (xx - 50.0) ** 2
    pocket = np.hypot(xx - 60.0, yy - 40.0)
    z = np.where(pocket < 15.0, np.minimum(z, -12.0 + 15.0 - np.sqrt(
        np.maximum(15.0**2 - pocket**2, 0.0))), z)
    z = np.where(xx > 85.0, z + 10.0, z)
    step = 100.0 / (n - 1)
    return ZMap(z, dx=step, dy=step)


def run(name: str, zmap: ZMap, repeat: int = 3) -> tuple[float, float]:
    """Best wall and CPU seconds of ``repeat`` plans; prints the plan's figures."""
    best, cpu = float("inf"), float("inf")
    plan = None
    for _ in range(repeat):
        t, c = time.perf_counter(), time.process_time()
        plan = plan_scanline(zmap)
        best = min(best, time.perf_counter() - t)
        cpu = min(cpu, time.process_time() - c)
    assert plan is not None
    phases = ", ".join(f"{k} {v * 1e3:.0f}" for k, v in plan.timings)
    c = plan.checks
    print(f"{name:>22s} {zmap.shape[0]}x{zmap.shape[1]}: {best:.3f} s wall, {cpu:.3f} s CPU  "
          f"[{phases} ms]  stages {len(plan.stages)}  tools {' > '.join(plan.tool_sequence)}  "
          f"ok {c.ok}")
    # The simulated stock (issue 11 part 4): its share is the passes_simulated phase.
    print(f"{'':>22s} simulated positions {sum(s.sim_positions for s in plan.stages)}, "
          f"lifted passes {sum(s.sim_lifted_nodes > 0 for s in plan.stages)}, "
          f"depth over flute {c.max_depth_over_flute:+.3f} mm (ok {c.depth_of_cut}), "
          f"gouge {c.sim_max_gouge:.1e} mm, left over part max {c.sim_left_over_part_max:.3f} "
          f"p95 {c.sim_left_over_part_p95:.4f} mm", flush=True)
    return best, cpu


def _ratios(label: str, times: dict[int, tuple[float, float]]) -> None:
    sizes = sorted(times)
    for what, k in (("wall", 0), ("CPU", 1)):
        steps = ", ".join(f"{b}/{a} {times[b][k] / times[a][k]:.2f}"
                          for a, b in itertools.pairwise(sizes))
        print(f"{label} {what} ratios: {steps} (cells x4 each)")


def _regions(plan: ScanlinePlan) -> str:
    """Per tool, its passes and region area fraction."""
    out: dict[str, list[float]] = {}
    for s in plan.stages:
        got = out.setdefault(s.tool.id, [0, 1.0])
        got[0] += 1
        got[1] = s.region_area_fraction if s.region_area_fraction is not None else 1.0
    return ", ".join(f"{t} {int(n)} passes on {100 * f:.1f} %" for t, (n, f) in out.items())


def unthinned(sizes: tuple[int, ...]) -> None:
    """The plan with passes over ``MAX_PASS_WORK`` thinned to ``0.7 R``
    (``_stock.CUSP_THINNING = False``), within the cusp rule (as planned), and every pass
    at all its positions (``_stock.THINNING = False``), same run: time, passes and
    regions, and what the simulated stock leaves on the part."""
    for n in sizes:
        zmap = synthetic(n)
        rows = []
        for label, thin, cusp in (("0.7 R", True, False), ("cusp", True, True),
                                  ("unthinned", False, True)):
            _stock.THINNING, _stock.CUSP_THINNING = thin, cusp
            t, c = time.perf_counter(), time.process_time()
            plan = plan_scanline(zmap)
            wall, cpu = time.perf_counter() - t, time.process_time() - c
            phases = dict(plan.timings)
            rows.append(cpu)
            print(f"{label:>10s} {n}x{n}: {wall:.2f} s wall, "
                  f"{cpu:.2f} s CPU (passes {phases['passes_simulated']:.2f} s), "
                  f"{len(plan.stages)} passes: {_regions(plan)}; left over part p95 "
                  f"{plan.checks.sim_left_over_part_p95:.4f} max "
                  f"{plan.checks.sim_left_over_part_max:.3f} mm, ok {plan.checks.ok}",
                  flush=True)
        _stock.THINNING = _stock.CUSP_THINNING = True
        print(f"{'':>10s} {n}x{n}: CPU cusp/0.7 R {rows[1] / rows[0]:.2f}, "
              f"unthinned/0.7 R {rows[2] / rows[0]:.2f}")


def _figures(zmap: ZMap, repeat: int) -> dict[str, object]:
    """Best wall and CPU seconds of ``repeat`` plans, and the last plan's figures; with
    the plan's second thread (``zwcore.scanline._threads``, absent before session 8):
    the CPU seconds its two threads ran side by side in the best run (the wall they save
    on idle cores) and the wall of one plan on one thread, same run."""
    try:
        from zwcore.scanline import _threads
    except ImportError:
        _threads = None  # type: ignore[assignment]
    best, cpu, overlap = float("inf"), float("inf"), 0.0
    for _ in range(repeat):
        if _threads is not None:
            _threads.overlap_seconds(reset=True)
        t, c = time.perf_counter(), time.process_time()
        plan = plan_scanline(zmap)
        wall = time.perf_counter() - t
        if wall < best:
            best = wall
            overlap = _threads.overlap_seconds() if _threads is not None else 0.0
        cpu = min(cpu, time.process_time() - c)
    ck = plan.checks
    out: dict[str, object] = {
        "wall": best, "cpu": cpu, "passes": len(plan.stages), "regions": _regions(plan),
        "left": f"p95 {ck.sim_left_over_part_p95:.4f} max {ck.sim_left_over_part_max:.3f}",
        "ok": ck.ok}
    if _threads is not None:
        from zwcore.sim import _morph  # its dilations keep their own second thread

        workers, dilation = _threads.WORKERS, _morph.THREADS
        _threads.WORKERS = _morph.THREADS = 1
        t, c = time.perf_counter(), time.process_time()
        plan_scanline(zmap)
        out["one_thread"] = (time.perf_counter() - t, time.process_time() - c)
        _threads.WORKERS, _morph.THREADS = workers, dilation
        out["overlap"] = overlap
    return out


def _child() -> None:
    """The figures of :func:`_compare` with the code on ``sys.path`` (a subprocess)."""
    plan_scanline(synthetic(129))  # load the compiled kernels
    out = {str(n): _figures(synthetic(n), 2 if n < 2049 else 1) for n in (513, 1025, 2049)}
    path = DATA / "mount_rush_zmap_0.1mm.npy"
    if path.exists():
        z = np.load(path).astype(np.float64)
        out["Rushmore"] = _figures(ZMap(z, x0=-40.958, y0=-24.696, dx=0.1, dy=0.1), 2)
    print(json.dumps(out))


def _compare(before: str) -> None:
    """This checkout against ``before``, each in a subprocess, back to back."""
    here = str(pathlib.Path(__file__).resolve().parents[1])
    runs = {}
    for name, tree in (("before", before), ("this", here)):
        env = dict(os.environ, PYTHONPATH=tree)
        done = subprocess.run([sys.executable, str(pathlib.Path(__file__).resolve()),
                               "--child"], env=env, cwd=tree, capture_output=True,
                              text=True, check=True)
        runs[name] = json.loads(done.stdout.strip().splitlines()[-1])
    for name, run in runs.items():
        for part, r in run.items():
            print(f"{name:>6s} {part:>8s}: {r['wall']:.2f} s wall, {r['cpu']:.2f} s CPU, "
                  f"{r['passes']} passes: {r['regions']}; left over part {r['left']} mm, "
                  f"ok {r['ok']}")
            if "overlap" in r:
                one_wall, one_cpu = r["one_thread"]
                print(f"{'':>15s}  two threads side by side {r['overlap']:.2f} s CPU (the "
                      f"wall they save on idle cores: CPU - that = "
                      f"{r['cpu'] - r['overlap']:.2f} s); one thread, same run: "
                      f"{one_wall:.2f} s wall, {one_cpu:.2f} s CPU")
    for part in runs["this"]:
        b, a = runs["before"][part], runs["this"][part]
        print(f"this/before {part}: CPU {a['cpu'] / b['cpu']:.2f}, wall "
              f"{a['wall'] / b['wall']:.2f}")
    for name, run in runs.items():
        print(f"{name} CPU growth per x4 cells: 1025/513 "
              f"{run['1025']['cpu'] / run['513']['cpu']:.2f}, 2049/1025 "
              f"{run['2049']['cpu'] / run['1025']['cpu']:.2f}")


def main() -> None:
    if "--child" in sys.argv:
        _child()
        return
    if "--before" in sys.argv:
        _compare(sys.argv[sys.argv.index("--before") + 1])
        return
    if "--unthinned" in sys.argv:
        plan_scanline(synthetic(129))  # load the compiled kernels
        unthinned((257, 513, 1025) if "--big" in sys.argv else (257, 513))
        return
    before = "--no-before" not in sys.argv
    sizes = (513, 1025, 2049)
    parts = {n: synthetic(n) for n in sizes}
    plan_scanline(synthetic(129))  # load the compiled kernels
    times = {n: run(f"synthetic {n}", parts[n], 3 if n < 2049 else 1) for n in sizes}
    _ratios("planned", times)
    if before:
        _stock.INCREMENTAL = False
        old = {n: run(f"before: synthetic {n}", parts[n], 1) for n in sizes}
        _stock.INCREMENTAL = True
        _ratios("before", old)
        print("speed-up (before/planned, wall): "
              + ", ".join(f"{n}² {old[n][0] / times[n][0]:.2f}" for n in sizes))
    path = DATA / "mount_rush_zmap_0.1mm.npy"
    if path.exists():
        z = np.load(path).astype(np.float64)
        rush = ZMap(z, x0=-40.958, y0=-24.696, dx=0.1, dy=0.1)
        run("Mount Rushmore", rush)
        plan = plan_scanline(rush)
        print("Rushmore tool sequence:", plan.tool_sequence, "stages", len(plan.stages),
              "stock_top", round(plan.stock_top, 4))
        for n in plan.notes:
            print("  note:", n)


if __name__ == "__main__":
    main()
