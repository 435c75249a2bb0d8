"""Run starts without a given tangent, and runs that are one piece.

A run of the C1 chain (:mod:`zwcore.arcs._search`) that starts at the curve's first point or
at a corner has no tangent handed to it: :func:`free_start` picks the one from which the
first piece reaches furthest (a line when it reaches nearly as far). A run that one piece
covers is that piece (:func:`one_piece_to_end`), and a closed curve that one circle fits
is that full circle (:func:`full_circle`). A fitted run's end can sometimes be done
with fewer pieces from the start of one of its last pieces (:func:`shorter_ends`).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from zwcore.arcs import _kernels
from zwcore.arcs._geometry import local_uv
from zwcore.arcs._pieces import Piece, ToleranceBand

FloatArray = NDArray[np.float64]

__all__ = [
    "free_start", "free_start_tangents", "full_circle", "one_piece_to_end", "shorter_ends",
]


def free_start(
    band: ToleranceBand, p: FloatArray, k: int, b: int,
    cache: dict[tuple[int, int], tuple[FloatArray, int]] | None = None,
) -> tuple[FloatArray, int]:
    """Tangent at a run start that lets the first piece reach furthest.

    Returns the unit tangent and the last sample the first piece can cover
    from it (interval test). ``cache``: the answers for ``(k, b)`` so far, for starts
    ``p`` at sample ``k`` in bands of the same samples and working tolerance (a run's
    plain fit and its refits ask for the same start several times).
    """
    if cache is not None:
        got = cache.get((k, b))
        if got is None:
            got = cache[(k, b)] = free_start(band, p, k, b)
        return got[0].copy(), got[1]
    samples = band.samples
    d = np.hypot(samples[k + 1 : b + 1, 0] - p[0], samples[k + 1 : b + 1, 1] - p[1])
    far = np.flatnonzero(d >= 3.0 * band.tol)
    i0 = k + 1 + (int(far[0]) if far.size else len(d) - 1)
    th0 = math.atan2(samples[i0, 1] - p[1], samples[i0, 0] - p[0])
    span, n = 1.4, 57
    best_th, best_r = th0, k
    for _ in range(3):
        ths = best_th + np.linspace(-span, span, n)
        ts = np.stack([np.cos(ths), np.sin(ths)], axis=1)
        r = band.reach(np.repeat(p[None, :], n, axis=0), ts, k, b)
        top = np.flatnonzero(r == r.max())
        # the middle of the best range: robust to the grid and to noise
        mid = int(top[len(top) // 2])
        best_th, best_r = float(ths[mid]), int(r[mid])
        span = 2.0 * span / (n - 1)
        n = 21
    # a straight start is preferred when a line reaches nearly as far as the best arc
    ths = best_th + np.linspace(-0.2, 0.2, 81)
    lr, lth = band.line_reach(p, ths, k, b)
    if lr > k and band.cum[lr] - band.cum[k] >= 0.9 * (band.cum[best_r] - band.cum[k]):
        return np.array([math.cos(lth), math.sin(lth)]), best_r
    return np.array([math.cos(best_th), math.sin(best_th)]), best_r


def free_start_tangents(
    band: ToleranceBand, p: FloatArray, k: int, b: int,
    cache: dict[tuple[int, int], tuple[FloatArray, int]] | None = None,
) -> list[FloatArray]:
    """A few start tangents at a run start (no tangent given), best first
    (``cache``: see :func:`free_start`)."""
    t0, _r0 = free_start(band, p, k, b, cache)
    out = [t0]
    th0 = math.atan2(t0[1], t0[0])
    for d in (0.04, -0.04, 0.12, -0.12):
        out.append(np.array([math.cos(th0 + d), math.sin(th0 + d)]))
    return out



def one_piece_to_end(
    band: ToleranceBand, p: FloatArray, k: int, b: int, th_guess: float
) -> Piece | None:
    """One piece from ``p`` (free tangent) ending exactly at sample ``b``.

    The start tangent is the chord's or the one of the minimax circle through
    both ends (golden-section search about ``th_guess``).
    """
    samples = band.samples
    dx, dy = samples[b] - p
    chord = math.atan2(dy, dx)

    def worst(th: float) -> float:
        return _kernels.chord_circle_gap(samples, float(p[0]), float(p[1]), th, k, b)

    cands = [chord]
    # golden-section search for the minimax circle through both ends
    rel = math.remainder(th_guess - chord, 2.0 * math.pi)
    lo, hi = min(rel, 0.0) - 0.3, max(rel, 0.0) + 0.3
    lo, hi = max(lo, -1.5), min(hi, 1.5)
    gr = (math.sqrt(5.0) - 1.0) / 2.0
    a, c = lo, hi
    x1, x2 = c - gr * (c - a), a + gr * (c - a)
    f1, f2 = worst(chord + x1), worst(chord + x2)
    for _ in range(48):
        if f1 < f2:
            c, x2, f2 = x2, x1, f1
            x1 = c - gr * (c - a)
            f1 = worst(chord + x1)
        else:
            a, x1, f1 = x1, x2, f2
            x2 = a + gr * (c - a)
            f2 = worst(chord + x2)
    cands.append(chord + 0.5 * (a + c))
    for th in cands:
        t = np.array([math.cos(th), math.sin(th)])
        ub, vb = local_uv(p, t, samples[b : b + 1])
        q2 = float(ub[0] ** 2 + vb[0] ** 2)
        if q2 <= 0.0:
            continue
        kap = 0.0 if th == chord else float(2.0 * vb[0] / q2)
        if not band.radius_ok(kap):
            continue
        res = band.verify(p, t, kap, k, b, float(np.hypot(*(samples[k] - p))))
        if res is not None:
            piece = band.make_piece(p, t, kap, k, b, res)
            piece.end = samples[b].copy()
            return piece
    return None


def full_circle(band: ToleranceBand, a: int, b: int) -> Piece | None:
    """A whole closed run as one full circle through its first sample (if it fits)."""
    pts = band.samples[a:b]
    if len(pts) == 2:
        # a loop of two points (there and back): the circle on their segment as its
        # diameter (within half the segment of it both ways)
        c = pts.mean(axis=0)
    elif len(pts) < 2:
        return None
    else:
        c0 = pts.mean(axis=0)
        x = pts - c0
        mat = np.column_stack([x[:, 0], x[:, 1], np.ones(len(x))])
        rhs = (x * x).sum(axis=1)
        sol, *_ = np.linalg.lstsq(mat, rhs, rcond=None)
        c = c0 + 0.5 * sol[:2]
    p = band.samples[a]
    r = float(np.hypot(*(p - c)))
    if not (r > 0 and math.isfinite(r)):
        return None
    xx = band.samples[a : b + 1]
    area = float(np.sum(xx[:-1, 0] * xx[1:, 1] - xx[1:, 0] * xx[:-1, 1]))
    kap = 1.0 / r if area > 0 else -1.0 / r
    rv = (p - c) / r
    t = np.array([-rv[1], rv[0]]) if kap > 0 else np.array([rv[1], -rv[0]])
    if abs(kap) < band.kmin:  # any small radius: the whole loop is one circle
        return None
    # (two points: the second is the first's antipode, its foot point ambiguous, so the
    # circle's length is given)
    res = band.verify(p, t, kap, a, b, 0.0, 2.0 * math.pi * r if len(pts) == 2 else None)
    if res is None or abs(abs(kap * res[0]) - 2.0 * math.pi) > 1e-6:
        return None
    piece = band.make_piece(p, t, kap, a, b, (2.0 * math.pi / abs(kap), p.copy(), 0.0))
    piece.t_end = t.copy()
    return piece


def shorter_ends(
    pieces: list[Piece], band: ToleranceBand, b: int, ends: list[FloatArray],
    more: Callable[[Piece, float], list[list[Piece]]] | None = None,
) -> list[list[Piece]]:
    """``pieces`` (a run ending at sample ``b``) with their end replaced by no more pieces.

    From the start of one of the last few pieces: the single piece to ``b``, the biarc to
    ``b`` arriving along one of the tangents ``ends``, and the pieces ``more`` proposes
    from that piece's start (given the piece and the distance of its first sample). A
    refit whose junctions differ a little from the plain fit's may need extra short
    pieces at its end; these endings do without them.
    """
    out: list[list[Piece]] = []
    for s in range(len(pieces) - 2, max(len(pieces) - 7, 0) - 1, -1):
        pc = pieces[s]
        if pc.k >= b - 1:
            continue
        e = pieces[s - 1].e_end if s > 0 else 0.0
        tails: list[list[Piece]] = []
        one = band.piece_to_sample(pc.p, pc.t, pc.k, e, b)
        if one is not None:
            tails.append([one])
        for t1 in ends:
            two = band.biarc(pc.p, pc.t, pc.k, e, b, t1)
            if two is not None:
                tails.append(two)
        if more is not None:
            tails.extend(more(pc, e))
        out.extend([*pieces[:s], *tail] for tail in tails if s + len(tail) <= len(pieces))
    return out
