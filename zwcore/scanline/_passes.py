"""Scallops and pick-feeds of scan-line passes: strips, and extra lines where needed.

The design's scallop rule, ``h = R - sqrt(R^2 - e^2)`` with
``e = p / (2 cos theta)``, is the cusp between two ball paths a pick-feed
``p`` apart on a slope ``theta`` measured *across* the paths. For a plane
``z = a x + b y`` scanned along x, the two swept channels are cylinders of
radius ``R`` with axes along ``(1, 0, a)`` and a ``(0, p, b p)`` apart; their
distance is ``p sqrt((1 + a^2 + b^2) / (1 + a^2)) <= p sqrt(1 + b^2)``. So
``theta = atan |b|``, the slope across the lines, bounds the scallop, and the
steepest slope in any direction (the seed's choice) overestimates it wherever
the surface climbs along the lines: a wall crossed by the scan lines is
climbed along them and leaves flat-surface scallops.

Pick-feeds are chosen strip by strip, then cell by cell. A strip is the band
between two adjacent grid lines of the level (the nominal scan lines, which
run the whole length); its cells are the level's cells along it. On a
bilinear cell the slope across the lines is linear along them, so its largest
magnitude over the cell is the larger of the cell's two grid-edge differences
across the strip (exact), and over the strip the largest of those.

A strip whose scallop at the level spacing would exceed the budget on its
steepest cell is divided evenly into ``k`` lanes (the fewest that meet the
budget there): the candidate extra lines sit at ``m p``, ``p = w / k``,
``m = 1 .. k-1``. A cell whose own slope allows gaps up to ``a`` needs only the
lines at the multiples of ``g = floor(a / p)`` (the fewest lines with no gap
over ``g p <= a``: the greedy choice from the strip's lower edge). An extra
line therefore runs only over the cells that need it, extended by one tool
radius at each end (lead-in and lead-out, which also covers the ball's
contact point lying up to ``R`` ahead of or behind its centre along the
line); overlapping stretches merge. Every cell keeps at most ``g p`` between
adjacent lines, so the scallop bound holds cell by cell; the predicted
scallop is the largest over the cells. The scan direction is the one with the
shorter path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import partial
from typing import Literal

import numpy as np
from numba import njit
from numpy.typing import NDArray

from zwcore.errors import PlanningError
from zwcore.scanline._threads import both
from zwcore.scanline.results import ScanLines

__all__ = ["StripPlan", "cell_cross_curvatures", "cell_cross_slopes", "plan_strips",
           "scallop_height"]

F64 = NDArray[np.float64]


def scallop_height(pick_feed: float, slope: float, radius: float) -> float:
    """Scallop height of a ball on a slope, design section 3.

    Parameters
    ----------
    pick_feed : float
        Distance between scan lines, mm.
    slope : float
        ``tan(theta)`` of the surface across the scan lines.
    radius : float
        Ball radius, mm.

    Returns
    -------
    float
        ``R - sqrt(R^2 - e^2)`` with ``e = p / (2 cos theta)``; ``inf`` when
        ``e > R`` (the ball does not reach between adjacent lines).
    """
    e = 0.5 * pick_feed * math.sqrt(1.0 + slope * slope)
    if e > radius:
        return math.inf
    # Written without the cancellation of R - sqrt(R^2 - e^2) for small e.
    return e * e / (radius + math.sqrt(max(radius * radius - e * e, 0.0)))


def cell_cross_slopes(model: F64, sx: float, sy: float,
                      cells: tuple[int, int]) -> tuple[F64, F64]:
    """Largest slope across the lines in every cell, for both scan directions.

    Parameters
    ----------
    model : (my, mx) float64
        Node values of the bilinear model.
    sx, sy : float
    cells : (cy, cx)
        Cells touching the input's extent.

    Returns
    -------
    along_x : (cy, max(cx, 1)) float64
        Lines along x, strip ``r`` (rows ``r, r+1``), cell ``c``: ``max |dz/dy|``
        over the cell, the larger of its edge differences at columns ``c`` and
        ``c+1``.
    along_y : (cx, max(cy, 1)) float64
        Lines along y, strip ``c`` (columns ``c, c+1``), cell ``r``:
        ``max |dz/dx|`` over the cell.

    A model one node wide along the lines has one degenerate cell per strip
    (its single edge).
    """
    cy, cx = cells
    sub = model[: cy + 1, : cx + 1]
    ny, nx = sub.shape
    along_x = _edge_max(np.abs(np.diff(sub, axis=0)), cy) * (1.0 / sy) if cy > 0 and ny > 1 \
        else np.zeros((cy, max(cx, 1)))
    along_y = _edge_max(np.abs(np.diff(sub, axis=1)).T, cx) * (1.0 / sx) if cx > 0 and nx > 1 \
        else np.zeros((cx, max(cy, 1)))
    return along_x, along_y


def cell_cross_curvatures(model: F64, sx: float, sy: float,
                          cells: tuple[int, int]) -> tuple[F64, F64]:
    """Concave curvature across the lines at every grid line, per cell, both directions.

    Parameters
    ----------
    model : (my, mx) float64
    sx, sy : float
    cells : (cy, cx)

    Returns
    -------
    along_x : (cy + 1, max(cx, 1)) float64
        Lines along x, grid row ``i``, cell ``c``: ``max(d2z/dy2, 0)`` from the
        second difference across the row at columns ``c`` and ``c+1`` (the larger).
        The model is linear across between grid lines, so its concave curvature sits
        in the kinks at the rows; the second difference over the spacing squared is
        the kink's slope change per spacing, an upper bound of the mean curvature of
        the section that a ball can touch there. Edge rows copy their neighbour.
    along_y : (cx + 1, max(cy, 1)) float64
        The same for lines along y (columns, ``d2z/dx2``).
    """
    cy, cx = cells
    sub = model[: cy + 1, : cx + 1]
    return _kinks(sub, cy, sy), _kinks(sub.T, cx, sx)


def _kinks(sub: F64, strips: int, h: float) -> F64:
    """``(strips + 1, cells)``: concave second difference across rows, per cell."""
    ny, nx = sub.shape
    if strips == 0 or ny < 3:
        return np.zeros((strips + 1, max(nx - 1, 1)))
    d2 = np.maximum(sub[:-2] - 2.0 * sub[1:-1] + sub[2:], 0.0) * (1.0 / (h * h))
    d2 = np.concatenate((d2[:1], d2, d2[-1:]))[: strips + 1]
    return _edge_max(d2, strips + 1)


def _edge_max(edges: F64, strips: int) -> F64:
    """``(strips, cells)``: per cell, the larger of its two edges (nodes ``c``, ``c+1``)."""
    e = edges[:strips]
    n = e.shape[1]
    if n < 2:
        return np.array(e[:, :1], dtype=np.float64)
    return np.maximum(e[:, :-1], e[:, 1:])


@dataclass(frozen=True)
class StripPlan:
    """Scan lines of one pass.

    ``scan_lines`` counts distinct lines (each offset once, however many
    segments it has); ``path_length_whole_strips`` is the length the same lines
    would have if every extra line ran its strip's whole length.
    """

    direction: Literal["x", "y"]
    pick_feed: float
    pick_feed_max: float
    scan_lines: int
    scallop: float
    cross_slope: float
    reduced_strips: int
    reason: str | None
    lines: ScanLines
    path_length: float
    path_length_whole_strips: float
    extra_segments: int


def _scallops(gap: F64, slope: F64, radius: float) -> F64:
    """:func:`scallop_height` elementwise (``inf`` where the ball cannot reach)."""
    e2 = 0.25 * gap * gap * (1.0 + slope * slope)
    r = radius
    with np.errstate(invalid="ignore"):
        out: F64 = np.where(e2 <= r * r, e2 / (r + np.sqrt(np.maximum(r * r - e2, 0.0))), np.inf)
    return out


def _allowed(budget: float, radius: float, slope: F64) -> F64:
    """Largest pick-feed whose scallop on ``slope`` is at most ``budget``, elementwise.

    A hair under the exact value, so the recomputed scallop is at most the
    budget despite rounding.
    """
    b = min(budget, radius)
    if b <= 0.0:  # nothing left for scallops: as fine as rounding allows
        b = 1e-12 * radius
    e = math.sqrt(b * (2.0 * radius - b))
    out: F64 = 2.0 * e / np.sqrt(1.0 + slope * slope) * (1.0 - 1e-9)
    return out


def _lanes(widths: F64, slopes: F64, radius: float, budget: float,
           ) -> tuple[NDArray[np.bool_], NDArray[np.int64], F64, F64]:
    """Strips over budget, lanes per strip, lane width and the scallop at the level spacing."""
    h = _scallops(widths, slopes, radius)
    over = h > budget
    counts = np.ones(widths.size, dtype=np.int64)
    picks = widths.copy()
    if over.any():
        allowed = _allowed(budget, radius, slopes[over])
        k = np.ceil(widths[over] / allowed - 1e-12).astype(np.int64)
        k = np.maximum(k, 1)
        # The even split is at most ``allowed``; re-check against rounding.
        p = widths[over] / k
        bad = p > allowed
        k[bad] += 1
        counts[over] = k
        picks[over] = widths[over] / k
    return over, counts, picks, h


def _cell_steps(cell_slopes: F64, picks: F64, counts: NDArray[np.int64], radius: float,
                budget: float) -> NDArray[np.int64]:
    """``(m, cells)``: per cell of the reduced strips, the lanes ``g`` between needed lines.

    ``g`` is the most lanes whose width stays within the gap the cell's own
    slope allows (at least 1: the lane width meets the strip's steepest cell),
    at most the strip's lane count (no extra line needed).
    """
    allowed = _allowed(budget, radius, cell_slopes)
    p = picks[:, None]
    g = np.floor(allowed / p).astype(np.int64)
    g = np.minimum(g, counts[:, None])
    g -= (g * p > allowed).astype(np.int64)  # rounding of the floor
    return np.maximum(g, 1)


#: (extra line, cell) pairs one pass may lay out beyond 64 per cell: a 0.01 mm ball
#: over a 2 x 2 grid of 10**5 mm cells asked for 10**8 and held a worker (and GBs) for
#: minutes. Beyond this the plan is refused.
MAX_LINE_CELLS = 1 << 22


def _extra_lines(strips: NDArray[np.intp], counts: NDArray[np.int64], steps: NDArray[np.int64],
                 along: tuple[float, float], radius: float,
                 ) -> tuple[NDArray[np.intp], NDArray[np.int64], F64, F64]:
    """Segments of the extra lines: strip, line index ``m``, start and stop along the line.

    ``steps`` holds the reduced strips' ``g`` per cell (rows in the order of
    ``strips``); ``along`` is the cell length and the line length, mm. Line
    ``m`` of a strip is needed over the cells whose ``g`` divides ``m``; the
    work is proportional to those (line, cell) pairs, not to lines x cells.
    """
    sa, length = along
    k = counts[:, None]
    per = np.where(steps < k, (k - 1) // steps, 0)  # needed lines per cell
    row, cell = np.nonzero(per)
    if row.size == 0:
        none = np.zeros(0)
        return strips[:0], np.zeros(0, dtype=np.int64), none, none
    n = per[row, cell]
    if int(n.sum()) > max(MAX_LINE_CELLS, 64 * steps.size):
        raise PlanningError(
            "tools", f"one pass would need extra scan lines over {int(n.sum()):.3g} grid "
            f"cells, more than {MAX_LINE_CELLS}: the ball (radius {radius:g} mm) is too small "
            "for the grid's extent; use a larger ball or a smaller part")
    # Pairs (row, cell, m) with m = g, 2g, .. < k, grouped by line then cell.
    pr = np.repeat(row, n)
    pc = np.repeat(cell, n)
    first = np.cumsum(n) - n
    pm = (np.arange(pr.size) - np.repeat(first, n) + 1) * np.repeat(steps[row, cell], n)
    lines_per, cells = int(counts.max()), steps.shape[1]
    key = np.sort((pr * lines_per + pm) * cells + pc)
    pr, rest = np.divmod(key, lines_per * cells)
    pm, pc = np.divmod(rest, cells)
    # Runs of adjacent cells on one line, then the lead-in/out and merging.
    run = np.ones(pr.size, dtype=bool)
    run[1:] = (pr[1:] != pr[:-1]) | (pm[1:] != pm[:-1]) | (pc[1:] != pc[:-1] + 1)
    heads = np.flatnonzero(run)
    tails = np.append(heads[1:], pr.size) - 1
    rr, rm = pr[heads], pm[heads]
    lo = np.maximum(pc[heads] * sa - radius, 0.0)
    hi = np.minimum(np.minimum((pc[tails] + 1) * sa, length) + radius, length)
    new = np.ones(rr.size, dtype=bool)
    new[1:] = (rr[1:] != rr[:-1]) | (rm[1:] != rm[:-1]) | (lo[1:] > hi[:-1])
    keep = np.flatnonzero(new)
    return strips[rr[keep]], rm[keep], lo[keep], np.maximum.reduceat(hi, keep)


def _lines(direction: Literal["x", "y"], starts: F64, widths: F64, length: float,
           extra: tuple[NDArray[np.intp], NDArray[np.int64], F64, F64], picks: F64) -> ScanLines:
    """All segments of a pass: the strips' edge lines whole, then the extra ones, sorted."""
    n = widths.size
    nominal = np.append(starts, starts[-1] + widths[-1])
    strip, m, lo, hi = extra
    offset = np.concatenate((nominal, starts[strip] + m * picks[strip]))
    start = np.concatenate((np.zeros(n + 1), lo))
    stop = np.concatenate((np.full(n + 1, length), hi))
    order = np.lexsort((start, offset))
    return ScanLines(direction, offset[order], start[order], stop[order])


