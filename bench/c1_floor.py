"""What tangent continuity costs in segments: joined (C0, ArcWelder's) against C1 chains.

Run: ``.venv/bin/python bench/c1_floor.py [--contours d0,b1 --tol 0.05]``.

Local model (small angles): a chain that follows a curve of curvature ``kappa(s)`` at a
normal offset ``e(s)`` has ``e'' = kappa(s) - k_i`` on its piece ``i`` (``k_i`` the
piece's constant curvature), so ``e = g - h`` with ``g'' = kappa`` and ``h`` a piecewise
quadratic with a knot at every junction: continuous for a chain whose pieces meet
(C0), with a continuous slope too for a C1 chain. For fixed junctions the smallest
``max |e|`` is a linear programme (:func:`minimax`); the junctions are then moved by a
local search (Nelder-Mead from an even spread, so the figure is an upper bound on the
model's optimum for that many pieces, and the counts below are upper bounds too).

Printed:

1. curvature varying linearly (``g = s^3 / 6``): ``max |e| = c L^3 / 124.7`` for both
   chains (the periodic Bernoulli monospline, ``72 sqrt 3 = 124.7``; a chain free to
   jump reaches ``c L^3 / 192``): tangent continuity costs nothing there;
2. across an extremum of curvature (``g = -s^4 / 12`` on ``[-1, 1]``, ends pinned as at
   corners): C1 needs up to 2.1x the offset of C0 with the same pieces (an even count
   of C1 pieces does no better than one fewer);
3. per run (between corners) of the given glyph contours, the fewest pieces each chain
   needs in the model at ``--tol``, the curvature taken from the outline sampled every
   0.05 mm (its Bezier pieces, bench/glyphs.py), and the totals (``--contours all``:
   every contour). Not a lower bound: the junction search is local and the model
   small-angle, so a real chain may need fewer (ours do on some contours); the C1 - C0
   difference is the model's estimate of what tangent continuity costs.

``--c1-minimax d0 5 11 --arcwelder PATH``: instead, the least deviation a C1 chain of as
many arcs as ArcWelder's segments 5..10 of contour ``d0`` (the bowl of the "d") reaches
(a local minimax, started from ArcWelder's arcs).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linprog, minimize

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from zwcore.arcs._geometry import points_to_segments_distance

FloatArray = NDArray[np.float64]


def minimax(s: FloatArray, g: FloatArray, knots: FloatArray, c1: bool) -> float:
    """Smallest ``max |g - h|`` over the grid ``s`` ``(K,)`` (values ``g`` ``(K,)``) of a
    piecewise quadratic ``h`` with the ``knots`` ``(P + 1,)`` (first and last: the grid's
    ends, where ``h = g``: pinned ends), continuous, and with a continuous slope if
    ``c1``."""
    p = len(knots) - 1
    piece = np.clip(np.searchsorted(knots, s, side="right") - 1, 0, p - 1)
    u = s - knots[piece]
    nv = 3 * p + 1
    rows = np.zeros((len(s), nv))
    idx = np.arange(len(s))
    rows[idx, 3 * piece] = 1.0
    rows[idx, 3 * piece + 1] = u
    rows[idx, 3 * piece + 2] = u * u
    ones = np.ones(len(s))
    # h - t <= g and -h - t <= -g: |g - h| <= t
    a_ub = np.vstack([np.c_[rows[:, :-1], -ones], np.c_[-rows[:, :-1], -ones]])
    b_ub = np.r_[g, -g]
    eq: list[FloatArray] = []
    beq: list[float] = []
    for i in range(p - 1):
        ln = knots[i + 1] - knots[i]
        r = np.zeros(nv)
        r[3 * i : 3 * i + 3] = [1.0, ln, ln * ln]
        r[3 * i + 3] = -1.0
        eq.append(r)
        beq.append(0.0)
        if c1:
            r = np.zeros(nv)
            r[3 * i + 1 : 3 * i + 3] = [1.0, 2.0 * ln]
            r[3 * i + 4] = -1.0
            eq.append(r)
            beq.append(0.0)
    r = np.zeros(nv)
    r[0] = 1.0
    eq.append(r)
    beq.append(float(g[0]))
    ln = knots[-1] - knots[-2]
    r = np.zeros(nv)
    r[3 * p - 3 : 3 * p] = [1.0, ln, ln * ln]
    eq.append(r)
    beq.append(float(g[-1]))
    cost = np.zeros(nv)
    cost[-1] = 1.0
    res = linprog(cost, A_ub=a_ub, b_ub=b_ub, A_eq=np.array(eq), b_eq=np.array(beq),
                  bounds=[(None, None)] * nv, method="highs")
    return float(res.fun) if res.status == 0 else math.inf


def best_knots(s: FloatArray, g: FloatArray, p: int, c1: bool, w: FloatArray | None = None,
               iters: int = 400, starts: int = 3,
               also: FloatArray | None = None) -> tuple[float, FloatArray]:
    """:func:`minimax` with ``p`` pieces, the junctions moved by Nelder-Mead from an even
    spread of arc length, of the weight ``w`` ``(K,)``, from the knots ``also``
    ``(p + 1,)`` (another chain's best) and from seeded random spreads (``starts`` in
    all); the smallest figure found and its knots."""
    if p == 1:
        one = np.array([s[0], s[-1]])
        return minimax(s, g, one, c1), one

    def knots(x: FloatArray) -> FloatArray:
        ln = np.exp(x - x.max())
        return s[0] + np.concatenate([[0.0], np.cumsum(ln / ln.sum())]) * (s[-1] - s[0])

    rng = np.random.default_rng(p)
    x0s = [np.zeros(p)]
    if also is not None:
        x0s.append(np.log(np.maximum(np.diff(also), 1e-12)))
    if w is not None:
        cw = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(s))])
        x0s.append(np.log(np.maximum(np.diff(np.interp(np.linspace(0.0, cw[-1], p + 1), cw,
                                                               s)), 1e-9)))
    while len(x0s) < starts:
        x0s.append(rng.normal(0.0, 0.3, p))
    best, at = math.inf, knots(x0s[0])
    for x0 in x0s:
        got = minimize(lambda x: minimax(s, g, knots(x), c1), x0, method="Nelder-Mead",
                       options={"maxiter": iters, "xatol": 1e-4, "fatol": 1e-12})
        for x in (got.x, x0):
            e = minimax(s, g, knots(x), c1)
            if e < best:
                best, at = e, knots(x)
    return best, at


def _models() -> None:
    s = np.linspace(0.0, 8.0, 1601)
    print("1. curvature varying linearly (g = s^3/6, 8 pieces of length 1, ends pinned):")
    for c1 in (False, True):
        e = minimax(s, s**3 / 6.0, np.arange(9.0), c1)
        print(f"   {'C1' if c1 else 'C0'}: max|e| = 1/{1.0 / e:.1f}")
    print("   a piece free to jump: 1/192.0 (Chebyshev); Bernoulli monospline: 1/124.7\n")
    print("2. across an extremum of curvature (g = -s^4/12 on [-1, 1], ends pinned):")
    s = np.linspace(-1.0, 1.0, 201)
    g = -(s**4) / 12.0
    print(f"   {'pieces':>6s} {'C0 max|e|':>10s} {'C1 max|e|':>10s} {'C1/C0':>6s}")
    for p in range(2, 7):
        e1, k1 = best_knots(s, g, p, True)
        # a C1 chain is a C0 chain: C0 searched from C1's junctions too
        e0, k0 = best_knots(s, g, p, False, also=k1)
        # and C1 from C0's junctions
        e1 = min(e1, best_knots(s, g, p, True, also=k0, starts=2)[0])
        print(f"   {p:6d} {e0:10.3e} {e1:10.3e} {e1 / e0:6.2f}")


def _runs(pts: FloatArray, corners: FloatArray) -> list[FloatArray]:
    """The closed outline ``pts`` cut at the samples nearest ``corners`` (a loop: one
    run from its first point round to it)."""
    if not len(corners):
        return [np.vstack([pts, pts[:1]])]
    at = sorted({int(np.argmin(np.hypot(*(pts - c).T))) for c in corners})
    ring = np.vstack([pts, pts])
    return [ring[a : (b if b > a else b + len(pts)) + 1]
            for a, b in zip(at, [*at[1:], at[0]], strict=True)]


def _fewest(run: FloatArray, tol: float, c1: bool, p_from: int = 1,
            p_max: int = 24) -> int | None:
    """Fewest pieces (``p_from..p_max``; the caller knows fewer fail) whose model offset
    stays within ``tol`` on ``run``."""
    d = np.diff(run, axis=0)
    ds = np.hypot(*d.T)
    s = np.concatenate([[0.0], np.cumsum(ds)])
    th = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
    kappa = np.gradient(th, 0.5 * (s[1:] + s[:-1]))
    # g'' = kappa (g' = turn from the first direction, g = offset from the first tangent)
    gp = np.concatenate([[0.0], np.cumsum(kappa * ds)])
    g = np.concatenate([[0.0], np.cumsum(0.5 * (gp[1:] + gp[:-1]) * ds)])
    w = np.abs(np.gradient(np.concatenate([kappa, kappa[-1:]]), s)) ** (1.0 / 3.0) + 1e-3
    # the constraints on a grid of about 250 points (every sample: 0.05 mm)
    keep = np.unique(np.r_[np.linspace(0, len(s) - 1, 250).astype(int), len(s) - 1])
    for p in range(p_from, p_max + 1):
        if best_knots(s[keep], g[keep], p, c1, w[keep], iters=200)[0] <= tol:
            return p
    return None


def _contours(labels: list[str], tol: float) -> None:
    from glyphs import glyph_contours

    sets = glyph_contours(chord_tol=0.005)
    print(f"\n3. glyph runs (between corners), tol {tol}: fewest pieces in the model")
    print(f"   {'contour':8s} {'run':>3s} {'mm':>6s} {'C0':>3s} {'C1':>3s}")
    t0 = t1 = 0
    for label, pts, corners in sets["even"]:
        if label not in labels and labels != ["all"]:
            continue
        fine = _resample(pts, 0.05)
        n0 = n1 = 0
        for r, run in enumerate(_runs(fine, corners)):
            length = float(np.hypot(*np.diff(run, axis=0).T).sum())
            # a straight run (within tol of its chord): one line either way. (Until session
            # 9 a run whose net turn was under 5 degrees counted as straight, so the
            # S-shaped 111 mm run of S0, 395 degrees of turning, counted one piece.)
            # (a closed run, a loop or a contour with one corner, has no chord: until
            # session 10 its zero chord made it "straight", one piece)
            chord = run[-1] - run[0]
            off = np.abs((run[:, 0] - run[0, 0]) * chord[1] - (run[:, 1] - run[0, 1]) * chord[0])
            if float(np.hypot(*chord)) > tol and float(off.max()) <= tol * float(np.hypot(*chord)):
                n0 += 1
                n1 += 1
                continue
            c0 = _fewest(run, tol, False)
            # a C1 chain is a C0 chain: it needs at least as many
            c1 = _fewest(run, tol, True, c0 or 1)
            print(f"   {label:8s} {r:3d} {length:6.1f} {c0 or '-':>3} {c1 or '-':>3}", flush=True)
            n0 += c0 or 99
            n1 += c1 or 99
        print(f"   {label:8s} all {'':6s} {n0:3d} {n1:3d}", flush=True)
        t0 += n0
        t1 += n1
    # (issue 15, session 9: all 34 contours at 0.05: 342 / 395; ArcWelder's chordal 333)
    print(f"   {'total':8s} {'':3s} {'':6s} {t0:3d} {t1:3d}", flush=True)


def _c1_arcs(x: FloatArray, start: FloatArray, n: int, per: int = 24) -> FloatArray:
    """Points ``(n * per, 2)`` of the C1 chain of ``n`` arcs from ``start`` with first
    direction ``x[0]``, curvatures ``x[1:n+1]`` and lengths ``x[n+1:]``."""
    th, (px, py) = x[0], start
    out = []
    f = np.linspace(0.0, 1.0, per)
    for k, ln in zip(x[1 : n + 1], x[n + 1 :], strict=True):
        sg = f * ln
        dx = (np.sin(th + k * sg) - np.sin(th)) / k
        dy = (np.cos(th) - np.cos(th + k * sg)) / k
        out.append(np.stack([px + dx, py + dy], 1))
        px, py = out[-1][-1]
        th += k * ln
    return np.vstack(out)


def _to_polyline(q: FloatArray, poly: FloatArray) -> FloatArray:
    """Distance of each point of ``q`` ``(Q, 2)`` to the polyline ``poly`` ``(K, 2)``."""
    return points_to_segments_distance(q, poly[:-1], poly[1:]).min(axis=1)


def c1_minimax(label: str, i0: int, i1: int, tol: float, exe: str) -> None:
    """Least two-sided deviation (SLSQP, local) of C1 chains with as many arcs as
    ArcWelder's segments ``i0..i1-1`` of contour ``label`` (chordal), through their end
    points, started from ArcWelder's arcs with their kinks averaged out."""
    from _arcwelder import _tangents, run_arcwelder
    from glyphs import glyph_contours

    pts = next(p for lb, p, _c in glyph_contours()["chordal"] if lb == label)
    segs = run_arcwelder(exe, pts, tol)[0][i0:i1]
    if any(sg[0] != "arc" for sg in segs):
        raise SystemExit("choose a stretch of ArcWelder's arcs only")
    a, b = np.array(segs[0][1]), np.array(segs[-1][2])
    ia, ib = (int(np.argmin(np.hypot(*(pts - q).T))) for q in (a, b))
    poly = np.vstack([pts, pts])[ia : ib + (0 if ib > ia else len(pts)) + 1]
    ks, lens = [], []
    for sg in segs:
        c = np.asarray(sg[3])
        r = float(np.hypot(*(np.asarray(sg[1]) - c)))
        a0, a1 = (math.atan2(*(np.asarray(q) - c)[::-1]) for q in (sg[1], sg[2]))
        sweep = (a1 - a0) % (2 * math.pi) if sg[4] else (a0 - a1) % (2 * math.pi)
        ks.append((1.0 if sg[4] else -1.0) / r)
        lens.append(sweep * r)
    n = len(segs)
    t0 = _tangents(segs[0])[0]
    x0 = np.r_[math.atan2(t0[1], t0[0]), ks, lens]

    def devs(x: FloatArray) -> FloatArray:
        q = _c1_arcs(x, a, n)
        return np.r_[_to_polyline(q, poly), _to_polyline(poly, q)]

    z0 = np.r_[x0, devs(x0).max()]
    got = minimize(lambda z: z[-1], z0, method="SLSQP", options={"maxiter": 400, "ftol": 1e-12},
                   constraints=[{"type": "ineq", "fun": lambda z: z[-1] - devs(z[:-1])},
                                {"type": "eq", "fun": lambda z: _c1_arcs(z[:-1], a, n)[-1] - b}])
    print(f"\n{label} segments {i0}..{i1 - 1} of ArcWelder at tol {tol}: {n} arcs; a C1 chain"
          f" of {n} arcs through the same ends: max deviation {devs(got.x[:-1]).max():.4f}"
          f" (SLSQP, local: {got.message})")


def _resample(pts: FloatArray, step: float) -> FloatArray:
    closed = np.vstack([pts, pts[:1]])
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(closed, axis=0).T))])
    at = np.arange(0.0, s[-1], step)
    return np.stack([np.interp(at, s, closed[:, 0]), np.interp(at, s, closed[:, 1])], 1)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--contours", default="",
                    help="glyph contours, e.g. d0,b1, or all (slow: ~35 min at 0.05)")
    ap.add_argument("--tol", type=float, default=0.05)
    ap.add_argument("--c1-minimax", nargs=3, metavar=("LABEL", "I0", "I1"),
                    help="a C1 chain with as many arcs as ArcWelder's segments I0..I1-1 of"
                    " a chordal glyph contour (needs --arcwelder; about a minute)")
    ap.add_argument("--arcwelder", metavar="PATH")
    args = ap.parse_args()
    if args.c1_minimax:
        lb, i0, i1 = args.c1_minimax
        c1_minimax(lb, int(i0), int(i1), args.tol, args.arcwelder)
        return
    _models()
    if args.contours:
        _contours(args.contours.split(","), args.tol)


if __name__ == "__main__":
    main()
