"""Dump fitted chains exactly (repr of every float) for before/after comparisons.

Run: ``python bench/chain_dump.py OUT.txt [--quick]``; compare two dumps with ``diff``.
A refactor that must keep chains bit-for-bit identical leaves the dump unchanged.
Cases: the bench curves, coarse polygons, noisy and random curves (seeded), the
filleted-polyline fallback forced everywhere, offsets and G-code programs, at
tolerances 0.1, 0.05 and 0.01.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from curves import BENCH_CURVES, coarse_ellipse, coarse_spiral, sine

from zwcore.arcs import _search
from zwcore.arcs.fit import ArcChain, fit_arcs
from zwcore.arcs.gcode import to_gcode
from zwcore.arcs.offset import offset_chain

TOLS = (0.1, 0.05, 0.01)


def dump_chain(ch: ArcChain) -> str:
    rows = [f"closed={ch.closed} corners={ch.corners} forced={ch.forced_corners}"
            f" dev={ch.max_deviation_points!r},{ch.max_deviation_chain!r}"
            f" kink={ch.max_kink_smooth!r}"]
    rows += [repr(s) for s in ch.segments]
    return "\n".join(rows)


def cases(quick: bool) -> Iterator[tuple[str, np.ndarray, bool, float, dict[str, object]]]:
    for name, make in BENCH_CURVES.items():
        pts, closed = make()
        for tol in TOLS[:2] if quick else TOLS:
            yield f"{name}@{tol}", pts, closed, tol, {}
    for n in (42, 84):
        for tol in TOLS:
            yield f"coarse_spiral{n}@{tol}", *coarse_spiral(n), tol, {}
    for tol in TOLS:
        yield f"coarse_ellipse42@{tol}", *coarse_ellipse(42), tol, {}
    rng = np.random.default_rng(7)
    pts, _ = sine(0.2, length=60.0)
    noisy = pts + rng.uniform(-0.01, 0.01, pts.shape)
    for tol in (0.05, 0.01):
        yield f"noisy_sine@{tol}", noisy, False, tol, {}
    for i in range(12):
        r = np.random.default_rng(100 + i)
        pts = r.uniform(-5, 5, (int(r.integers(3, 30)), 2))
        yield f"random{i}", pts, bool(i % 2), float(r.uniform(0.01, 1.0)), {}
    pts, closed = BENCH_CURVES["ellipse"]()
    yield "ellipse_maxr", pts, closed, 0.1, {"max_radius": 120.0}
    pts, closed = BENCH_CURVES["die_edge"]()
    yield "die_edge_c179", pts, closed, 0.1, {"corner_angle_deg": 179.0}


def forced_fallback() -> object:
    """Patch :class:`Fitter` so every run is the filleted-polyline fallback; returns the
    original ``run`` to restore."""
    orig = _search.Fitter.run

    def run(self, a, b, loop, allow_forced, t_start=None, resume=None):  # type: ignore[no-untyped-def]
        if not allow_forced:
            raise _search.Stuck
        self._expand = lambda level, b: []
        self.use_bridge = False
        self.one_piece_runs = False
        return orig(self, a, b, loop, allow_forced, t_start, resume)

    _search.Fitter.run = run  # type: ignore[method-assign]
    return orig


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    lines: list[str] = []
    for label, pts, closed, tol, kw in cases(args.quick):
        t0 = time.perf_counter()
        ch = fit_arcs(pts, tol, closed=closed, **kw)  # type: ignore[arg-type]
        print(f"{label}: {len(ch.segments)} seg {time.perf_counter() - t0:.2f} s", flush=True)
        lines += [f"== {label}", dump_chain(ch)]
        if label.startswith(("ellipse@", "die_edge@", "sine@")):
            for d in (-5.0, -2.0, 2.0, 5.0):
                res = offset_chain(ch, d)
                lines += [f"-- offset {d} vanished={res.vanished} reversed={res.reversed}",
                          dump_chain(res.chain)]
            lines += ["-- gcode", to_gcode(ch, feed=1000.0)]
    orig = forced_fallback()
    try:
        for i in range(16):
            r = np.random.default_rng(200 + i)
            pts = np.cumsum(r.normal(0, 1, (int(r.integers(3, 40)), 2)), axis=0) * 3.0
            tol = float(r.uniform(0.01, 0.5))
            ch = fit_arcs(pts, tol, closed=bool(i % 2))
            lines += [f"== fallback{i}", dump_chain(ch)]
    finally:
        _search.Fitter.run = orig  # type: ignore[method-assign]
    Path(args.out).write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
