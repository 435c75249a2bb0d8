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
  densely as the pass's nominal lines (every grid line for a lifted pass and for a rest
  ball's; a whole-part last pass's every ``k``-th, ``k`` up to ``floor(p / spacing)``
  and of the shortest cut, a strip keeping every grid line over its whole length where
  the scallop at ``k`` lines breaks the tolerance anywhere along it: the plan's stride),
  and a line climbs ``sqrt(1 + a²)`` per unit along a slope ``a``: ``sum over region
  nodes of cell area x sqrt(1 + a²) x lines per mm across``; a whole-part pass's nominal
  lines run a radius and a grid step past both stock edges, linked beside the stock;
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
from zwcore.scanline._passes import MAX_STRIDE

__all__ = ["ACROSS_MM", "ENTRY_GAP", "SCALLOP_FLUTE_SHARE", "BallTime", "Feeds", "PassFigures",
           "ball_time", "flat_pick_feed", "pass_figures", "passes_for", "stock_met"]

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
    """Cutting and plunge feed of one ball and the rapid rate, mm/min. The planner ranks
    with the program's defaults for now: a request's cutting data does not reach
    :func:`~zwcore.scanline.planner.plan_scanline` yet (issue 11, open)."""

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
    along_x : bool
        The scan direction of the estimate (lines along x).
    roughing : float
        A main ball's: the roughing stages before it, minutes (not in ``minutes``).
    """

    minutes: float
    passes: int
    cut_length: float
    stretches: float
    area: float
    depth: float
    last: tuple[float, float] = (0.0, 0.0)
    lifted: tuple[float, float] = (0.0, 0.0)
    along_x: bool = True
    roughing: float = 0.0


def passes_for(depth: float, flute: float) -> int:
    """``max(1, ceil(depth / flute))``: the passes of a ball whose flutes meet ``depth``."""
    return max(1, math.ceil(depth / flute - 1e-9))


def flat_pick_feed(radius: float, tolerance: float) -> float:
    """Pick-feed whose scallop on a flat is ``tolerance``: ``2 sqrt(2 R t - t²)`` (at most 2R)."""
    if tolerance >= radius:
        return 2.0 * radius
    return 2.0 * math.sqrt(2.0 * radius * tolerance - tolerance * tolerance)


@njit(cache=True, nogil=True)
def _window_max(x: F64, r: int, out: F64, pre: F64, suf: F64) -> None:
    """``out[u] = max(x[u - r : u + r + 1])`` (clipped at the ends) for ``x >= 0``, in
    ``O(n)``: ``x`` padded by ``r`` zeros each side (``pre`` and ``suf`` hold
    ``n + 2r``), prefix and suffix maxima in blocks of ``w = 2r + 1`` (van Herk /
    Gil-Werman): every padded window ``[u, u + 2r]`` spans at most two blocks."""
    n = x.size
    w = 2 * r + 1
    m = n + 2 * r
    for t in range(m):
        val = x[t - r] if r <= t < n + r else 0.0
        pre[t] = val if t % w == 0 else max(pre[t - 1], val)
    for t in range(m - 1, -1, -1):
        val = x[t - r] if r <= t < n + r else 0.0
        suf[t] = val if (t % w == w - 1 or t == m - 1) else max(suf[t + 1], val)
    for u in range(n):
        out[u] = max(suf[u], pre[u + 2 * r])


@njit(cache=True, nogil=True)
def _directions(z: F64, path: F64, region: B8, strips: B8, whole: bool, along_x: bool,
                du: float, dv: float, picks: F64, nominals: F64, reach: int,
                overrun: float, grids: F64) -> tuple[F64, F64]:
    """Cut length and stretches of passes with lines along ``u`` (``x`` if ``along_x``),
    one per ``(picks[r], nominals[r])``, in one sweep over the strips that hold region
    cells (``strips``).

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
    stock: each runs ``overrun`` mm past both stock edges, and its link to the next is
    its spacing long, both at the feed). Where ``grids[r]`` is finer than the nominal
    spacing, a strip whose cells need more lines than the nominal ones anywhere along it
    takes every ``grids[r]`` line over its whole length (the plan's stride: a group of
    strips is coarse only where its scallop holds over the whole group)."""
    ny, nx = z.shape
    nu, nv = (nx - 1, ny - 1) if along_x else (ny - 1, nx - 1)
    runs = picks.size
    length, stretches = np.zeros(runs), np.zeros(runs)
    m = max(nu, 0)
    steep, climb = np.zeros(m), np.zeros(m)
    inside = np.zeros(m, dtype=np.bool_)
    extra, grown = np.zeros(m), np.zeros(m)
    pre, suf = np.zeros(m + 2 * reach), np.zeros(m + 2 * reach)
    bases, lengths, rises = np.zeros(runs), np.zeros(runs), np.zeros(runs)
    for v in range(nv):
        if not strips[v]:
            continue
        for u in range(nu):
            i, k = (v, u) if along_x else (u, v)
            if along_x:
                b = max(abs(z[i + 1, k] - z[i, k]), abs(z[i + 1, k + 1] - z[i, k + 1])) / dv
                a = max(abs(path[i, k + 1] - path[i, k]),
                        abs(path[i + 1, k + 1] - path[i + 1, k])) / du
            else:
                b = max(abs(z[i, k + 1] - z[i, k]), abs(z[i + 1, k + 1] - z[i + 1, k])) / dv
                a = max(abs(path[i + 1, k] - path[i, k]),
                        abs(path[i + 1, k + 1] - path[i, k + 1])) / du
            steep[u] = math.sqrt(1.0 + b * b) * dv
            climb[u] = math.sqrt(1.0 + a * a)
            inside[u] = whole or (region[i, k] or region[i + 1, k] or region[i, k + 1]
                                  or region[i + 1, k + 1])
        highest = 0.0  # (the most lines a cell of the strip needs, times the pick)
        climbed = 0.0  # (the climb summed over the strip's cells in the region)
        for u in range(nu):
            highest = max(highest, steep[u])
            if inside[u]:
                climbed += climb[u]
        for r in range(runs):
            base = dv / nominals[r]
            if grids[r] < nominals[r] and highest / picks[r] > base * (1.0 + 1e-9):
                # the plan's stride: a strip keeps every grid line over its whole length
                # where its scallop at the stride's width breaks the budget anywhere
                base = dv / grids[r]
            got_length = got_stretches = 0.0
            same = -1  # an earlier run with the same lines in this strip
            if r > 0 and picks[r] == picks[r - 1] and base == bases[r - 1]:
                same = r - 1
            elif r > 0 and picks[r] == picks[0] and base == bases[0]:
                same = 0
            if same >= 0:
                got_length, got_stretches = lengths[same], rises[same]
            elif whole and highest / picks[r] <= base:
                got_length = du * base * climbed  # nominal lines alone: no extra, no entry
            else:
                for u in range(nu):
                    extra[u] = max(steep[u] / picks[r] - base, 0.0)
                _window_max(extra, reach, grown, pre, suf)
                prev = 0.0
                for u in range(nu):
                    now = 0.0
                    if inside[u]:
                        got_length += du * (base * climb[u] + grown[u])
                        now = grown[u] if whole else grown[u] + base
                    if now > prev:
                        got_stretches += now - prev
                    prev = now
            bases[r], lengths[r], rises[r] = base, got_length, got_stretches
            if whole:  # the strip's share of the whole lines' overruns and links
                length[r] += base * 2.0 * overrun + dv
            length[r] += got_length
            stretches[r] += got_stretches
    for r in range(runs):
        length[r] += stretches[r] * 2.0 * reach * du
    return length, stretches


@njit(cache=True, nogil=True)
def _met_kernel(z: F64, theirs: F64, mine: F64, region: B8, whole: bool, wy: int,
                wx: int) -> float:
    """Most of ``max over the (2wy+1) x (2wx+1) nodes about c of (z + theirs) - (z +
    mine)(c)`` over the region's nodes ``c`` (all: ``whole``), at least 0: row maxima by
    :func:`_window_max` on the rows within ``wy`` of a region row, then each region node's
    column of them."""
    ny, nx = z.shape
    has = np.zeros(ny, dtype=np.bool_)
    for i in range(ny):
        if whole:
            has[i] = True
            continue
        for k in range(nx):
            if region[i, k]:
                has[i] = True
                break
    rowmax = np.zeros((ny, nx))
    row, out = np.zeros(nx), np.zeros(nx)
    pre, suf = np.zeros(nx + 2 * wx), np.zeros(nx + 2 * wx)
    low = np.inf
    for i in range(ny):
        for k in range(nx):
            low = min(low, z[i, k] + theirs[i, k])
    for i in range(ny):
        near = False
        for a in range(max(0, i - wy), min(ny, i + wy + 1)):
            near = near or has[a]
        if not near:
            continue
        for k in range(nx):  # shifted to >= 0 for the window maxima
            row[k] = z[i, k] + theirs[i, k] - low
        _window_max(row, wx, out, pre, suf)
        rowmax[i] = out
    best = 0.0
    if whole:  # every node: the column maxima in O(n) too
        col, top = np.zeros(ny), np.zeros(ny)
        cpre, csuf = np.zeros(ny + 2 * wy), np.zeros(ny + 2 * wy)
        for k in range(nx):
            for i in range(ny):
                col[i] = rowmax[i, k]
            _window_max(col, wy, top, cpre, csuf)
            for i in range(ny):
                best = max(best, top[i] + low - z[i, k] - mine[i, k])
        return best
    for i in range(ny):
        if not has[i]:
            continue
        for k in range(nx):
            if not region[i, k]:
                continue
            t = 0.0
            for a in range(max(0, i - wy), min(ny, i + wy + 1)):
                t = max(t, rowmax[a, k])
            best = max(best, t + low - z[i, k] - mine[i, k])
    return best


def stock_met(z: F64, theirs: F64, mine: F64, region: B8 | None, wy: int, wx: int) -> float:
    """Most stock a ball meets above its tip in ``region`` (None: everywhere), as the
    flute rule takes it: the highest stock (the part ``z`` plus ``theirs``, what the
    ball before leaves) in the square of ``2 wy + 1`` by ``2 wx + 1`` nodes about the tip
    (it holds the ball's cylinder), less the tip (the part plus ``mine``, what this ball
    leaves: its closing, at most its CL there); at least 0.

    Parameters
    ----------
    z, theirs, mine : (ny, nx) float64
    region : (ny, nx) bool or None
    wy, wx : int
        The ball's radius in nodes across and along the rows (rounded down).
    """
    whole = region is None
    mask = np.zeros((1, 1), dtype=bool) if region is None else np.ascontiguousarray(region)
    return float(_met_kernel(np.require(z, np.float64, ["C"]),
                             np.require(theirs, np.float64, ["C"]),
                             np.require(mine, np.float64, ["C"]), mask, whole, wy, wx))


def _strips(region: B8, along_x: bool) -> B8:
    """Strips of cells (between two node rows across the lines) with a region node."""
    rows: B8 = np.asarray(region.any(axis=1) if along_x else region.any(axis=0))
    out: B8 = rows[:-1] | rows[1:]
    return out


def _direction(z: F64, path: F64, region: B8, whole: bool, along_x: bool, du: float,
               dv: float, pick: float, nominal: float, reach: int, overrun: float = 0.0,
               grid: float | None = None) -> tuple[float, float]:
    """:func:`_directions` for one pass."""
    got = _directions(z, path, region, _strips(region, along_x), whole, along_x, du, dv,
                      np.array([pick]), np.array([nominal]), reach, overrun,
                      np.array([nominal if grid is None else grid]))
    return float(got[0][0]), float(got[1][0])


def ball_time(z: F64, closing: F64, dx: float, dy: float, spacing: tuple[float, float],
              tool: Tool, region: B8 | None, depth: float, tolerance: float, feeds: Feeds,
              entry: float = 0.0, along_x: bool | None = None) -> BallTime:
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
        Where the ball works; None: the whole part (its nominal lines run whole, each a
        radius and a grid step past both stock edges, as the tool paths run them).
    depth : float
        Most material the ball meets in its region, mm.
    tolerance : float
    feeds : Feeds
    entry : float
        Depth of stock an entry plunges through below :data:`ENTRY_GAP`, mm (a rest
        region's: the material the ball before left around it and the ball's radius;
        a whole-part pass enters its extra lines just above its own whole lines: 0).
    along_x : bool, optional
        The scan direction; default: the one with the shorter time.

    Returns
    -------
    BallTime
    """
    n = passes_for(depth, tool.flute_length)
    return pass_figures(z, closing, dx, dy, spacing, tool, region, tolerance, n > 1,
                        along_x).time(n, depth, feeds, entry)


