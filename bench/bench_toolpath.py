"""Tool paths and NC programs (issue 12): Mount Rushmore and a 1025² part, times and ratios
measured in the same run.

1. Mount Rushmore (../shared/data, 0.1 mm): scan-line paths of every stage, the program
   written, parsed back and simulated; each roughing stage's path computed on its stage
   model and on the full-resolution part (same lines, same guarantee against the part,
   the refine tolerance the plan gives the stage; the gouge measure's coarse looks follow
   the model's spacing, so they are off on the part). The part's block bounds are built
   once per plan and shared by every stage, both sides (as ``scanline_toolpaths`` does);
   a first pass on the stage models builds them and is reported on its own. Times wall
   and, on a shared machine the steadier figure, CPU.
2. A 1025² synthetic part: plan + tool paths + program + verification end to end, with
   where the time goes.

Both run the paths twice: sequentially (the lines comparable with earlier sessions: each
phase's wall and CPU) and with each stage's program written, read back and simulated on a
worker thread while the next stage's paths are laid (``overlap=True``, the default on two
cores or more), the wall saved measured in the same run, the program and figures compared.

The CL heights come from ``zwcore.sim.drop_cutter`` (bilinear) on each stage model; the
exact lift against the part's nodes follows.
Run: ``PYTHONPATH=. .venv/bin/python bench/bench_toolpath.py [N]`` (``N``: the 1025² paths
sequential and overlapped in turn N times more, the best wall of each).
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import zwcore.toolpath.simulate as sim_mod  # noqa: E402
from bench.bench_scanline_core import synthetic  # noqa: E402
from zwcore import ZMap, plan_scanline  # noqa: E402
from zwcore.toolpath import parse_program, scanline_toolpaths, simulate_program  # noqa: E402
from zwcore.toolpath._polyline import PartBounds, measure_block  # noqa: E402
from zwcore.toolpath.plans import _refine_tolerance, tool_numbers  # noqa: E402
from zwcore.toolpath.scanline_paths import scanline_stage_path, sim_cl_heights  # noqa: E402
from zwcore.toolpath.sweep import MIN_BLOCK_RADIUS  # noqa: E402

DATA = next((p for p in (ROOT.parent / "shared" / "data" / "mount_rush_zmap_0.1mm.npy",
             Path("/work/shared/data/mount_rush_zmap_0.1mm.npy")) if p.exists()),
            ROOT.parent / "shared" / "data" / "mount_rush_zmap_0.1mm.npy")


CL = sim_cl_heights



def finished_line(part, plan, chk) -> str:  # type: ignore[no-untyped-def]
    """Where the plan says it finishes, what the simulated program leaves over the part."""
    left = chk.machined - part.z
    over = int((plan.finished & (left > plan.tolerance)).sum())
    return (f"where the plan finishes ({plan.finished.mean():.1%} of the nodes) the program "
            f"leaves at most {chk.finished_over_part_max:.4f} mm at tolerance "
            f"{plan.tolerance:g}; {over} nodes over it; within tolerance "
            f"{chk.within_tolerance}")

def rushmore() -> None:
    z = np.load(DATA).astype(np.float64)
    part = ZMap(z, x0=-40.958, y0=-24.696, dx=0.1, dy=0.1)
    t = time.perf_counter()
    plan = plan_scanline(part)
    t_plan = time.perf_counter() - t
    print(f"Mount Rushmore {z.shape}: plan {t_plan:.2f} s, {len(plan.stages)} stages, "
          f"tolerance {plan.tolerance}")
    t, c = time.perf_counter(), time.process_time()
    tp = scanline_toolpaths(part, plan, CL, overlap=False)
    total, cpu = time.perf_counter() - t, time.process_time() - c
    timings = dict(tp.timings)
    chk = tp.check
    assert chk is not None
    print(f"tool paths + program + verification: {total:.2f} s ({cpu:.2f} s CPU, all threads) "
          + ", ".join(f"{k} {v:.2f} s" for k, v in tp.timings)
          + "; CPU " + ", ".join(f"{k} {v:.2f} s" for k, v in tp.cpu_timings))
    overlapped(part, plan, tp, total, cpu)
    print(f"program {len(tp.program) / 1e6:.1f} MB, {tp.program.count(chr(10))} blocks, "
          f"length {tp.length / 1000:.1f} m, time estimate {tp.time_min:.0f} min")
    print(f"verification: gouge {chk.gouge:.2e} mm, moves below part {chk.below_part_moves}, "
          f"rapids in material {chk.rapid_in_material:.2e} mm, final over part max "
          f"{chk.final_over_part_max:.3f} / p95 {chk.final_over_part_p95:.4f} mm")
    print(finished_line(part, plan, chk))
    print("| stage | tool | level | lines | segments | scallop | points | feed m | air m | "
          "rapid m | min | over model p95 mm |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    merged = iter(chk.stages)
    sc = None
    for i, (st, p, fig) in enumerate(zip(plan.stages, tp.stages, tp.stage_figures(),
                                         strict=True)):
        if i == 0 or tp.stages[i - 1].cutting.tool_number != p.cutting.tool_number:
            sc = next(merged)
        assert sc is not None
        print(f"| {i} | {st.tool.id} | {st.level} | {p.figures['lines']:.0f} | "
              f"{p.figures['segments']:.0f} | {p.figures['scallop_segments']:.0f} | "
              f"{p.figures['points']:.0f} | "
              f"{fig['feed_length'] / 1000:.2f} | {sc.air_feed_length / 1000:.2f} | "
              f"{fig['rapid_length'] / 1000:.2f} | {fig['time_min']:.1f} | "
              f"{sc.over_model_p95 if sc.over_model_p95 is not None else float('nan'):.3f} |")
    print(f"paths of all stages: {timings['paths']:.2f} s; simulation of the program: "
          f"{timings['simulate']:.2f} s (parse {timings['parse']:.2f} s)")

    # roughing stages: on their stage model vs on the full-resolution part, same run
    data = tool_numbers(list(dict.fromkeys(s.tool for s in plan.stages)), None)
    # on the part, the CL is computed on the part's rows the lines read (as on the stage
    # models); "whole CL" computes it on every row of the part (the former method)
    # the part's block bounds (gouge measure) are built once per plan and shared by its
    # stages (as scanline_toolpaths does): a first pass on the stage models builds them
    bounds = PartBounds(part)
    rough = [i for i, st in enumerate(plan.stages) if st.level != plan.depth]

    def path(i: int, on_part: bool, whole: bool = False) -> float:
        st = plan.stages[i]
        kw = dict(model=part.z, spacing=(part.dx, part.dy)) if on_part else {}
        t, c = time.perf_counter(), time.process_time()
        scanline_stage_path(part, st, i, data[st.tool.id],
                            (lambda m, tl: CL(m, tl)) if whole else CL,
                            clearance=plan.stock_top + 5,
                            chord_tolerance=0.25 * plan.tolerance, stock_top=plan.stock_top,
                            refine_tolerance=_refine_tolerance(plan, st), part_bounds=bounds,
                            **kw)
        cpu[on_part + whole] += time.process_time() - c
        return time.perf_counter() - t

    cpu = [0.0, 0.0, 0.0]
    t = time.perf_counter()
    for tool in {plan.stages[i].tool for i in rough}:  # the part side's skip blocks too
        if tool.radius >= MIN_BLOCK_RADIUS * min(part.dx, part.dy):
            bounds.skip_blocks(measure_block(tool.radius, min(part.dx, part.dy)))
    t_first = time.perf_counter() - t + sum(path(i, False) for i in rough)
    cpu = [0.0, 0.0, 0.0]
    print(f"roughing stages on stage models, first pass (it builds the part's block bounds, "
          f"once per plan): {t_first:.2f} s")
    print("| roughing stage | tool | model spacing mm | on stage model s | on the part s "
          "| ratio | on the part, whole CL s | ratio |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    t_model = t_full = t_whole = 0.0
    for i in rough:
        st = plan.stages[i]
        a, b, w = path(i, False), path(i, True), path(i, True, whole=True)
        t_model += a
        t_full += b
        t_whole += w
        print(f"| {i} | {st.tool.id} | {st.spacing[0]:g} | {a:.3f} | {b:.3f} | {b / a:.1f} "
              f"| {w:.3f} | {w / a:.1f} |")
    print(f"roughing stages together: {t_model:.2f} s on stage models, {t_full:.2f} s on the "
          f"part: {t_full / t_model:.1f}x ({t_whole:.2f} s with the whole CL on the part: "
          f"{t_whole / t_model:.1f}x)")
    print(f"  CPU: {cpu[0]:.2f} s on stage models, {cpu[1]:.2f} s on the part: "
          f"{cpu[1] / cpu[0]:.1f}x ({cpu[2]:.2f} s with the whole CL: {cpu[2] / cpu[0]:.1f}x)")


def overlapped(part: ZMap, plan, seq, seq_wall: float, seq_cpu: float) -> None:
    """Same run: the paths again with each stage's program written, read back and simulated
    on a worker thread while the next stage's paths are laid, against the sequential run
    just before (the same program and figures, checked here)."""
    t, c = time.perf_counter(), time.process_time()
    tp = scanline_toolpaths(part, plan, CL, overlap=True)
    total, cpu = time.perf_counter() - t, time.process_time() - c
    a, b = seq.check, tp.check
    same = (tp.program == seq.program and a.stages == b.stages
            and np.array_equal(a.machined, b.machined)
            and (a.gouge, a.final_over_part_max, a.final_over_part_p95)
            == (b.gouge, b.final_over_part_max, b.final_over_part_p95))
    print(f"  overlapped (each stage verified on a worker thread while the next one's paths "
          f"are laid): {total:.2f} s ({cpu:.2f} s CPU) against {seq_wall:.2f} s ({seq_cpu:.2f} "
          f"s CPU) sequential: {seq_wall - total:+.2f} s wall saved "
          f"({(seq_wall - total) / seq_wall:+.0%}); "
          + ", ".join(f"{k} {v:.2f} s" for k, v in tp.timings)
          + f"; same program and figures: {same}; load average {os.getloadavg()[0]:.1f}")


def end_to_end_1025() -> None:
    part = synthetic(1025)
    t0, c0 = time.perf_counter(), time.process_time()
    plan = plan_scanline(part)
    t_plan, c_plan = time.perf_counter() - t0, time.process_time() - c0
    tp = scanline_toolpaths(part, plan, CL, overlap=False)
    total, cpu = time.perf_counter() - t0, time.process_time() - c0
    chk = tp.check
    assert chk is not None
    print(f"\n1025² part: plan + tool paths + program + verification {total:.2f} s "
          f"(target <= 10 s; {cpu:.2f} s CPU, all threads; load average "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores): plan {t_plan:.2f} s, "
          + ", ".join(f"{k} {v:.2f} s" for k, v in tp.timings))
    print(f"  CPU: plan {c_plan:.2f} s, "
          + ", ".join(f"{k} {v:.2f} s" for k, v in tp.cpu_timings))
    print(f"  {len(plan.stages)} stages ("
          + " > ".join(dict.fromkeys(s.tool.id for s in plan.stages))
          + f"), program {len(tp.program) / 1e6:.1f} MB, length {tp.length / 1000:.1f} m, "
          f"time estimate {tp.time_min:.0f} min, gouge "
          f"{chk.gouge:.2e}, rapids in material {chk.rapid_in_material:.2e}, final over part "
          f"p95 {chk.final_over_part_p95:.4f} mm")
    print("  " + finished_line(part, plan, chk))
    print(f"  end to end with the verification overlapped (plan {t_plan:.2f} s + the run below):")
    t1 = time.perf_counter()
    overlapped(part, plan, tp, total - t_plan, cpu - c_plan)
    print(f"  = {t_plan + time.perf_counter() - t1:.2f} s end to end (target <= 10 s)")
    repeats_off(part, plan, tp)


def repeats_off(part: ZMap, plan, tp) -> None:
    """Same run: the simulation sweeping every move again (repeats included), the former
    method, against skipping repeats."""
    prog = parse_program(tp.program)
    table = {p.cutting.tool_number: p.tool for p in tp.stages}
    times = []
    for skip in (False, True):
        sim_mod.SKIP_REPEATS = skip
        t, c = time.perf_counter(), time.process_time()
        simulate_program(prog, table, part, plan.stock_top, tolerance=plan.tolerance)
        times.append((time.perf_counter() - t, time.process_time() - c))
    sim_mod.SKIP_REPEATS = True
    (a, ac), (b, bc) = times
    print(f"  same run, repeats swept again / skipped: simulation {a:.2f} s ({ac:.2f} s CPU)"
          f" / {b:.2f} s ({bc:.2f} s CPU)")


def alternate(repeats: int) -> None:
    """The 1025² paths + verification, sequential and overlapped in turn ``repeats`` times
    (one plan): the best wall of each, on a machine shared with other work (a single pair
    swings with the others' load)."""
    part = synthetic(1025)
    plan = plan_scanline(part)
    best = {False: (np.inf, np.inf), True: (np.inf, np.inf)}
    for _ in range(repeats):
        for overlap in (False, True):
            t, c = time.perf_counter(), time.process_time()
            scanline_toolpaths(part, plan, CL, overlap=overlap)
            wall, cpu = time.perf_counter() - t, time.process_time() - c
            best[overlap] = min(best[overlap], (wall, cpu))
    (a, ac), (b, bc) = best[False], best[True]
    print(f"\n1025² paths + program + verification, best of {repeats} in turn: sequential "
          f"{a:.2f} s ({ac:.2f} s CPU), overlapped {b:.2f} s ({bc:.2f} s CPU): "
          f"{a - b:+.2f} s wall saved ({(a - b) / a:+.0%}); load average "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")


def main() -> None:
    # compile (or load from numba's disk cache) every kernel outside the timings
    small = synthetic(65)
    scanline_toolpaths(small, plan_scanline(small), CL)
    if DATA.exists():
        rushmore()
    else:
        print(f"no data at {DATA}: Mount Rushmore skipped")
    end_to_end_1025()
    if len(sys.argv) > 1:  # e.g. ``bench_toolpath.py 3``: the overlap measured in turns
        alternate(int(sys.argv[1]))


if __name__ == "__main__":
    main()
