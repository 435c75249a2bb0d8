"""Benchmark of the C1 arc fit: segment counts, deviations, kinks, time, scaling.

Run: ``.venv/bin/python bench/bench_arcs.py`` (``--quick`` skips the 1M-point run
and the greedy reference on the largest curves).

Columns: segments (arcs/lines), max deviation polyline->chain and chain->polyline
(dense), max kink at smooth junctions, corners, wall and CPU time of ``fit_arcs`` end
to end (the fastest of ``--repeat`` fits, 11 by default; ``cpu ms/seg`` of the fastest
fit and ``median`` of all: one fit of a few milliseconds scatters by tens of percent on
a shared machine), ``greedy<=``: an upper bound on the minimum number of arcs/lines WITHOUT
the C1 constraint when breaks sit on input points (greedy: each piece extended
as far as one circle or line keeps its points and the polyline between them
within the tolerance, i.e. an annulus of width <= 2 tol; a run counts as
feasible only with a witness circle/line, so the count is a valid partition:
exact if the local annulus search never misses, otherwise an upper bound),
``AW``: ArcWelder at the same tolerance (``curves.ARCWELDER_REFERENCE``, measured
with ArcWelder 1.2.0 and stored). With ``--arcwelder PATH``
(an ArcWelder console, bench/README.md) ArcWelder is run on each curve too:
``AW seg`` its segments with its G1 runs merged and ``ratio`` ours over it, its
deviation (both ways, sampled) and kink, ``AW str`` its segments with every straight
run of lines or flat arcs merged (the generous count) and ``ratio`` ours over that.
``--glyphs --contours``: after each glyph row, the contours whose counts differ from
ArcWelder's (or the greedy bound's). ``--floor``: counts on an ellipse and a clothoid at
0.05-0.002 mm against the asymptotic floor of chains whose pieces join (C0 or C1 alike,
:data:`JOINED_CONST`) and of pieces free to jump (:data:`FREE_CONST`).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np
from scipy.optimize import minimize

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from curves import ARCWELDER_REFERENCE, BENCH_CURVES, coarse_ellipse, coarse_spiral, ellipse

from zwcore.arcs.fit import fit_arcs


def _annulus_width(pts: np.ndarray, cc: np.ndarray) -> float:
    """Width of the thinnest annulus about ``cc`` holding the polyline ``pts``.

    The outer radius is reached at a vertex (distance is convex along a segment),
    the inner one may be inside a segment: both are exact for the given centre.
    """
    d = np.hypot(pts[:, 0] - cc[0], pts[:, 1] - cc[1])
    a, b = pts[:-1], pts[1:]
    ab = b - a
    den = np.maximum((ab * ab).sum(1), 1e-300)
    f = np.clip(((cc - a) * ab).sum(1) / den, 0.0, 1.0)
    near = a + f[:, None] * ab
    d_in = np.hypot(near[:, 0] - cc[0], near[:, 1] - cc[1])
    return float(d.max() - min(d.min(), d_in.min() if len(d_in) else d.min()))


def _fits_one_piece(pts: np.ndarray, tol: float) -> bool:
    """True only with a witness: a line or circle keeping the polyline ``pts`` within ``tol``.

    The witness is exact (the polyline's band about the found line/centre is measured
    exactly); the search for it (least-squares centre, then Nelder-Mead on the exact
    width) is local, so a missed better centre can only answer False wrongly.
    """
    if len(pts) <= 2:
        return True
    c0 = pts.mean(axis=0)
    x = pts - c0
    # line: the strip about the principal axis (segments lie within their end points')
    _, _, vt = np.linalg.svd(x, full_matrices=False)
    off = x @ vt[1]
    if float(off.max() - off.min()) <= 2.0 * tol:
        return True
    mat = np.column_stack([x[:, 0], x[:, 1], np.ones(len(x))])
    sol, *_ = np.linalg.lstsq(mat, (x * x).sum(1), rcond=None)
    c = 0.5 * sol[:2]
    if not (np.all(np.isfinite(c)) and np.hypot(*c) < 1e7 * (np.abs(x).max() + 1)):
        return False
    if _annulus_width(x, c) <= 2.0 * tol:
        return True
    scale = max(float(np.abs(x).max()), 1e-9)
    res = minimize(lambda cc: _annulus_width(x, cc), c, method="Nelder-Mead",
                   options={"xatol": 1e-9 * scale, "fatol": 1e-12 * scale, "maxiter": 4000})
    return bool(_annulus_width(x, res.x) <= 2.0 * tol)


def greedy_min_pieces(points: np.ndarray, tol: float, closed: bool) -> int:
    """Pieces (arcs or lines, no C1, breaks on input points), each run extended greedily.

    With an exact feasibility test this greedy count would be the exact minimum (runs
    are hereditary: a sub-run of a feasible run is feasible). The test used here only
    answers "feasible" with a witness (see :func:`_fits_one_piece`), so the count is a
    valid partition and an UPPER BOUND on that minimum (exact unless the local centre
    search misses a thinner annulus). Closed curves start at the first point.
    """
    pts = np.vstack([points, points[:1]]) if closed else points
    n = len(pts)
    i, count = 0, 0
    while i < n - 1:
        # gallop, then bisect for the last j such that pts[i..j] fits one circle/line;
        # ``lo`` is always a run certified by a witness
        lo, step = i + 1, 1
        hi = n
        while True:
            cand = min(i + 2 * step, n - 1)
            if cand <= lo:
                break
            if _fits_one_piece(pts[i : cand + 1], tol):
                lo = cand
                step *= 2
                if cand == n - 1:
                    break
            else:
                hi = cand
                break
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if _fits_one_piece(pts[i : mid + 1], tol):
                lo = mid
            else:
                hi = mid
        i = lo
        count += 1
    return count


def _timed_cpu(pts: np.ndarray, closed: bool, tol: float) -> tuple[float, float, object]:
    """Wall and CPU time (this process; the fit is single-threaded) of one fit: on a
    shared machine the CPU time is the steadier figure."""
    t0, c0 = time.perf_counter(), time.process_time()
    chain = fit_arcs(pts, tol, closed=closed)
    return time.perf_counter() - t0, time.process_time() - c0, chain


def _timed_best(pts: np.ndarray, closed: bool, tol: float,
                repeat: int) -> tuple[float, float, float, object]:
    """Wall time of the fastest of ``repeat`` fits, and their best and median CPU time:
    one fit of a few milliseconds on a shared machine scatters by tens of percent (the
    other jobs' cache and scheduling), the best of several is its cost, the median what
    a request sees under that load."""
    runs = [_timed_cpu(pts, closed, tol) for _ in range(max(repeat, 1))]
    cpu = sorted(r[1] for r in runs)
    best = min(runs, key=lambda r: r[1])
    return best[0], cpu[0], float(np.median(cpu)), best[2]


def _warm_up() -> None:
    """Before anything is timed, the compiled kernels loaded (or compiled) once per
    process, not counted against the first curve: importing :mod:`zwcore.arcs.warmup`
    fits the small curves that take every compiled path (as the service's workers do)."""
    import zwcore.arcs.warmup  # noqa: F401


def _corners_kept(chain: object, corners: np.ndarray, reach: float) -> int:
    """True corners with a corner junction of ``chain`` within ``reach`` mm."""
    segs = chain.segments  # type: ignore[attr-defined]
    at = np.array([segs[c].end for c in chain.corners]).reshape(-1, 2)  # type: ignore[attr-defined]
    if not len(at):
        return 0
    d = np.hypot(corners[:, None, 0] - at[None, :, 0], corners[:, None, 1] - at[None, :, 1])
    return int((d.min(axis=1) <= reach).sum())


def glyphs(quick: bool, arcwelder: str | None, contours: bool = False) -> None:
    """Glyph outlines (bench/glyphs.py): per sampling and tolerance, the totals over all
    contours against ArcWelder (``arcwelder``: its console) or the greedy bound;
    ``contours``: after each row, the contours where the counts differ (ours - its)."""
    from _arcwelder import deviation as aw_deviation
    from _arcwelder import max_kink as aw_max_kink
    from _arcwelder import merge_straight_runs, run_arcwelder
    from glyphs import GLYPHS, QUICK_GLYPHS, glyph_contours

    chars = QUICK_GLYPHS if quick else GLYPHS
    sets = glyph_contours(chars)
    _warm_up()
    ref = "AW seg" if arcwelder else "greedy<="
    print(f"Glyph outlines {chars!r} (DejaVu Sans, 50 mm high, {len(sets['even'])} closed"
          " contours), corner angle 30 deg\n")
    head = (f"{'sampling':8s} {'tol':>5s} {'points':>6s} {'seg':>5s} {'arc':>5s} {'line':>5s}"
            f" {'max dev':>8s} {'kink deg':>8s} {'corners':>9s} {'time s':>7s}"
            f" {'ms/seg':>6s} {'cpu s':>6s} {'cpu ms/seg':>10s} {ref:>8s} {'ratio':>5s}"
            + (f" {'AW dev':>8s} {'AW kink':>7s} {'AW s':>6s} {'AW str':>6s} {'ratio':>5s}"
               if arcwelder else ""))
    print(head)
    print("-" * len(head))
    for tol in (0.05, 0.01):
        for name in ("even", "chordal", "noisy"):
            n_pts = seg = arcs = lines = kept = n_corner = n_ref = 0
            n_str = 0
            diff: list[str] = []
            dev = kink = t_all = c_all = aw_dev = aw_kink = aw_t = 0.0
            for label, pts, corners in sets[name]:
                dt, dc, chain = _timed_cpu(pts, True, tol)
                n_ref0 = n_ref
                c_all += dc
                n_pts += len(pts)
                seg += len(chain.segments)
                arcs += chain.n_arcs
                lines += chain.n_lines
                dev = max(dev, chain.max_deviation_points, chain.max_deviation_chain)
                kink = max(kink, math.degrees(chain.max_kink_smooth))
                kept += _corners_kept(chain, corners, 0.2 + 3 * tol)
                n_corner += len(corners)
                t_all += dt
                if arcwelder:
                    aw, adt = run_arcwelder(arcwelder, pts, tol)
                    n_ref += len(aw)
                    aw_t += adt
                    aw_dev = max(aw_dev, *aw_deviation(aw, pts, True))
                    aw_kink = max(aw_kink, aw_max_kink(aw, True, corners, 0.2 + 3 * tol))
                    n_str += merge_straight_runs(aw, pts, True, tol)
                else:
                    n_ref += greedy_min_pieces(pts, tol, True)
                if len(chain.segments) != n_ref - n_ref0:
                    diff.append(f"{label} {len(chain.segments) - (n_ref - n_ref0):+d}")
            print(f"{name:8s} {tol:5.2f} {n_pts:6d} {seg:5d} {arcs:5d} {lines:5d} {dev:8.5f}"
                  f" {kink:8.1e} {kept:4d}/{n_corner:<4d} {t_all:7.2f}"
                  f" {1e3 * t_all / max(seg, 1):6.2f} {c_all:6.2f}"
                  f" {1e3 * c_all / max(seg, 1):10.2f}"
                  f" {n_ref:8d} {seg / max(n_ref, 1):5.2f}"
                  + (f" {aw_dev:8.5f} {aw_kink:7.1f} {aw_t:6.2f} {n_str:6d}"
                     f" {seg / max(n_str, 1):5.2f}" if arcwelder else ""),
                  flush=True)
            if contours:
                print("    ours - ref by contour:", ", ".join(diff) or "none", flush=True)


def _aw_columns(exe: str, pts: np.ndarray, closed: bool, tol: float, nseg: int) -> str:
    """ArcWelder's measured columns for one smooth curve: its segments (G1 runs merged),
    our count over its, its largest deviation (both ways, sampled), its largest kink
    (degrees) away from the input's corners (vertices turning more than 30 deg), and its
    count with straight runs of lines or flat arcs merged too, with our count over it."""
    from _arcwelder import (
        deviation,
        max_kink,
        merge_straight_runs,
        polyline_corners,
        run_arcwelder,
    )

    aw, _ = run_arcwelder(exe, pts, tol, closed)
    corners = polyline_corners(pts, closed)
    n_str = merge_straight_runs(aw, pts, closed, tol)
    return (f" {len(aw):6d} {nseg / len(aw):5.2f} {max(deviation(aw, pts, closed)):7.4f}"
            f" {max_kink(aw, closed, corners, 0.2 + 3 * tol):7.1f} {n_str:6d}"
            f" {nseg / n_str:5.2f}")


def coarse_polygon(n: int = 1000, edge: float = 10.0, turn_deg: float = 12.0,
                   flip: int = 15) -> np.ndarray:
    """An open polygon of ``n`` vertices, ``edge`` mm edges, turning ``turn_deg`` at
    every vertex, the turn changing sides every ``flip`` vertices (a meander)."""
    h = 0.0
    p = np.zeros(2)
    out = [p.copy()]
    for i in range(n - 1):
        p = p + edge * np.array([math.cos(h), math.sin(h)])
        out.append(p.copy())
        h += math.radians(turn_deg) * (1 if (i // flip) % 2 == 0 else -1)
    return np.array(out)


def _scaling(tol: float, quick: bool) -> None:
    """The closed ellipse sampled ever finer: time per point."""
    print("\nScaling (ellipse 100 x 50, closed, end to end incl. dense verification)")
    print(f"{'points':>9s} {'spacing mm':>10s} {'seg':>4s} {'time s':>7s} {'cpu s':>6s}"
          f" {'us/point':>9s} {'ratio vs prev':>13s}")
    perimeter = 484.4224
    runs = [("0.02 mm", 0.02)]
    sizes = [10_000, 100_000] + ([] if quick else [1_000_000])
    runs += [(f"{n} pts", perimeter / n) for n in sizes]
    prev: tuple[int, float] | None = None
    for _, step in runs:
        pts, closed = ellipse(step)
        dt, dc, chain = _timed_cpu(pts, closed, tol)
        ratio = ""
        if prev is not None:
            ratio = f"t x{dc / prev[1]:.1f} / N x{len(pts) / prev[0]:.1f}"
        print(f"{len(pts):9d} {step:10.5f} {len(chain.segments):4d} {dt:7.3f} {dc:6.3f}"
              f" {1e6 * dc / len(pts):9.2f} {ratio:>13s}")
        prev = (len(pts), dc)


def _coarse() -> None:
    """Coarse polygons: a line per edge and a fillet per vertex."""
    # coarse polygons at a tight tolerance: every edge a straight run, a line per edge
    # and a fillet per vertex (about two segments a point); the time must stay linear
    print("\nCoarse polygon, tol 0.01 (a line per edge, a fillet per vertex)")
    print(f"{'curve':22s} {'points':>6s} {'seg':>4s} {'arc':>4s} {'line':>4s} {'time s':>7s}"
          f" {'cpu s':>6s} {'cpu ms/seg':>10s}")
    coarse = [(f"spiral {n} pts", *coarse_spiral(n)) for n in (42, 84, 168)]
    coarse += [(f"ellipse 30x15 {n} pts", *coarse_ellipse(n)) for n in (42, 84)]
    for label, pts, closed in coarse:
        dt, dc, chain = _timed_cpu(pts, closed, 0.01)
        print(f"{label:22s} {len(pts):6d} {len(chain.segments):4d} {chain.n_arcs:4d}"
              f" {chain.n_lines:4d} {dt:7.3f} {dc:6.3f}"
              f" {1e3 * dc / len(chain.segments):10.2f}")
    print("\nCoarse polygon: 10 mm edges, 12 deg turns (sides change every 15), open, tol 0.05")
    print(f"{'vertices':>8s} {'seg':>5s} {'arc':>5s} {'line':>5s} {'time s':>7s} {'ms/seg':>6s}"
          f" {'cpu s':>6s} {'cpu ms/seg':>10s}")
    for n in (100, 1000):
        dt, dc, chain = _timed_cpu(coarse_polygon(n), False, 0.05)
        nseg = len(chain.segments)
        print(f"{n:8d} {nseg:5d} {chain.n_arcs:5d} {chain.n_lines:5d}"
              f" {dt:7.3f} {1e3 * dt / nseg:6.2f} {dc:6.3f} {1e3 * dc / nseg:10.2f}")


#: Local model of a stretch whose curvature varies linearly (``kappa' = c``): the normal
#: offset of the curve from a piece of curvature ``k`` is ``c s^3 / 6`` plus a quadratic,
#: so a chain's error is a cubic with leading coefficient ``c / 6`` on every piece. One
#: piece of length ``L`` alone (ends free) keeps ``|error| >= c L^3 / 192`` (Chebyshev);
#: pieces joined continuously, tangentially (C1) or not (C0, ArcWelder), need the error
#: continuous, and their best uniform pieces give the periodic Bernoulli monospline,
#: ``c L^3 / (72 sqrt 3) = c L^3 / 124.7`` (C0 cannot do better in the limit: an LP over
#: 24 pieces gives 1/125.5 for C0, 1/124.7 for C1; the optimal C0 junctions are C1).
FREE_CONST = 192.0
JOINED_CONST = 72.0 * math.sqrt(3.0)


def floor_count(dkappa_ds: np.ndarray, ds: np.ndarray, tol: float, const: float) -> float:
    """Asymptotic count of pieces ``sum |kappa'|^(1/3) ds / (const tol)^(1/3)`` of a curve
    given ``|kappa'|`` (1/mm^2) at parameter nodes and their arc-length weights ``ds``
    (both ``(K,)``): the limit for small ``tol`` of the fewest pieces, each of length
    ``(const tol / |kappa'|)^(1/3)`` (see :data:`JOINED_CONST`)."""
    return float(np.sum(np.abs(dkappa_ds) ** (1.0 / 3.0) * ds) / (const * tol) ** (1.0 / 3.0))


def floor(arcwelder: str | None) -> None:
    """Counts on smooth curves against the asymptotic floor of chains whose pieces join
    (:data:`JOINED_CONST`; a floor in the limit of small tolerances only: a few pieces
    at the ends of the curvature's range are not in it) and the floor of pieces free
    to jump (:data:`FREE_CONST`): ours, ArcWelder's where given, and their ratios."""
    from _arcwelder import run_arcwelder
    from curves import clothoid

    _warm_up()
    t = np.linspace(0.0, 2.0 * math.pi, 200_001)
    a, b = 30.0, 15.0
    speed = np.hypot(a * np.sin(t), b * np.cos(t))
    dk = np.gradient(a * b / speed**3, t) / speed
    w = np.gradient(t) * speed
    cases = [("ellipse 30x15", *ellipse(0.2, a, b), dk, w, tol) for tol in (0.05, 0.01, 0.002)]
    pts_c, _ = clothoid(0.2)
    n_c = len(pts_c) - 1
    cases += [("clothoid", pts_c, False, np.full(n_c, 0.1 / 200.0), np.full(n_c, 200.0 / n_c),
               tol) for tol in (0.01, 0.002)]
    print("Counts against the asymptotic floor (curvature varying linearly per piece)\n")
    head = (f"{'curve':14s} {'tol':>6s} {'points':>6s} {'free':>6s} {'joined':>6s} {'ours':>5s}"
            f" {'/joined':>7s}" + (f" {'AW':>5s} {'/joined':>7s}" if arcwelder else ""))
    print(head)
    print("-" * len(head))
    for label, pts, closed, dkc, wc, tol in cases:
        ours = len(fit_arcs(pts, tol, closed=closed).segments)
        lo = floor_count(dkc, wc, tol, JOINED_CONST)
        row = (f"{label:14s} {tol:6.3f} {len(pts):6d} {floor_count(dkc, wc, tol, FREE_CONST):6.1f}"
               f" {lo:6.1f} {ours:5d} {ours / lo:7.2f}")
        if arcwelder:
            n_aw = len(run_arcwelder(arcwelder, pts, tol, closed)[0])
            row += f" {n_aw:5d} {n_aw / lo:7.2f}"
        print(row, flush=True)


def load_mix(n: int) -> None:
    """The arc requests of ``bench/load.py`` (its body generators and coarse share,
    seeded), fitted in this process as the service's ``/v1/arcs`` does (a G-code
    program with its rounding reserved where asked): the core's share of their latency."""
    import random

    from load import COARSE_SHARE, _arcs, _coarse_polygon

    from zwcore.arcs.gcode import rounding_budget, to_gcode

    rng = random.Random(15)
    rows: dict[str, list[tuple[float, float, int]]] = {"fit_arcs": [], "fit_arcs_coarse": []}
    for _ in range(n):
        coarse = rng.random() < COARSE_SHARE
        body = _coarse_polygon(rng) if coarse else _arcs(rng)
        gcode = bool(body.get("gcode"))
        t0, c0 = time.perf_counter(), time.process_time()
        chain = fit_arcs(np.array(body["points"], dtype=float), body["tolerance"],
                         closed=body["closed"], reserve=rounding_budget(4) if gcode else 0.0)
        if gcode:
            to_gcode(chain, feed=1000.0)
        rows["fit_arcs_coarse" if coarse else "fit_arcs"].append(
            (time.perf_counter() - t0, time.process_time() - c0, len(chain.segments)))
    print(f"Arc requests of bench/load.py, {n} bodies (seed 15), fitted in-process\n")
    head = (f"{'operation':16s} {'n':>4s} {'seg p50':>7s} {'p50 ms':>7s} {'p99 ms':>7s}"
            f" {'max ms':>7s} {'cpu p50':>7s} {'cpu p99':>7s} {'cpu max':>7s}")
    print(head)
    print("-" * len(head))
    for name, got in rows.items():
        if not got:
            continue
        wall = np.array([g[0] for g in got]) * 1e3
        cpu = np.array([g[1] for g in got]) * 1e3
        seg = np.array([g[2] for g in got])
        print(f"{name:16s} {len(got):4d} {np.median(seg):7.0f} {np.median(wall):7.1f}"
              f" {np.percentile(wall, 99):7.1f} {wall.max():7.1f} {np.median(cpu):7.1f}"
              f" {np.percentile(cpu, 99):7.1f} {cpu.max():7.1f}")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="skip the 1M-point run")
    ap.add_argument("--glyphs", action="store_true", help="glyph outlines benchmark only")
    ap.add_argument("--arcwelder", metavar="PATH", help="ArcWelder console (see README)")
    ap.add_argument("--contours", action="store_true",
                    help="with --glyphs: the contours where the counts differ")
    ap.add_argument("--floor", action="store_true",
                    help="only the counts against the asymptotic floor (smooth curves)")
    ap.add_argument("--load-mix", type=int, metavar="N",
                    help="only the arc requests of bench/load.py: N bodies, in-process")
    ap.add_argument("--repeat", type=int, default=11, metavar="N",
                    help="fits per curve of the first table (best and median; default 11)")
    ap.add_argument("--seam", choices=("first_point", "free"), default="first_point",
                    help="fit_arcs' seam: where closed chains start (default first_point)")
    args = ap.parse_args()
    if args.seam != "first_point":
        import functools

        global fit_arcs  # every fit of this run with that seam
        fit_arcs = functools.partial(fit_arcs, seam=args.seam)
    print(f"fit_arcs seam: {args.seam}")
    if args.load_mix:
        _warm_up()
        load_mix(args.load_mix)
        return
    if args.glyphs:
        glyphs(args.quick, args.arcwelder, args.contours)
        return
    if args.floor:
        floor(args.arcwelder)
        return
    tol = 0.1
    _warm_up()
    print(f"C1 arc fit, tolerance {tol} mm, curves sampled at 0.5 mm; each curve fitted"
          f" {args.repeat} times: time s and cpu s of the fastest fit (CPU time,"
          " time.process_time), cpu ms/seg of the fastest and the median fit\n")
    head = (f"{'curve':10s} {'N':>6s} {'seg':>4s} {'arc':>4s} {'line':>4s} {'dev pts':>8s}"
            f" {'dev chain':>9s} {'kink':>8s} {'corners':>7s} {'time s':>7s} {'cpu s':>6s}"
            f" {'cpu ms/seg':>10s} {'median':>6s} {'greedy<=':>8s} {'AW':>7s}"
            + (f" {'AW seg':>6s} {'ratio':>5s} {'AW dev':>7s} {'AW kink':>7s} {'AW str':>6s}"
               f" {'ratio':>5s}" if args.arcwelder else ""))
    print(head)
    print("-" * len(head))
    for name, make in BENCH_CURVES.items():
        pts, closed = make()
        dt, dc, dc_med, chain = _timed_best(pts, closed, tol, args.repeat)
        greedy = greedy_min_pieces(pts, tol, closed)
        aw_a, aw_l = ARCWELDER_REFERENCE[name]
        aw = "-" if aw_a is None else (f"{aw_a}" + (f"+{aw_l}L" if aw_l else ""))
        nseg = len(chain.segments)
        print(f"{name:10s} {len(pts):6d} {nseg:4d} {chain.n_arcs:4d}"
              f" {chain.n_lines:4d} {chain.max_deviation_points:8.4f}"
              f" {chain.max_deviation_chain:9.4f} {chain.max_kink_smooth:8.1e}"
              f" {len(chain.corners):7d} {dt:7.3f} {dc:6.3f} {1e3 * dc / nseg:10.2f}"
              f" {1e3 * dc_med / nseg:6.2f} {greedy:8d} {aw:>7s}"
              + (_aw_columns(args.arcwelder, pts, closed, tol, nseg) if args.arcwelder else ""))
    _scaling(tol, args.quick)
    _coarse()
    print("\nArcWelder 2.0 on the 0.02 mm ellipse (24,223 points): 10.3 s (issue text)")
    if args.arcwelder:
        from _arcwelder import run_arcwelder

        pts, closed = ellipse(0.02)
        aw, adt = run_arcwelder(args.arcwelder, pts, tol, closed)
        print(f"ArcWelder here on it: {len(aw)} segments, {adt:.1f} s wall")


if __name__ == "__main__":
    main()
