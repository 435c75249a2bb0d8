"""Estimated machining time of a finishing ball over its region (the chain's ranking).

A CAM engineer ranks finishing chains by what the program will cost on the machine, not
by cut length: a small ball with short flutes over deep rest goes down in several
passes, and a rest region in many small pieces is entered and left many times. Per ball
and region (on the ball's lattice, :mod:`zwcore.scanline._regions`):

- **passes** ``n = max(1, ceil(depth / flute))``, ``depth`` the most material the ball
  meets in its region: what the ball before leaves less what this one leaves, at the
  nodes (the flute rule of :mod:`zwcore.scanline._stage_passes` lifts every pass but
  the last where more than the flute length stands above the tip, and every pass runs
  over the whole region). The last pass holds the finishing tolerance; the ``n - 1``
  before it only half the flute length (:data:`SCALLOP_FLUTE_SHARE`), so their lines
  are as far apart as the ball and the grid allow;
- **cut length** of a pass, lines along ``x`` (and the same along ``y``; the scan
  direction with the shorter time counts): the plan's strips (:mod:`._passes`) space
  lines ``p / sqrt(1 + b²)`` apart across a slope ``b`` (the scallop rule), at least as
  densely as the pass's nominal lines (every grid line for a lifted pass, every
  ``floor(p / spacing)``-th for the last), and a line climbs ``sqrt(1 + a²)`` per unit
  along a slope ``a``: ``sum over region nodes of cell area x sqrt(1 + a²) x lines per
  mm across``;
- **stretches** entered and left: the lines' count per lattice row (lines per mm across
  times the row spacing) grown by the radius along the row (an extra line runs one
  radius past the cells that need it, and stretches that overlap merge), and every rise
  of that count along the row starts a stretch; a rest region's count is 0 outside it,
  a whole-part pass counts only the lines beyond its nominal ones (those run the whole
  length, linked in air beside the stock);
- **time** of a pass (:func:`zwcore.grid.feeds.machining_minutes`, the program's own
  formula): the cut length at the feed, per stretch a plunge from :data:`ENTRY_GAP`
  above the stock at the plunge feed (in a rest region also through the ball's radius
  and the mean material the ball before left there: the tool paths enter above the
  stock around the start), and the rapid up, across (:data:`ACROSS_MM`) and down.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import NDArray

from zwcore.grid.feeds import (
    DEFAULT_FEED,
    DEFAULT_PLUNGE_FEED,
    DEFAULT_RAPID_FEED,
    machining_minutes,
)
from zwcore.grid.tools import Tool

__all__ = ["ACROSS_MM", "ENTRY_GAP", "SCALLOP_FLUTE_SHARE", "BallTime", "Feeds", "ball_time",
           "passes_for"]

F64 = NDArray[np.float64]
B8 = NDArray[np.bool_]

#: Height above the stock where an entry's rapid ends and its plunge begins, mm (the tool
#: paths' ``zwcore.toolpath.scanline_paths.ENTRY_GAP``; a test pins the two together).
ENTRY_GAP = 0.5

#: Rapid distance across from one stretch to the next, mm (the mean of the Mount Rushmore
#: rest passes' rapids per stretch, less their rise and fall, was about 7 mm).
ACROSS_MM = 7.0

#: A lifted pass's scallops may take this share of its flute length (the plan's
#: ``zwcore.scanline._stage_passes.SCALLOP_FLUTE_SHARE``; a test pins the two together).
SCALLOP_FLUTE_SHARE = 0.5


@dataclass(frozen=True)
class Feeds:
    """Cutting and plunge feed of one ball and the rapid rate, mm/min (the program's
    defaults unless the request gives cutting data)."""

    feed: float = DEFAULT_FEED
    plunge_feed: float = DEFAULT_PLUNGE_FEED
    rapid_feed: float = DEFAULT_RAPID_FEED


@dataclass(frozen=True)
class BallTime:
    """One ball's estimated work over its region.

    Attributes
    ----------
    minutes : float
        All its passes.
    passes : int
    cut_length : float
        Of all passes, mm.
    stretches : float
        Entered and left, all passes.
    area : float
        Region area, mm².
    depth : float
        Most material the ball meets in its region, mm.
    last : (float, float)
        Cut length (mm) and stretches of the last pass (the finishing pick-feed).
    lifted : (float, float)
        The same of each lifted pass before it (0 when there is none).
    """

    minutes: float
    passes: int
    cut_length: float
    stretches: float
    area: float
    depth: float
    last: tuple[float, float] = (0.0, 0.0)
    lifted: tuple[float, float] = (0.0, 0.0)


def passes_for(depth: float, flute: float) -> int:
    """``max(1, ceil(depth / flute))``: the passes of a ball whose flutes meet ``depth``."""
    return max(1, math.ceil(depth / flute - 1e-9))


def _pick(radius: float, scallop: float) -> float:
    """Pick-feed whose scallop on a flat is ``scallop`` (at most the diameter)."""
    if scallop >= radius:
        return 2.0 * radius
    return 2.0 * math.sqrt(2.0 * radius * scallop - scallop * scallop)


@njit(cache=True, nogil=True)
def _direction(z: F64, path: F64, region: B8, whole: bool, along_x: bool, du: float,
               dv: float, pick: float, nominal: float, reach: int) -> tuple[float, float]:
    """Cut length and stretches of one pass with lines along ``u`` (``x`` if ``along_x``).

    The plan's lines over the whole part, strip of cells by strip (:mod:`._passes`):
    ``dv / nominal`` nominal lines per strip, and where the part is steep across the
    lines (``b``, the larger of the cell's two edge differences of ``z`` across them
    over ``dv``) ``dv sqrt(1 + b²) / pick`` lines in all; the extra ones run a radius
    (``reach`` cells) past the cells that need them. A region's pass runs those lines
    where they cross its cells (a cell is the region's when one of its corners is, as
    the tool paths take a region). Per cell: the nominal lines climb the tip's path
    (``sqrt(1 + a²)`` per mm, ``a`` the larger edge difference of ``path`` along the
    lines over ``du``), the extra ones, laid where the part is steep across the lines,
    run along its contours (``du`` each), and each stretch a radius on at either end.
    Every rise of the lines' count along a strip starts a stretch (a whole-part pass:
    of the extra lines only; its nominal lines run whole, linked in air beside the
    stock)."""
    ny, nx = z.shape
    nu, nv = (nx - 1, ny - 1) if along_x else (ny - 1, nx - 1)
    length, stretches = 0.0, 0.0
    extra = np.zeros(max(nu, 0))
    base = dv / nominal
    for v in range(nv):
        any_in = whole
        for u in range(nu):
            if any_in:
                break
            i, k = (v, u) if along_x else (u, v)
            any_in = (region[i, k] or region[i + 1, k] or region[i, k + 1]
                      or region[i + 1, k + 1])
        if not any_in:
            continue
        for u in range(nu):
            i, k = (v, u) if along_x else (u, v)
            if along_x:
                b = max(abs(z[i + 1, k] - z[i, k]), abs(z[i + 1, k + 1] - z[i, k + 1])) / dv
            else:
                b = max(abs(z[i, k + 1] - z[i, k]), abs(z[i + 1, k + 1] - z[i + 1, k])) / dv
            extra[u] = max(math.sqrt(1.0 + b * b) * dv / pick - base, 0.0)
        prev = 0.0
        for u in range(nu):
            i, k = (v, u) if along_x else (u, v)
            now = 0.0
            if whole or (region[i, k] or region[i + 1, k] or region[i, k + 1]
                         or region[i + 1, k + 1]):
                grown = 0.0
                for w in range(max(0, u - reach), min(nu, u + reach + 1)):
                    grown = max(grown, extra[w])
                if along_x:
                    a = max(abs(path[i, k + 1] - path[i, k]),
                            abs(path[i + 1, k + 1] - path[i + 1, k])) / du
                else:
                    a = max(abs(path[i + 1, k] - path[i, k]),
                            abs(path[i + 1, k + 1] - path[i, k + 1])) / du
                length += du * (base * math.sqrt(1.0 + a * a) + grown)
                now = grown if whole else grown + base
            if now > prev:
                stretches += now - prev
            prev = now
    # an extra line runs a radius past the cells that need it at each end (a region's
    # stretches too: the region holds the positions within the radius of where it cuts)
    return length + stretches * 2.0 * reach * du, stretches


def ball_time(z: F64, closing: F64, dx: float, dy: float, spacing: tuple[float, float],
              tool: Tool, region: B8 | None, depth: float, tolerance: float, feeds: Feeds,
              entry: float = 0.0) -> BallTime:
    """Estimated time of ``tool`` over ``region`` of the lattice ``z``.

    Parameters
    ----------
    z : (ny, nx) float64
        The part on the ball's lattice (its slopes across the lines set their spacing).
    closing : (ny, nx) float64
        The ball's closing there (the part plus what the ball leaves): the tip's path
        climbs its slopes along the lines.
    dx, dy : float
        The lattice's spacing, mm.
    spacing : (float, float)
        The input grid's spacing ``(dx, dy)`` (the plan's nominal lines run on its grid
        lines).
    tool : Tool
    region : (ny, nx) bool or None
        Where the ball works; None: the whole part (its nominal lines run whole).
    depth : float
        Most material the ball meets in its region, mm.
    tolerance : float
    feeds : Feeds
    entry : float
        Depth of stock an entry plunges through below :data:`ENTRY_GAP`, mm (a rest
        region's: the material the ball before left around it and the ball's radius;
        a whole-part pass enters its extra lines just above its own whole lines: 0).

    Returns
    -------
    BallTime
    """
    whole = region is None
    mask = np.ones(z.shape, dtype=bool) if region is None else np.ascontiguousarray(region)
    zc = np.require(z, dtype=np.float64, requirements=["C"])
    path = np.require(closing, dtype=np.float64, requirements=["C"])
    n = passes_for(depth, tool.flute_length)
    final = _pick(tool.radius, tolerance)
    lifted = _pick(tool.radius, SCALLOP_FLUTE_SHARE * tool.flute_length)
    area = float(mask.sum()) * dx * dy
    best: BallTime | None = None
    for along_x in (True, False):
        du, dv = (dx, dy) if along_x else (dy, dx)
        grid = spacing[1] if along_x else spacing[0]  # the input's spacing across the lines
        reach = math.ceil(tool.radius / du)
        runs = [(final, grid * max(1, math.floor(final / grid)), 1)]
        if n > 1:
            runs.append((lifted, grid, n - 1))
        length = stretches = minutes = 0.0
        each = []
        for pick, nominal, count in runs:
            cut, entered = _direction(zc, path, mask, whole, along_x, du, dv, pick, nominal,
                                      reach)
            each.append((cut, entered))
            plunge = ENTRY_GAP + entry
            minutes += count * machining_minutes(
                cut, entered * plunge, entered * (2.0 * plunge + ACROSS_MM), feed=feeds.feed,
                plunge_feed=feeds.plunge_feed, rapid_feed=feeds.rapid_feed)
            length += count * cut
            stretches += count * entered
        if best is None or minutes < best.minutes:
            best = BallTime(minutes, n, length, stretches, area, depth, each[0],
                            each[1] if n > 1 else (0.0, 0.0))
    assert best is not None
    return best
