"""Tool choice by reach and rest regions: plan time before/after, and Mount Rushmore.

Prints, in one run: the whole scan-line plan's time (best of ``--repeat``) with its
phases on the synthetic part of ``bench_scanline_core.py`` at 513² and 1025², for the
code of another checkout (``--before PATH``, e.g. a ``git worktree`` of the commit before
reach; without it only this tree is timed) and of this one, each in its own process,
and the ratios after/before and 1025²/513², and the known-answer parts' finishing
regions, cut-length factors and what is left (``tests/test_reach.py``); then
Mount Rushmore (../shared/data) with this tree: the tool sequence, each finishing
ball's region area, and the finishing cut length against finishing the whole part with
the smallest ball (both region area over the flat pick-feed that holds the tolerance);
each checkout's child also plans Mount Rushmore once (its finishing chain, factor, what
is left and CPU seconds, before and after in one run).
With ``--forced`` it also plans Mount Rushmore with the finishing chains Ø3 > Ø1 and
Ø2 > Ø1 (the estimate's ranking replaced for those runs) and prints the simulated regions.
With ``--chains`` it prints, for Mount Rushmore's candidate chains (the ranking's, Ø1
alone, Ø2 > Ø1, Ø3 > Ø2 > Ø1, Ø6 > Ø2 > Ø1, Ø6 > Ø3 > Ø2 > Ø1), the time ranking's
estimate per ball (passes, cut length, stretches, minutes), and with ``--programs`` also
plans each chain, generates its tool paths and prints the emitted program's time estimate
(roughing and finishing; minutes per chain, slow).
With ``--known-chains`` it prints instead, for the known-answer parts (the 45° fillet,
the pockets, the 3 mm trench, the dome; with ``--with-bench`` also the 1025² part) and
their candidate chains, the ranking's estimate per ball against the emitted program's
minutes per stage (roughing levels and finishing balls apart): where the estimate misses.
Usage: ``python bench/bench_reach.py [--before ../zwplan-old] [--sizes 513 1025]
[--forced] [--chains [--programs]]`` or ``python bench/bench_reach.py --known-chains
[--with-bench]``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "mount_rush_zmap_0.1mm.npy"


def _known_parts() -> dict[str, object]:
    """The known-answer parts of ``tests/test_reach.py`` and the trenches of
    ``tests/test_scanline_stock.py`` (same geometry, written out here)."""
    import numpy as np

    from zwcore import ZMap

    x = (np.arange(129) - 64) * 0.25
    r = np.hypot(*np.meshgrid(x, x))
    pocket = np.where(r < 8.0, 8.0 - np.sqrt(np.maximum(64.0 - r * r, 0.0)), 8.0)
    al, h, rf = math.radians(45.0), 0.2, 3.0
    xf = np.arange(0.0, 60.0 + 1e-9, h)
    xt, zt = 20.0 + rf * math.sin(al), rf - rf * math.cos(al)
    prof = np.where(xf < 20.0, 0.0,
                    np.where(xf < xt, rf - np.sqrt(np.maximum(rf * rf - (xf - 20.0) ** 2, 0.0)),
                             zt + math.tan(al) * (xf - xt)))
    fillet = np.tile(np.minimum(prof, 25.0), (121, 1))
    rect = np.zeros((161, 201))
    rect[40:121, 40:161] = -5.0
    parts = {"R 8 pocket": ZMap(pocket, dx=0.25, dy=0.25),
             "45° fillet": ZMap(fillet, dx=h, dy=h),
             "rectangular pocket": ZMap(rect, dx=0.25, dy=0.25)}
    xs = np.arange(129) * 0.25
    for width in (2.0, 3.0):
        z = np.zeros((129, 129))
        z[:, np.abs(xs - xs[-1] / 2) <= width / 2] = -20.0
        parts[f"trench {width:g} mm"] = ZMap(z, dx=0.25, dy=0.25)
    return parts


def _known() -> dict[str, dict[str, object]]:
    from zwcore.scanline.planner import plan_scanline

    out: dict[str, dict[str, object]] = {}
    for name, zmap in _known_parts().items():
        plan = plan_scanline(zmap)
        fin = [s for s in plan.stages if s.level == plan.depth and s.pass_index == 1]
        r = plan.reach
        out[name] = {
            "regions": " > ".join(f"{s.tool.id} {100 * s.region_area_fraction:.1f} %"
                                  for s in fin),
            "factor": r.smallest_ball_cut_length / r.finishing_cut_length,
            "left": f"{r.unreachable_area:.4g} mm² up to {r.unreachable_max_height:.4g} mm"}
    return out


def _child(sizes: list[int], repeat: int) -> None:
    """Time the plans with the code on ``sys.path`` (run in a subprocess)."""
    sys.path.insert(0, str(ROOT / "bench"))
    from bench_scanline_core import synthetic

    from zwcore.scanline.planner import plan_scanline

    plan_scanline(synthetic(65))  # compile / load the kernels outside the timing
    out = {}
    for n in sizes:
        zmap = synthetic(n)
        best, cpu, phases = float("inf"), float("inf"), {}
        for _ in range(repeat):
            t, c = time.perf_counter(), time.process_time()
            plan = plan_scanline(zmap)
            took = time.perf_counter() - t
            cpu = min(cpu, time.process_time() - c)
            if took < best:
                best = took
                phases = {}
                for name, sec in plan.timings:
                    phases[name] = phases.get(name, 0.0) + sec
        regions = {s.tool.id: round(100 * s.region_area_fraction, 2) for s in plan.stages
                   if s.level == plan.depth and s.region_area_fraction is not None}
        factor = (plan.reach.smallest_ball_cut_length / plan.reach.finishing_cut_length
                  if plan.reach is not None else None)
        out[n] = {"seconds": best, "cpu": cpu, "phases": phases, "passes": len(plan.stages),
                  "tools": list(plan.tool_sequence), "regions": regions, "factor": factor}
    out["known"] = _known()
    out["rushmore"] = _rushmore_child()
    print(json.dumps(out))


def _rushmore_child() -> dict[str, object] | None:
    """Mount Rushmore planned once with the code on ``sys.path`` (CPU seconds: the machine
    is shared), its finishing chain, factor and what is left."""
    import numpy as np

    from zwcore import ZMap
    from zwcore.scanline.planner import plan_scanline

    if not DATA.exists():
        return None
    zmap = ZMap(np.load(DATA).astype(np.float64), dx=0.1, dy=0.1)
    c = time.process_time()
    plan = plan_scanline(zmap)
    cpu = time.process_time() - c
    fin = [s for s in plan.stages if s.level == plan.depth and s.pass_index == 1]
    r = plan.reach
    return {"cpu": cpu, "passes": len(plan.stages),
            "finishing": " > ".join(f"{s.tool.id} {100 * s.region_area_fraction:.1f} % "
                                    f"({s.pass_count} passes)" for s in fin),
            "factor": r.smallest_ball_cut_length / r.finishing_cut_length,
            "left": f"{r.unreachable_area:.0f} mm² up to {r.unreachable_max_height:.2f} mm"}


def _run(tree: str, sizes: list[int], repeat: int) -> dict[str, dict]:
    env = dict(os.environ, PYTHONPATH=tree)
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", "--repeat", str(repeat),
           "--sizes", *map(str, sizes)]
    done = subprocess.run(cmd, env=env, cwd=tree, capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def _sizes(before: str | None, sizes: list[int], repeat: int) -> None:
    runs = {"after": _run(str(ROOT), sizes, repeat)}
    if before is not None:
        runs = {"before": _run(before, sizes, repeat), **runs}
    print("| code | cells | plan s (wall) | plan s (CPU) | passes | tools | finishing regions % "
          "| factor | phases (s, wall) |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for name, run in runs.items():
        for n in sizes:
            r = run[str(n)]
            ph = ", ".join(f"{k} {v:.2f}" for k, v in r["phases"].items() if v >= 0.01)
            reg = ", ".join(f"{k} {v:g}" for k, v in r.get("regions", {}).items())
            fac = f"{r['factor']:.2f}" if r.get("factor") is not None else "-"
            print(f"| {name} | {n}² | {r['seconds']:.2f} | {r['cpu']:.2f} | {r['passes']} | "
                  f"{' > '.join(r['tools'])} | {reg} | {fac} | {ph} |")
    for n in sizes if "before" in runs else []:
        b, a = runs["before"][str(n)], runs["after"][str(n)]
        print(f"after / before at {n}²: wall {a['seconds'] / b['seconds']:.2f}, "
              f"CPU {a['cpu'] / b['cpu']:.2f}")
    if len(sizes) > 1:
        for name, run in runs.items():
            lo, hi = run[str(sizes[0])], run[str(sizes[-1])]
            print(f"{name}: {sizes[-1]}² / {sizes[0]}²: wall {hi['seconds'] / lo['seconds']:.2f}, "
                  f"CPU {hi['cpu'] / lo['cpu']:.2f}")
    print("\n| code | Mount Rushmore finishing | passes | factor | left above the tolerance "
          "| plan s (CPU) |")
    print("| --- | --- | --- | --- | --- | --- |")
    for name, run in runs.items():
        r = run.get("rushmore")
        if r is not None:
            print(f"| {name} | {r['finishing']} | {r['passes']} | {r['factor']:.2f} "
                  f"| {r['left']} | {r['cpu']:.2f} |")
    print("\n| code | part | finishing regions | factor | left above the tolerance |")
    print("| --- | --- | --- | --- | --- |")
    for part in runs["after"]["known"]:
        for name, run in runs.items():
            k = run["known"][part]
            print(f"| {name} | {part} | {k['regions']} | {k['factor']:.2f} | {k['left']} |")


def _rushmore(forced: bool, roughing: bool = False, chains: bool = False,
              programs: bool = False) -> None:
    import numpy as np

    sys.path.insert(0, str(ROOT))
    from zwcore import ZMap, plan_scanline

    if not DATA.exists():
        print(f"no data at {DATA}")
        return
    z = np.load(DATA).astype(np.float64)
    zmap = ZMap(z, dx=0.1, dy=0.1)
    t, c = time.perf_counter(), time.process_time()
    plan = plan_scanline(zmap)
    took, cpu = time.perf_counter() - t, time.process_time() - c
    area = z.size * 0.01
    print(f"\nMount Rushmore {z.shape[0]} x {z.shape[1]} at 0.1 mm: plan {took:.2f} s "
          f"({cpu:.2f} s CPU), "
          f"{len(plan.stages)} passes, {' > '.join(plan.tool_sequence)}")
    print("phases: " + ", ".join(f"{k} {v:.2f}" for k, v in plan.timings if v >= 0.01))
    for s in plan.stages:
        if s.level == plan.depth and s.pass_index == 1:
            print(f"  {s.tool.id}: region {100 * s.region_area_fraction:.1f} % "
                  f"({s.region_area_fraction * area:.0f} mm²), {s.pass_count} passes, "
                  f"estimated cut {s.estimated_cut_length:.0f} mm")
    r = plan.reach
    if r is not None:
        print(f"finishing cut {r.finishing_cut_length:.0f} mm, smallest ball everywhere "
              f"{r.smallest_ball_cut_length:.0f} mm: factor "
              f"{r.smallest_ball_cut_length / r.finishing_cut_length:.2f}")
        print(f"left above the tolerance: {r.unreachable_area:.0f} mm², up to "
              f"{r.unreachable_max_height:.2f} mm")
    _why(z, 0.1, plan.tolerance)
    if roughing:
        _roughing(z)
    if forced:
        _forced(z, [["BEM-D3", "BEM-D1"], ["BEM-D2", "BEM-D1"]])
    if chains:
        _chains(z, programs)


def _forced(z: object, chains: list[list[str]]) -> None:
    """Mount Rushmore planned with given finishing chains instead of the estimate's choice
    (its ranking function replaced for the run): the simulated rest regions, cut-length
    factor and what is left, as the plan reports them."""
    import numpy as np

    from zwcore import ZMap
    from zwcore.scanline import _regions
    from zwcore.scanline.planner import plan_scanline

    ranked = _regions._plan
    print("\n| forced chain | plan s | passes | finishing regions (simulated) | factor "
          "| left above the tolerance |")
    print("| --- | --- | --- | --- | --- | --- |")
    try:
        for chain in chains:
            _regions._plan = _fixed(chain)
            t = time.perf_counter()
            plan = plan_scanline(ZMap(np.asarray(z), dx=0.1, dy=0.1))
            took = time.perf_counter() - t
            fin = [s for s in plan.stages if s.level == plan.depth and s.pass_index == 1]
            r = plan.reach
            regions = " > ".join(f"{s.tool.id} {100 * s.region_area_fraction:.1f} %"
                                 for s in fin)
            print(f"| {' > '.join(chain)} | {took:.1f} | {len(plan.stages)} | {regions} "
                  f"| {r.smallest_ball_cut_length / r.finishing_cut_length:.2f} "
                  f"| {r.unreachable_area:.0f} mm² up to {r.unreachable_max_height:.2f} mm |")
    finally:
        _regions._plan = ranked


def _fixed(ids: list[str]):  # type: ignore[no-untyped-def]
    """A stand-in for ``_regions._plan`` that returns the chain ``ids`` (and the time
    estimate of each of its balls); a ball with no rest region after the one before it
    is left out (the plan would drop its stage)."""
    def fixed(balls: list, reach, bound: bool = True):  # type: ignore[no-untyped-def]
        names = [b.id for b in balls]
        order = [names.index(i) for i in ids]
        times = [reach.main_time(balls, order[0])]
        kept = order[:1]
        for b in order[1:]:
            if reach.cost(balls[kept[-1]].radius, balls[b]) is not None:
                times.append(reach.times[balls[kept[-1]].radius, balls[b].id])
                kept.append(b)
        return kept, times
    return fixed


#: Candidate finishing chains of the known-answer parts (``--known-chains``): the ones
#: the issue's table names, the ranking's own first.
KNOWN_CHAINS: dict[str, list[list[str]]] = {
    "45° fillet": [["BEM-D20", "BEM-D5"], ["BEM-D16", "BEM-D5"], ["BEM-D12", "BEM-D5"],
                   ["BEM-D10", "BEM-D4"]],
    "R 8 pocket": [["BEM-D16"], ["BEM-D20", "BEM-D16"], ["BEM-D8"]],
    "rectangular pocket": [["BEM-D16", "BEM-D3", "BEM-D1"], ["BEM-D20", "BEM-D3", "BEM-D1"],
                           ["BEM-D6", "BEM-D1"]],
    "trench 3 mm": [["BEM-D4", "BEM-D3", "BEM-D1"], ["BEM-D20", "BEM-D3"],
                    ["BEM-D16", "BEM-D3", "BEM-D1"]],
    "dome": [["BEM-D20"], ["BEM-D16"], ["BEM-D12"]],
    "1025²": [["BEM-D20", "BEM-D8", "BEM-D2", "BEM-D1"], ["BEM-D16", "BEM-D8", "BEM-D2", "BEM-D1"],
              ["BEM-D10", "BEM-D3", "BEM-D2", "BEM-D1"], ["BEM-D6", "BEM-D2", "BEM-D1"]],
}


def _known_chains(bench: bool) -> None:
    """Per known-answer part (and with ``bench`` the 1025² part of
    ``bench_scanline_core.py``) and candidate chain (:data:`KNOWN_CHAINS`, the
    ranking's own first): the ranking's estimate per ball (passes, depth met, minutes)
    and the emitted program's minutes (``scanline_toolpaths``, no verification) per
    stage, roughing levels (``Ø/L<level>``) and finishing balls (``Ø/fin``) apart, each
    ball's passes summed. What the estimate leaves out shows as the stages it has no
    figure for, or prices short."""
    import numpy as np

    from zwcore import ZMap
    from zwcore.scanline import _regions
    from zwcore.scanline.planner import plan_scanline
    from zwcore.toolpath import scanline_toolpaths

    known = _known_parts()
    parts: dict[str, tuple[ZMap, float]] = {n: (z, 0.01) for n, z in known.items()  # type: ignore[misc]
                                            if n in KNOWN_CHAINS}
    x = np.arange(-30.0, 30.0 + 1e-9, 0.25)
    xx, yy = np.meshgrid(x, x)
    parts["dome"] = (ZMap(np.sqrt(50.0**2 - xx**2 - yy**2), dx=0.25, dy=0.25), 0.005)
    if bench:
        sys.path.insert(0, str(ROOT / "bench"))
        from bench_scanline_core import synthetic
        parts["1025²"] = (synthetic(1025), 0.01)
    ranked_fn = _regions._plan
    print("\n| part | chain | estimate per ball: passes, depth mm, min | estimated min "
          "| program min | program per stage, min |")
    print("| --- | --- | --- | --- | --- | --- |")
    for name, (zmap, tol) in parts.items():
        ranked: list[str] = []
        for chain in [None, *KNOWN_CHAINS[name]]:
            if chain is not None and chain == ranked:
                continue
            got: dict[str, object] = {}

            def record(balls: list, reach, bound: bool = True,
                       chain: list[str] | None = chain, got: dict = got):
                order, times = (ranked_fn(balls, reach, bound) if chain is None
                                else _fixed(chain)(balls, reach))
                got["est"] = [(balls[j].id, t) for j, t in zip(order, times, strict=True)]
                return order, times

            try:
                _regions._plan = record
                plan = plan_scanline(zmap, tolerance=tol)
            finally:
                _regions._plan = ranked_fn
            est = got["est"]
            assert isinstance(est, list)
            ids = [i for i, _ in est]
            if chain is None:
                ranked = ids
            tp = scanline_toolpaths(zmap, plan, verify=False)
            per: dict[str, float] = {}
            for s, f in zip(plan.stages, tp.stage_figures(), strict=True):
                key = f"{s.tool.id}/{'fin' if s.level == plan.depth else f'L{s.level}'}"
                per[key] = per.get(key, 0.0) + f["time_min"]
            total = (sum(t.minutes for _, t in est)
                     + _regions.TOOL_CHANGE_MIN * (len(est) - 1))
            label = ("ranked: " if chain is None else "") + " > ".join(
                plan.reach.finishing_tools if plan.reach is not None else ids)
            print(f"| {name} | {label} | "
                  + "; ".join(f"{i} {t.passes}, {t.depth:.1f}, {t.minutes:.2f}" for i, t in est)
                  + f" | {total:.2f} | {tp.time_min:.2f} | "
                  + ", ".join(f"{k} {v:.2f}" for k, v in per.items()) + " |", flush=True)


CHAINS = [["BEM-D1"], ["BEM-D2", "BEM-D1"], ["BEM-D3", "BEM-D2", "BEM-D1"],
          ["BEM-D6", "BEM-D2", "BEM-D1"], ["BEM-D6", "BEM-D3", "BEM-D2", "BEM-D1"]]


def _chains(z: object, programs: bool) -> None:
    """Mount Rushmore's candidate chains: the time ranking's estimate per ball, and (with
    ``programs``) the emitted program's time of each chain planned with it."""
    import numpy as np

    from zwcore import ZMap
    from zwcore.grid.tools import default_tools
    from zwcore.scanline import _regions
    from zwcore.scanline.planner import plan_scanline
    from zwcore.toolpath import scanline_toolpaths

    balls = list(default_tools("ball"))
    reach = _regions._Reach(np.asarray(z), 0.1, 0.1, 0.01)
    c = time.process_time()
    order, _ = _regions._plan(balls, reach)
    ranking = time.process_time() - c
    ranked = [balls[j].id for j in order]
    print(f"\ntime ranking on Mount Rushmore: {' > '.join(ranked)} ({ranking:.2f} s CPU, "
          "the rest maps included)")
    print("| chain | estimate per ball: passes, cut m, stretches, min | estimated min "
          "| program min (roughing + finishing) |")
    print("| --- | --- | --- | --- |")
    chains = [ranked] + [c for c in CHAINS if c != ranked]
    ranked_fn = _regions._plan
    for chain in chains:
        _, times = _fixed(chain)(balls, reach)
        per = "; ".join(f"{i} {t.passes}, {t.cut_length / 1000:.0f}, {t.stretches:.0f}, "
                        f"{t.minutes:.0f}" for i, t in zip(chain, times, strict=True))
        est = sum(t.minutes for t in times) + _regions.TOOL_CHANGE_MIN * (len(times) - 1)
        prog = "-"
        if programs:
            try:
                _regions._plan = _fixed(chain)
                part = ZMap(np.asarray(z), dx=0.1, dy=0.1)
                plan = plan_scanline(part)
            finally:
                _regions._plan = ranked_fn
            tp = scanline_toolpaths(part, plan, verify=False)
            rough = sum(f["time_min"] for s, f in zip(plan.stages, tp.stage_figures(),
                                                      strict=True) if s.level != plan.depth)
            prog = f"{tp.time_min:.0f} ({rough:.0f} + {tp.time_min - rough:.0f})"
        print(f"| {' > '.join(chain)} | {per} | {est:.0f} | {prog} |", flush=True)


def _roughing(z: object) -> None:
    """Per roughing stage of the Mount Rushmore plan, the share of the part where the stock
    before the stage (the plan's passes replayed) already lies within the stage's
    allowance (a quarter of the next stage's flute length) above the stage's model: what
    a roughing region rule could skip."""
    import numpy as np

    from zwcore import ZMap
    from zwcore.scanline._stock import StockSim, run_pass
    from zwcore.scanline.planner import plan_scanline
    from zwcore.scanline.replay import _guard, _targets
    from zwcore.scanline.results import stage_at_nodes

    part = ZMap(np.asarray(z), dx=0.1, dy=0.1)
    plan = plan_scanline(part)
    sim = StockSim(part, plan.stock_top)
    guard = _guard(part, plan)
    stages = plan.stages
    print("\n| roughing stage | level | allowance mm | stock before within it % of the part |")
    print("| --- | --- | --- | --- |")
    for i, (s, target) in enumerate(zip(stages, _targets(plan), strict=True)):
        if s.pass_index == 1 and s.level != plan.depth:
            nxt = next(t for t in stages[i:] if t.level != s.level)
            allowance = 0.25 * nxt.tool.flute_length
            model = stage_at_nodes(stages[i + s.pass_count - 1], part)
            within = float((sim.stock - model <= allowance).mean())
            print(f"| {s.tool.id} | {s.level} | {allowance:g} | {100 * within:.1f} |")
        along = part.dx if s.lines.direction == "x" else part.dy
        stride = max(1, round(s.sim_position_spacing / along))
        run_pass(sim, target.copy(), s.spacing, s.tool, s.lines, stride, s.region, guard,
                 lift=s.sim_flute_rule_ok)


def _why(z: object, d: float, tol: float) -> None:
    """What the estimate sees on Mount Rushmore: per candidate main ball, where it leaves
    more than the tolerance, where the smallest ball does better by more than it (the
    seed), that seed grown by the small ball's radius (the region the ranking used before)
    and the positions within it that cut the material (the region the ranking uses now,
    as the plan's rest rule), with the two-ball chain's estimated cut length each way."""
    import numpy as np

    from zwcore.grid.tools import default_tools
    from zwcore.scanline._reach import within_distance
    from zwcore.scanline._regions import TOOL_CHANGE_MM, _Reach, flat_pick_feed, lattice

    balls = list(default_tools("ball"))
    small = balls[-1]
    reach = _Reach(np.asarray(z), d, d, tol)
    area = reach.z.size * d * d
    pf_s = flat_pick_feed(small.radius, tol)
    alone = area / pf_s
    print(f"\nwhy (nodal estimate, tolerance {tol:g}): {small.id} alone {alone:.0f} mm; "
          f"the chain main > {small.id} (one layer) with {small.id}'s region as the seed grown "
          "by its radius (the ranking before) and as the positions that cut (the ranking now)")
    print(f"| main | leaves > tol % | seed for {small.id} % | seed grown by R % "
          f"| positions that cut % | chain cut mm, grown | factor | chain cut mm, cutting "
          f"| factor |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for b in balls[:-1]:
        rest_b = reach.rest(b.radius, lattice(b.radius, d, d))
        nodes, mat, kn = reach._compare(b.radius, small.radius)
        better = np.zeros(mat.rest.shape, dtype=bool)
        better.flat[nodes] = True
        grown = within_distance(better, small.radius, kn * d, kn * d)
        reach.cost(b.radius, small)
        cutting = reach.cutter(small.radius, kn).last_region()
        safe = reach._safe_region(lattice(b.radius, d, d), kn, small.radius)
        if safe is not None:
            grown |= safe[0]
            cutting |= safe[0]
        main = area / flat_pick_feed(b.radius, tol) + TOOL_CHANGE_MM
        chain = main + grown.mean() * area / pf_s
        cut = main + cutting.mean() * area / pf_s
        print(f"| {b.id} | {100 * (rest_b > tol).mean():.1f} | {100 * better.mean():.1f} "
              f"| {100 * grown.mean():.1f} | {100 * cutting.mean():.1f} | {chain:.0f} "
              f"| {alone / chain:.2f} | {cut:.0f} | {alone / cut:.2f} |")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--before", default=None)
    ap.add_argument("--sizes", type=int, nargs="*", default=[513, 1025])
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--child", action="store_true")
    ap.add_argument("--no-rushmore", action="store_true")
    ap.add_argument("--roughing", action="store_true",
                    help="also print what a roughing region rule could skip on Mount Rushmore")
    ap.add_argument("--forced", action="store_true",
                    help="also plan Mount Rushmore with the chains D3 > D1 and D2 > D1")
    ap.add_argument("--chains", action="store_true",
                    help="Mount Rushmore's candidate chains: the time estimate per ball")
    ap.add_argument("--programs", action="store_true",
                    help="with --chains: each chain's emitted program time (slow)")
    ap.add_argument("--known-chains", action="store_true",
                    help="the known-answer parts' candidate chains: estimate per ball and "
                         "emitted program minutes per stage (then exits)")
    ap.add_argument("--with-bench", action="store_true",
                    help="with --known-chains: also the 1025² part (slow)")
    args = ap.parse_args()
    if args.child:
        _child(args.sizes, args.repeat)
        return
    if args.known_chains:
        _known_chains(args.with_bench)
        return
    if args.sizes:
        _sizes(args.before, args.sizes, args.repeat)
    if not args.no_rushmore:
        _rushmore(args.forced, args.roughing, args.chains, args.programs)


if __name__ == "__main__":
    main()