@dataclass(frozen=True)
class PassFigures:
    """A ball's pass figures over its region, per scan direction: the last pass's and a
    lifted pass's ``(cut length, stretches)`` (the lifted: ``(0, 0)`` when not asked
    for); :meth:`time` the estimate for a number of passes (the same as
    :func:`ball_time`'s)."""

    directions: tuple[tuple[bool, tuple[float, float], tuple[float, float]], ...]
    area: float

    def time(self, n: int, depth: float, feeds: Feeds, entry: float = 0.0) -> BallTime:
        """The :class:`BallTime` of ``n`` passes (the direction with the shorter time; the
        first of equal ones)."""
        best: BallTime | None = None
        plunge = ENTRY_GAP + entry
        for along, last, lifted in self.directions:
            length = stretches = minutes = 0.0
            for count, (cut, entered) in ((1, last), (n - 1, lifted)) if n > 1 else ((1, last),):
                minutes += count * machining_minutes(
                    cut, entered * plunge, entered * (2.0 * plunge + ACROSS_MM),
                    feed=feeds.feed, plunge_feed=feeds.plunge_feed, rapid_feed=feeds.rapid_feed)
                length += count * cut
                stretches += count * entered
            if best is None or minutes < best.minutes:
                best = BallTime(minutes, n, length, stretches, self.area, depth, last,
                                lifted if n > 1 else (0.0, 0.0), along)
        assert best is not None
        return best