#: Most grid lines one coarse pick-feed spans (bounds the search over ``k``).
MAX_STRIDE = 64


def _effective_slopes(slopes: F64, kappa: F64, radius: float) -> F64:
    """Slope whose flat-section scallop bounds the scallop on a concave section.

    Ball centres a pick-feed ``p`` apart on a concave section of radius
    ``rho > R`` touch it ``p rho / (rho - R)`` apart, so the cusp is
    ``p^2 / (8R) * f`` with ``f = 1 / (1 - R kappa)``. Scaling ``e^2`` by ``f``
    bounds that (``h(e) = e^2 / (R + sqrt(R^2 - e^2))`` grows faster than
    ``e^2``), and ``1 + s'^2 = (1 + s^2) f`` does it in the slope term.
    ``inf`` where ``R kappa >= 1`` (a nearly fitting ball: no coarse lines).
    """
    rk = radius * kappa
    with np.errstate(divide="ignore", invalid="ignore"):
        f = np.where(rk < 1.0, 1.0 / np.maximum(1.0 - rk, 1e-300), np.inf)
        out: F64 = np.sqrt((1.0 + slopes * slopes) * f - 1.0)
    return out


def _grouped(a: F64, k: int) -> F64:
    """``(ceil(n / k), cells)``: the largest over groups of ``k`` consecutive rows."""
    n = a.shape[0]
    ng = -(-n // k)
    pad = np.full((ng * k - n, a.shape[1]), -np.inf)
    out: F64 = np.concatenate((a, pad)).reshape(ng, k, a.shape[1]).max(axis=1)
    return out


def _coarse(cell_slopes: F64, kappa: F64, widths: F64, k: int, radius: float,
            ok: NDArray[np.bool_]) -> tuple[F64, F64, F64]:
    """The groups of ``k`` strips (:func:`_groups_ok`) as strips: width, the cells'
    effective slopes for the scallop rule and their real steepest cross slopes."""
    n = widths.size
    heads = np.arange(0, n, k)[ok]
    slopes = _grouped(cell_slopes, k)[ok]
    bends = np.maximum(_grouped(kappa[:n], k)[ok], kappa[np.minimum(heads + k, n)])
    gw: F64 = np.asarray(np.add.reduceat(widths, np.arange(0, n, k))[ok], dtype=np.float64)
    return gw, _effective_slopes(slopes, bends, radius), slopes


@njit(cache=True, nogil=True)
def _groups_ok(cell_slopes: F64, kappa: F64, widths: F64, k: int, radius: float,
               budget: float) -> NDArray[np.bool_]:  # pragma: no cover - compiled
    """``(ceil(n / k),)``: whether one pair of lines can cover each group of ``k`` strips.

    A group's cell takes its strips' steepest cross slope ``s`` and the most concave
    kink ``kappa`` on its grid lines (both edges included), together (a bound): the
    scallop :func:`_scallops` of the group's width on :func:`_effective_slopes` of them
    must meet the budget on every cell. One sweep per group with an early exit (the
    search over ``k`` runs this for every ``k``; array temporaries of the whole grid per
    ``k`` took 0.2 s of a 1025² plan).
    """
    n, m = cell_slopes.shape
    ng = (n + k - 1) // k
    r2 = radius * radius
    out = np.zeros(ng, dtype=np.bool_)
    for g in range(ng):
        a, b = g * k, min(g * k + k, n)
        w = 0.0
        for i in range(a, b):
            w += widths[i]
        ok = True
        for c in range(m):
            s = 0.0
            for i in range(a, b):
                s = max(s, cell_slopes[i, c])
            kap = 0.0
            for i in range(a, b + 1):
                kap = max(kap, kappa[i, c])
            rk = radius * kap
            if rk >= 1.0:
                ok = False
                break
            e2 = 0.25 * w * w * ((1.0 + s * s) / max(1.0 - rk, 1e-300))
            if e2 > r2 or e2 / (radius + math.sqrt(max(r2 - e2, 0.0))) > budget:
                ok = False
                break
        out[g] = ok
    return out


def _stride_layout(cell_slopes: F64, kappa: F64, widths: F64, radius: float, budget: float,
                   ) -> tuple[int, F64, F64, F64, F64]:
    """Lines every ``k``-th grid line where the scallop allows, the strips between.

    ``k`` is fixed per pass and chosen to minimise the line count: a group of
    ``k`` strips whose scallop (steepest cross slope and concave kink) meets the
    budget at its whole width becomes one strip; the others keep their ``k``
    grid strips (and extra lines where even one spacing is too wide).

    Returns
    -------
    k, starts, widths, cell_slopes, shown_slopes
        The strips of the layout in order (offset, width, the cells' slopes for
        the scallop rule and their real cross slopes for the report).
    """
    n = widths.size
    # grid lines at i * spacing exactly (a running sum drifts by ulps off the model's
    # node rows, and the simulated stock's rim tests then flip: Mount Rushmore's Ø1
    # stage took 27 passes instead of 17 with the same lines)
    starts: F64 = np.arange(n, dtype=np.float64) * float(widths[0])
    flat = float(_allowed(budget, radius, np.zeros(1))[0])
    kmax = min(int(flat / float(widths[0])) if widths[0] > 0 else 1, MAX_STRIDE, n)
    if kmax < 2 or kappa.shape[0] != n + 1:
        return 1, starts, widths, cell_slopes, cell_slopes
    _, fine, _, _ = _lanes(widths, cell_slopes.max(axis=1), radius, budget)
    slopes_c = np.ascontiguousarray(cell_slopes)
    kappa_c = np.ascontiguousarray(kappa)
    best, best_lines, best_ok = 1, int(fine.sum()), np.zeros(0, dtype=bool)
    for k in range(2, kmax + 1):
        ok = _groups_ok(slopes_c, kappa_c, widths, k, radius, budget)
        lines = int(np.add.reduceat(fine, np.arange(0, n, k))[~ok].sum()) + int(ok.sum())
        if lines < best_lines:
            best, best_lines, best_ok = k, lines, ok
    if best == 1:
        return 1, starts, widths, cell_slopes, cell_slopes
    ok = best_ok
    gw, eff, shown = _coarse(cell_slopes, kappa, widths, best, radius, ok)
    keep = ~ok[np.arange(n) // best]  # grid strips of the groups that stay fine
    heads = np.arange(0, n, best)[ok]
    st = np.concatenate((starts[keep], starts[heads]))
    order = np.argsort(st, kind="stable")
    return (best, st[order], np.concatenate((widths[keep], gw))[order],
            np.concatenate((cell_slopes[keep], eff))[order],
            np.concatenate((cell_slopes[keep], shown))[order])


def _one_direction(direction: Literal["x", "y"], cell_slopes: F64, kappa: F64 | None,
                   spacings: tuple[float, float], extent: tuple[float, float], radius: float,
                   budget: float, what: str) -> StripPlan:
    """Lines along one axis. ``spacings`` and ``extent``: (across, along) the lines, mm."""
    spacing, sa = spacings
    length, along = extent
    n = cell_slopes.shape[0]
    if n == 0 or length <= 0.0:
        one = ScanLines(direction, np.zeros(1), np.zeros(1), np.full(1, along))
        return StripPlan(direction, spacing, spacing, 1, 0.0, 0.0, 0, None, one, along, along, 0)
    widths = np.full(n, spacing)
    widths[-1] = max(length - (n - 1) * spacing, 0.0) or spacing
    kappa = np.zeros((0, 1)) if kappa is None else kappa
    k, starts, widths, cell_slopes, shown = _stride_layout(cell_slopes, kappa, widths, radius,
                                                           budget)
    slopes = cell_slopes.max(axis=1)
    over, counts, picks, h = _lanes(widths, slopes, radius, budget)
    reduced = np.flatnonzero(over)
    steps = _cell_steps(cell_slopes[reduced], picks[reduced], counts[reduced], radius, budget)
    gaps = steps * picks[reduced, None]
    # A strip without extra lines has its largest scallop on its steepest cell
    # (the scallop grows with the slope): ``h`` has it already.
    scallop = max(float(np.max(h[~over], initial=0.0)),
                  float(np.max(_scallops(gaps, cell_slopes[reduced], radius), initial=0.0)))
    gap_max = max(float(np.max(widths[~over], initial=0.0)), float(np.max(gaps, initial=0.0)))
    extra = _extra_lines(reduced, counts[reduced], steps, (sa, along), radius)
    lines = _lines(direction, starts, widths, along, extra, picks)
    n_reduced = int(reduced.size)
    stride = (f"; elsewhere lines run every {k}th grid line ({k * spacing:g} mm) where the "
              "scallop with the cross slope and concave curvature allows" if k > 1 else "")
    if n_reduced:
        worst = int(np.argmax(np.where(over, slopes, -1.0)))
        theta = math.degrees(math.atan(float(slopes[worst])))
        shown_h = ("more than the ball radius" if math.isinf(float(h[worst]))
                   else f"{float(h[worst]):.4g} mm")
        reason = (f"in {n_reduced} of {n} strips the scallop at the level spacing {spacing:g} "
                  f"mm would exceed {what} (steepest slope across the lines {theta:.1f} deg: "
                  f"{shown_h}); those strips get extra lines over the stretches that need "
                  f"them{stride}")
        pick = float(picks[over].min())
    else:
        reason = None
        # every k-th grid line: the smallest distance between lines but the last
        # (which may end at the part's edge)
        pick = spacing if k == 1 else float(widths[:-1].min() if widths.size > 1 else widths[0])
    scan_lines = 1 + int(counts.sum())
    return StripPlan(direction, pick, max(gap_max, pick), scan_lines, scallop,
                     float(shown.max()), n_reduced, reason, lines, lines.length,
                     scan_lines * along, int(extra[0].size))


#: Cells from which :func:`plan_strips` lays the two directions on two threads.
THREAD_CELLS = 1 << 16


def plan_strips(along_x: F64, along_y: F64, sx: float, sy: float, extent_mm: tuple[float, float],
                radius: float, budget: float, what: str,
                bends: tuple[F64, F64] | None = None) -> StripPlan:
    """Scan lines, extra lines where the cells need them, in the direction with the shorter path.

    Parameters
    ----------
    along_x, along_y : float64
        :func:`cell_cross_slopes` of the pass's model (or bounds of them).
    sx, sy : float
        Level spacing.
    extent_mm : (height, width)
        The input's extent in y and x, mm.
    radius : float
    budget : float
        Largest scallop allowed, mm.
    what : str
        What the budget is, for the reason text.
    bends : (along_x, along_y) float64, optional
        :func:`cell_cross_curvatures` of the model (or bounds of them). With
        them lines may run every ``k``-th grid line where the scallop allows;
        without, on every grid line.
    """
    ly, lx = extent_mm
    bx, by = (None, None) if bends is None else bends
    x = partial(_one_direction, "x", along_x, bx, (sy, sx), (ly, lx), radius, budget, what)
    y = partial(_one_direction, "y", along_y, by, (sx, sy), (lx, ly), radius, budget, what)
    # the two directions are independent: on two threads (_threads) when large
    px, py = both(x, y) if along_x.size >= THREAD_CELLS else (x(), y())
    # The shorter path wins; on a tie the lines run along the larger spacing.
    if px.path_length != py.path_length:
        return px if px.path_length < py.path_length else py
    return px if sy <= sx else py
