"""ArcWelder as a reference for the glyph benchmark (``bench_arcs.py --glyphs
--arcwelder PATH``): the contour written as G1 moves, compressed by the ArcWelder
console at the same tolerance, and the output parsed back (G2/G3 with I J, G1 runs
merged where consecutive moves are collinear)."""

from __future__ import annotations

import itertools
import math
import re
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

WORD = re.compile(r"([A-Z])(-?\d+(?:\.\d+)?)")


def run_arcwelder(exe: str, pts: np.ndarray, tol: float) -> tuple[list[tuple], float]:
    """Segments ``("line", start, end)`` / ``("arc", start, end, centre, ccw)`` of
    ArcWelder's output for the closed contour ``pts``, and its wall time (s)."""
    loop = np.vstack([pts, pts[:1]])
    with tempfile.TemporaryDirectory() as tmp:
        src, dst = Path(tmp) / "in.gcode", Path(tmp) / "out.gcode"
        e = 0.0
        rows = ["G21", "G90", "M83", f"G0 X{loop[0, 0]:.4f} Y{loop[0, 1]:.4f}"]
        for a, b in itertools.pairwise(loop):
            e = math.dist(a, b) * 0.05  # extruding moves: ArcWelder welds only those
            rows.append(f"G1 X{b[0]:.4f} Y{b[1]:.4f} E{e:.5f}")
        src.write_text("\n".join(rows) + "\n")
        t0 = time.perf_counter()
        subprocess.run([exe, str(src), str(dst), f"--resolution-mm={2 * tol}",
                        "--path-tolerance-percent=100"], check=True, capture_output=True)
        dt = time.perf_counter() - t0
        text = dst.read_text()
    segs: list[tuple] = []
    pos = None
    for line in text.splitlines():
        w = dict(WORD.findall(line.split(";")[0]))
        g = w.get("G")
        if g is None or ("X" not in w and "Y" not in w):
            continue
        end = (float(w.get("X", pos[0] if pos else 0.0)), float(w.get("Y", pos[1] if pos else 0.0)))
        if g in ("0", "00"):
            pos = end
            continue
        assert pos is not None
        if g in ("1", "01"):
            if segs and segs[-1][0] == "line" and _collinear(segs[-1][1], segs[-1][2], end):
                segs[-1] = ("line", segs[-1][1], end)
            else:
                segs.append(("line", pos, end))
        elif g in ("2", "02", "3", "03"):
            c = (pos[0] + float(w["I"]), pos[1] + float(w["J"]))
            segs.append(("arc", pos, end, c, g in ("3", "03")))
        pos = end
    return segs, dt


def _collinear(a: tuple, b: tuple, c: tuple) -> bool:
    ab = np.subtract(b, a)
    bc = np.subtract(c, b)
    cr = abs(ab[0] * bc[1] - ab[1] * bc[0])
    return bool(cr <= 1e-9 * max(np.hypot(*ab) * np.hypot(*bc), 1e-300) and ab @ bc > 0)