def pass_figures(z: F64, closing: F64, dx: float, dy: float, spacing: tuple[float, float],
                 tool: Tool, region: B8 | None, tolerance: float, lifted_too: bool,
                 along_x: bool | None = None) -> PassFigures:
    """:func:`ball_time`'s pass figures (one sweep per direction), a lifted pass's too if
    ``lifted_too``."""
    whole = region is None
    mask = np.ones(z.shape, dtype=bool) if region is None else np.ascontiguousarray(region)
    zc = np.require(z, dtype=np.float64, requirements=["C"])
    path = np.require(closing, dtype=np.float64, requirements=["C"])
    final = flat_pick_feed(tool.radius, tolerance)
    lifted = flat_pick_feed(tool.radius, SCALLOP_FLUTE_SHARE * tool.flute_length)
    area = float(mask.sum()) * dx * dy
    # a whole line runs a radius and a grid step past each stock edge (the tool paths')
    overrun = tool.radius + max(spacing) if whole else 0.0
    out = []
    for along in ((True, False) if along_x is None else (along_x,)):
        du, dv = (dx, dy) if along else (dy, dx)
        grid = spacing[1] if along else spacing[0]  # the input's spacing across the lines
        reach = math.ceil(tool.radius / du)
        # The last pass's lines: a rest ball's on every grid line (the plan's); a
        # whole-part pass's on every k-th, k of the fewest lines (the plan's stride, at
        # most the flat pick-feed's), a strip keeping every grid line where the scallop
        # at k breaks the tolerance anywhere along it (the kernel)
        strides = range(1, min(max(1, math.floor(final / grid)), MAX_STRIDE) + 1) if whole else [1]
        runs = [(final, grid * k) for k in strides]
        if lifted_too:
            runs.append((lifted, grid))
        cuts, ins = _directions(zc, path, mask, _strips(mask, along), whole, along, du,
                                dv, np.array([r[0] for r in runs]),
                                np.array([r[1] for r in runs]), reach, overrun,
                                np.full(len(runs), grid))
        last = min(range(len(strides)), key=lambda r: (float(cuts[r]), r))
        lift = ((float(cuts[-1]), float(ins[-1])) if lifted_too else (0.0, 0.0))
        out.append((along, (float(cuts[last]), float(ins[last])), lift))
    return PassFigures(tuple(out), area)
