"""Scallops and pick-feeds of scan-line passes, strip by strip.

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

Pick-feeds are chosen strip by strip: a strip is the band between two
adjacent grid lines of the level (the nominal scan lines). On a bilinear
cell the slope across the lines is linear along them, so its largest
magnitude over the strip is the largest grid-edge difference across it
(exact). A strip whose scallop at the level spacing would exceed the budget
gets extra lines, evenly spaced, just enough to meet it; the rest of the
part keeps the level spacing, so one wall no longer makes every pass crawl.
The scan direction is the one with the shorter total path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

__all__ = ["StripPlan", "cross_slopes", "pick_feed_for", "plan_strips", "scallop_height"]

F64 = NDArray[np.float64]

#: Nodes per block of rows in :func:`cross_slopes`.
_BLOCK_NODES = 1 << 15


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


def pick_feed_for(scallop: float, slope: float, radius: float) -> float:
    """Largest pick-feed whose scallop on ``slope`` is at most ``scallop``."""
    b = min(scallop, radius)
    if b <= 0.0:
        b = 1e-12 * radius
    e = math.sqrt(b * (2.0 * radius - b))
    # A hair under the exact value so the recomputed scallop is <= the target
    # despite rounding.
    return 2.0 * e / math.sqrt(1.0 + slope * slope) * (1.0 - 1e-9)


def cross_slopes(model: F64, sx: float, sy: float,
                 cells: tuple[int, int]) -> tuple[F64, F64]:
    """Largest slope across the lines in every strip, for both scan directions.

    Parameters
    ----------
    model : (my, mx) float64
        Node values of the bilinear model.
    sx, sy : float
    cells : (cy, cx)
        Cells touching the input's extent.

    Returns
    -------
    along_x : (cy,) float64
        Lines along x: ``max |dz/dy|`` in each row strip (nodes ``0..cx``).
    along_y : (cx,) float64
        Lines along y: ``max |dz/dx|`` in each column strip (nodes ``0..cy``).
    """
    cy, cx = cells
    sub = model[: cy + 1, : cx + 1]
    ny, nx = sub.shape
    do_x = cy > 0 and ny > 1
    do_y = cx > 0 and nx > 1
    # In blocks of rows (one row of overlap for the differences across
    # them), so a full-resolution model makes no full-size temporaries; the
    # maxima are those of the whole-array expressions, bit for bit.
    rows = max(2, _BLOCK_NODES // max(nx, 1))
    parts_x: list[F64] = []
    max_y: F64 | None = None
    for a in range(0, max(ny - 1, 1), rows):
        blk = sub[a:min(a + rows, ny - 1) + 1]
        if do_x:
            parts_x.append(np.abs(np.diff(blk, axis=0)).max(axis=1))
        if do_y:
            m = np.abs(np.diff(blk, axis=1)).max(axis=0)
            max_y = m if max_y is None else np.maximum(max_y, m)
    along_x = np.concatenate(parts_x) * (1.0 / sy) if do_x else np.zeros(cy)
    along_y = max_y * (1.0 / sx) if do_y and max_y is not None else np.zeros(cx)
    return along_x, along_y


@dataclass(frozen=True)
class StripPlan:
    """Scan lines of one pass."""

    direction: Literal["x", "y"]
    pick_feed: float
    pick_feed_max: float
    scan_lines: int
    scallop: float
    cross_slope: float
    reduced_strips: int
    reason: str | None


def _one_direction(direction: Literal["x", "y"], slopes: F64, spacing: float, length: float,
                   radius: float, budget: float, what: str) -> StripPlan:
    n = slopes.size
    if n == 0 or length <= 0.0:
        return StripPlan(direction, spacing, spacing, 1, 0.0, 0.0, 0, None)
    widths = np.full(n, spacing)
    widths[-1] = max(length - (n - 1) * spacing, 0.0) or spacing
    e2 = 0.25 * widths * widths * (1.0 + slopes * slopes)
    r = radius
    with np.errstate(invalid="ignore"):
        h = np.where(e2 <= r * r, e2 / (r + np.sqrt(np.maximum(r * r - e2, 0.0))), np.inf)
    over = h > budget
    counts = np.ones(n, dtype=np.int64)
    picks = widths.copy()
    scallops = h
    if over.any():
        b = min(budget, radius)
        if b <= 0.0:  # nothing left for scallops: as fine as rounding allows
            b = 1e-12 * radius
        e = math.sqrt(b * (2.0 * radius - b))
        allowed = 2.0 * e / np.sqrt(1.0 + slopes[over] ** 2) * (1.0 - 1e-9)
        k = np.ceil(widths[over] / allowed - 1e-12).astype(np.int64)
        k = np.maximum(k, 1)
        # The even split is at most ``allowed``; re-check against rounding.
        p = widths[over] / k
        bad = p > allowed
        k[bad] += 1
        p = widths[over] / k
        counts[over] = k
        picks[over] = p
        scallops = h.copy()
        scallops[over] = [scallop_height(float(pp), float(ss), radius)
                          for pp, ss in zip(p, slopes[over], strict=True)]
    steep = float(slopes.max())
    reduced = int(np.count_nonzero(over))
    if reduced:
        worst = int(np.argmax(np.where(over, slopes, -1.0)))
        theta = math.degrees(math.atan(float(slopes[worst])))
        shown = ("more than the ball radius" if math.isinf(float(h[worst]))
                 else f"{float(h[worst]):.4g} mm")
        reason = (f"in {reduced} of {n} strips the scallop at the level spacing {spacing:g} mm "
                  f"would exceed {what} (steepest slope across the lines {theta:.1f} deg: "
                  f"{shown}); those strips get extra lines")
        pick = float(picks[over].min())
    else:
        reason = None
        pick = spacing
    return StripPlan(direction, pick, max(float(picks.max()), pick), 1 + int(counts.sum()),
                     float(np.max(scallops)), steep, reduced, reason)


def plan_strips(along_x: F64, along_y: F64, sx: float, sy: float, extent_mm: tuple[float, float],
                radius: float, budget: float, what: str) -> StripPlan:
    """Scan lines strip by strip in the direction that needs fewer of them.

    Parameters
    ----------
    along_x, along_y : float64
        :func:`cross_slopes` of the pass's model (or bounds of them).
    sx, sy : float
        Level spacing.
    extent_mm : (height, width)
        The input's extent in y and x, mm.
    radius : float
    budget : float
        Largest scallop allowed, mm.
    what : str
        What the budget is, for the reason text.
    """
    ly, lx = extent_mm
    px = _one_direction("x", along_x, sy, ly, radius, budget, what)
    py = _one_direction("y", along_y, sx, lx, radius, budget, what)
    # The shorter total path wins; on a tie the lines run along the larger
    # spacing.
    tx = px.scan_lines * max(lx, 1e-300)
    ty = py.scan_lines * max(ly, 1e-300)
    if tx != ty:
        return px if tx < ty else py
    return px if sy <= sx else py
