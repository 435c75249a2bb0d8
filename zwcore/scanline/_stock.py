"""The simulated stock of a scan-line plan: every pass's real tool positions, cut in turn.

A pass's positions are points on its scan lines (:class:`~zwcore.scanline.results.ScanLines`:
the level's grid lines whole, the extra segments where the plan has them), every
``stride`` input nodes along a line plus the segment ends, and only over the pass's
``region`` (level nodes; ``None``: everywhere). At each position ``c``:

- ``CL(c) = max(CL_model(c), CL_part(c))``: ``CL_model`` is the drop-cutter
  (:func:`zwcore.sim.drop_cutter`, bilinear) on the pass's model at the model's own
  nodes, bilinear between them (what the tool path follows); ``CL_part`` the exact
  drop-cutter against the part's input nodes, ``max over nodes q within R of
  z(q) - h(|q - c|)`` (no position cuts below a node of the part);
- the flute rule reads the stock before the pass: ``top(c)``, the highest stock node
  within ``R`` of the axis, and ``depth(c) = top(c) - CL(c)`` must stay at most the flute
  length ``L``; the planner lifts the pass where it would not (:func:`flute_lift`);
- the stock after the pass is ``min(stock, CL(c) + h(|p - c|))`` at every input node
  ``p`` within ``R`` of a position: exact at the nodes for the positions.

Positions at discrete points leave more stock than the continuous motion of the tool
between them (a cusp of about ``ds² / (8R)`` on a flat, more on a slope climbed along the
line): the simulated stock is never below what the tool path leaves at the same CL,
which is the safe side for the next pass's flute rule and for the material-left
figures. ``ds`` is the input spacing along the line for the finishing ball; a coarse
pass, whose ball spans thousands of input nodes, keeps ``ds`` where that cusp stays under
a quarter of its own scallop (or of the tolerance, the larger).

Cost: three numba kernels visit, per position, the input nodes within ``R`` block by
block (8 x 8 nodes) and skip a block when its maximum cannot change the answer (branch
and bound for the drop-cutter and the top, a block whose stock lies under the ball
everywhere for the envelope): near linear in the positions times the nodes a ball
really touches.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import NDArray

from zwcore.grid.tools import Tool
from zwcore.grid.zmap import ZMap
from zwcore.scanline.results import ScanLines
from zwcore.sim import drop_cutter

__all__ = ["BLOCK", "Positions", "StockSim", "block_max", "cl_on_model", "positions",
           "stride_for"]

F64 = NDArray[np.float64]

#: Input nodes per side of the blocks the kernels skip whole.
BLOCK = 8

#: The cusp discrete positions may leave along a line, as a share of the pass's scallop
#: (or of the tolerance, the larger).
CUSP_SHARE = 0.25


def block_max(z: F64, b: int = BLOCK) -> F64:
    """``(ceil(ny/b), ceil(nx/b))``: the largest value of every ``b x b`` block of nodes."""
    ny, nx = z.shape
    my, mx = -(-ny // b), -(-nx // b)
    pad = np.full((my * b, mx * b), -np.inf)
    pad[:ny, :nx] = z
    out: F64 = pad.reshape(my, b, mx, b).max(axis=(1, 3))
    return out


@njit(cache=True, nogil=True)
def _span(p: float, r: float, d: float, n: int) -> tuple[int, int]:
    """Node indices ``lo..hi`` (inclusive) within ``r`` of ``p`` along an axis."""
    lo = max(0, int(math.ceil((p - r) / d - 1e-9)))
    hi = min(n - 1, int(math.floor((p + r) / d + 1e-9)))
    return lo, hi


@njit(cache=True, nogil=True)
def _block_dist2(p: float, q: float, bi: int, bk: int, b: int, ny: int, nx: int,
                 dx: float, dy: float) -> float:
    """Squared xy distance from ``(p, q)`` (x, y in mm) to block ``(bi, bk)``'s nodes' box."""
    x0, x1 = bk * b * dx, (min(bk * b + b, nx) - 1) * dx
    y0, y1 = bi * b * dy, (min(bi * b + b, ny) - 1) * dy
    ex = max(0.0, x0 - p, p - x1)
    ey = max(0.0, y0 - q, q - y1)
    return ex * ex + ey * ey


@njit(cache=True, nogil=True)
def _cl_part(z: F64, zmax: F64, b: int, px: F64, py: F64, cl0: F64, r: float, dx: float,
             dy: float) -> F64:
    """``max(cl0, max over nodes q within r of z[q] - h(|q - c|))`` per position (ball)."""
    ny, nx = z.shape
    r2 = r * r
    out = cl0.copy()
    for n in range(px.size):
        p, q = px[n], py[n]
        best = out[n]
        k0, k1 = _span(p, r, dx, nx)
        i0, i1 = _span(q, r, dy, ny)
        if k0 > k1 or i0 > i1:
            continue
        for bi in range(i0 // b, i1 // b + 1):
            for bk in range(k0 // b, k1 // b + 1):
                dm2 = _block_dist2(p, q, bi, bk, b, ny, nx, dx, dy)
                if dm2 > r2 or zmax[bi, bk] - (r - math.sqrt(r2 - dm2)) <= best:
                    continue
                for i in range(max(i0, bi * b), min(i1, bi * b + b - 1) + 1):
                    ey = i * dy - q
                    for k in range(max(k0, bk * b), min(k1, bk * b + b - 1) + 1):
                        ex = k * dx - p
                        d2 = ex * ex + ey * ey
                        if d2 <= r2:
                            v = z[i, k] - (r - math.sqrt(r2 - d2))
                            if v > best:
                                best = v
        out[n] = best
    return out


@njit(cache=True, nogil=True)
def _top(s: F64, smax: F64, b: int, px: F64, py: F64, r: float, dx: float,
         dy: float) -> F64:
    """Highest stock node within ``r`` of each position (-inf: none)."""
    ny, nx = s.shape
    r2 = r * r
    out = np.full(px.size, -np.inf)
    for n in range(px.size):
        p, q = px[n], py[n]
        best = -np.inf
        k0, k1 = _span(p, r, dx, nx)
        i0, i1 = _span(q, r, dy, ny)
        if k0 > k1 or i0 > i1:
            continue
        for bi in range(i0 // b, i1 // b + 1):
            for bk in range(k0 // b, k1 // b + 1):
                if smax[bi, bk] <= best or _block_dist2(p, q, bi, bk, b, ny, nx, dx,
                                                        dy) > r2:
                    continue
                for i in range(max(i0, bi * b), min(i1, bi * b + b - 1) + 1):
                    ey = i * dy - q
                    for k in range(max(k0, bk * b), min(k1, bk * b + b - 1) + 1):
                        ex = k * dx - p
                        if ex * ex + ey * ey <= r2 and s[i, k] > best:
                            best = s[i, k]
        out[n] = best
    return out


@njit(cache=True, nogil=True)
def _cut(s: F64, smax: F64, b: int, px: F64, py: F64, cl: F64, r: float, dx: float,
         dy: float) -> None:
    """``s = min(s, cl + h(|p - c|))`` at every node within ``r`` of each position, in place.

    ``smax`` is the block maximum of ``s`` before the pass: a block whose stock lies at or
    under the ball's lowest point over it is left alone.
    """
    ny, nx = s.shape
    r2 = r * r
    for n in range(px.size):
        p, q, c = px[n], py[n], cl[n]
        k0, k1 = _span(p, r, dx, nx)
        i0, i1 = _span(q, r, dy, ny)
        if k0 > k1 or i0 > i1:
            continue
        for bi in range(i0 // b, i1 // b + 1):
            for bk in range(k0 // b, k1 // b + 1):
                dm2 = _block_dist2(p, q, bi, bk, b, ny, nx, dx, dy)
                if dm2 > r2 or smax[bi, bk] <= c + (r - math.sqrt(r2 - dm2)):
                    continue
                for i in range(max(i0, bi * b), min(i1, bi * b + b - 1) + 1):
                    ey = i * dy - q
                    for k in range(max(k0, bk * b), min(k1, bk * b + b - 1) + 1):
                        ex = k * dx - p
                        d2 = ex * ex + ey * ey
                        if d2 <= r2:
                            v = c + (r - math.sqrt(r2 - d2))
                            if v < s[i, k]:
                                s[i, k] = v


@dataclass(frozen=True, eq=False)
class Positions:
    """Tool positions of one pass: ``x, y`` in mm from the grid's first node, ``(n,)``."""

    x: F64
    y: F64

    @property
    def size(self) -> int:
        return int(self.x.size)


def stride_for(tool: Tool, scallop: float, tolerance: float, spacing: float) -> int:
    """Input nodes between positions along a line: the cusp ``ds² / (8R)`` of discrete
    positions on a flat stays under :data:`CUSP_SHARE` of ``max(scallop, tolerance)``."""
    allowance = CUSP_SHARE * max(scallop, tolerance)
    ds = math.sqrt(8.0 * tool.radius * allowance)
    return max(1, int(ds / spacing))


def positions(lines: ScanLines, part: ZMap, stride: int,
              region: NDArray[np.bool_] | None = None,
              spacing: tuple[float, float] | None = None) -> Positions:
    """Points on the segments every ``stride`` input nodes along them, plus their ends.

    Parameters
    ----------
    lines : ScanLines
    part : ZMap
        The input grid (``dx``, ``dy``, shape).
    stride : int
        >= 1.
    region : (my, mx) bool, optional
        Where on the pass's model nodes the ball machines: a position is kept when its
        nearest model node is in the region.
    spacing : (sx, sy), optional
        The model's node spacing (needed with ``region``).
    """
    along_x = lines.direction == "x"
    d = part.dx if along_x else part.dy
    step = stride * d
    us: list[F64] = []
    vs: list[F64] = []
    for off, a, b in zip(lines.offset, lines.start, lines.stop, strict=True):
        first = math.ceil(a / step - 1e-9)
        last = math.floor(b / step + 1e-9)
        inner = np.arange(first, last + 1) * step
        inner = inner[(inner > a) & (inner < b)]
        u = np.concatenate(([a], inner, [b])) if b > a else np.array([a])
        us.append(u)
        vs.append(np.full(u.size, off))
    u = np.concatenate(us) if us else np.zeros(0)
    v = np.concatenate(vs) if vs else np.zeros(0)
    x, y = (u, v) if along_x else (v, u)
    if region is not None and spacing is not None:
        sx, sy = spacing
        c = np.clip(np.rint(x / sx).astype(np.intp), 0, region.shape[1] - 1)
        r = np.clip(np.rint(y / sy).astype(np.intp), 0, region.shape[0] - 1)
        keep = region[r, c]
        x, y = x[keep], y[keep]
    return Positions(np.ascontiguousarray(x), np.ascontiguousarray(y))


def cl_on_model(model: F64, sx: float, sy: float, tool: Tool, pos: Positions) -> F64:
    """Drop-cutter CL on the model's own nodes, bilinear between them, at the positions."""
    cl = drop_cutter(ZMap(model, dx=sx, dy=sy), tool, "bilinear")
    return interpolate(cl, sx, sy, pos)


def interpolate(grid: F64, sx: float, sy: float, pos: Positions) -> F64:
    """Bilinear interpolation of node values ``grid`` at the positions (clamped to the grid)."""
    my, mx = grid.shape
    fx = pos.x / sx
    fy = pos.y / sy
    c0 = np.clip(np.floor(fx).astype(np.intp), 0, max(mx - 2, 0))
    r0 = np.clip(np.floor(fy).astype(np.intp), 0, max(my - 2, 0))
    c1 = np.minimum(c0 + 1, mx - 1)
    r1 = np.minimum(r0 + 1, my - 1)
    tx = np.clip(fx - c0, 0.0, 1.0)
    ty = np.clip(fy - r0, 0.0, 1.0)
    lo = grid[r0, c0] * (1.0 - tx) + grid[r0, c1] * tx
    hi = grid[r1, c0] * (1.0 - tx) + grid[r1, c1] * tx
    out: F64 = lo * (1.0 - ty) + hi * ty
    return out


def flute_lift(model: F64, sx: float, sy: float, pos: Positions, need: F64) -> int:
    """Raise the model's nodes so its bilinear surface is at least ``need`` at the positions.

    Every corner of the model cell holding a position rises to at least ``need`` there
    (in place): the bilinear surface over that cell is then at least ``need`` at the
    position, so is the drop-cutter CL there (the tip never lies below the surface under
    it), and so is the tool path's CL, bilinear between corner CLs that each are. Returns
    the number of nodes raised.
    """
    if pos.size == 0:
        return 0
    return int(_raise_corners(model, 1.0 / sx, 1.0 / sy, pos.x, pos.y,
                              np.ascontiguousarray(need, dtype=np.float64)))


@njit(cache=True, nogil=True)
def _raise_corners(model: F64, isx: float, isy: float, px: F64, py: F64, need: F64) -> int:
    my, mx = model.shape
    raised = 0
    for n in range(px.size):
        c0 = min(max(int(math.floor(px[n] * isx)), 0), max(mx - 2, 0))
        r0 = min(max(int(math.floor(py[n] * isy)), 0), max(my - 2, 0))
        for r in (r0, min(r0 + 1, my - 1)):
            for c in (c0, min(c0 + 1, mx - 1)):
                if model[r, c] < need[n]:
                    model[r, c] = need[n]
                    raised += 1
    return raised


def left_over(stock: F64, surface: F64) -> tuple[float, float]:
    """Largest and 95th-percentile ``stock - surface`` over the input nodes, mm."""
    d = stock - surface
    return float(d.max()), float(np.percentile(d, 95.0))


@dataclass(frozen=True, eq=False)
class PassCut:
    """One pass simulated: its positions, CL and real depth of cut, and stock figures.

    Attributes
    ----------
    positions : Positions
    cl : (n,) float64
    depth : (n,) float64
        Highest stock before the pass within ``R`` of the axis, minus ``cl`` (>= 0).
    gouge : float
        ``max(part - stock after)`` at the input nodes, clipped at 0.
    """

    positions: Positions
    cl: F64
    depth: F64
    gouge: float

    @property
    def depth_max(self) -> float:
        return float(self.depth.max(initial=0.0))

    @property
    def depth_mean(self) -> float:
        cutting = self.depth[self.depth > 0.0]
        return float(cutting.mean()) if cutting.size else 0.0


class StockSim:
    """The simulated stock at the input nodes, lowered pass by pass.

    Parameters
    ----------
    part : ZMap
    stock_top : float
    """

    def __init__(self, part: ZMap, stock_top: float) -> None:
        self.part = part
        self.stock = np.full(part.shape, float(stock_top))
        self._zmax = block_max(part.z)

    def base_cl(self, model_cl: F64, pos: Positions, tool: Tool) -> F64:
        """``max(model_cl, CL against the part's nodes)`` at the positions."""
        return _cl_part(self.part.z, self._zmax, BLOCK, pos.x, pos.y,
                        np.ascontiguousarray(model_cl), tool.radius, self.part.dx,
                        self.part.dy)

    def top(self, pos: Positions, tool: Tool) -> F64:
        """Highest stock node within the tool's radius of each position."""
        return _top(self.stock, block_max(self.stock), BLOCK, pos.x, pos.y, tool.radius,
                    self.part.dx, self.part.dy)

    def cut(self, pos: Positions, cl: F64, top: F64, tool: Tool) -> PassCut:
        """Machine the stock with the tool at ``cl`` on the positions (``top``: from
        :meth:`top` before the cut)."""
        cl = np.ascontiguousarray(cl, dtype=np.float64)
        _cut(self.stock, block_max(self.stock), BLOCK, pos.x, pos.y, cl, tool.radius,
             self.part.dx, self.part.dy)
        depth = np.maximum(top - cl, 0.0) if cl.size else np.zeros(0)
        depth[~np.isfinite(depth)] = 0.0
        gouge = float(max(0.0, float(np.max(self.part.z - self.stock))))
        return PassCut(pos, cl, depth, gouge)


@dataclass(frozen=True, eq=False)
class SimulatedPass:
    """What :func:`run_pass` did: the cut and the model nodes the flute rule raised."""

    cut: PassCut
    lifted_nodes: int
    spacing: float
    lowered: int


def run_pass(sim: StockSim, model: F64, spacing: tuple[float, float], tool: Tool,
             lines: ScanLines, stride: int, region: NDArray[np.bool_] | None,
             guard: float, *, lift: bool = True) -> SimulatedPass:
    """Simulate one pass over ``sim``'s stock, lifting ``model`` (in place) where the flute
    rule needs it.

    The positions' CL is ``max(CL on the model, CL against the part's nodes)``. Where the
    highest stock node within ``R`` minus the flute length ``L`` (plus ``guard``) lies
    above it, the model's nodes around those positions are raised to that height
    (:func:`flute_lift`) and the CL taken again on the raised model: every position then
    meets at most ``L`` of stock.

    Returns
    -------
    SimulatedPass
    """
    sx, sy = spacing
    pos = positions(lines, sim.part, stride, region, spacing)
    base = sim.base_cl(cl_on_model(model, sx, sy, tool, pos), pos, tool)
    top = sim.top(pos, tool)
    need = top - tool.flute_length + guard
    bind = need > base
    if not lift:
        bind[:] = False
    lifted = 0
    if bind.any():
        sub = Positions(pos.x[bind], pos.y[bind])
        lifted = flute_lift(model, sx, sy, sub, need[bind])
        base = np.maximum(base, cl_on_model(model, sx, sy, tool, pos))
        # Bilinear interpolation of corner CLs each >= need may round a hair under it.
        base[bind] = np.maximum(base[bind], need[bind])
    before = sim.stock.copy() if lifted else None
    cut = sim.cut(pos, base, top, tool)
    lowered = -1 if before is None else int(np.count_nonzero(sim.stock < before - guard))
    along = sim.part.dx if lines.direction == "x" else sim.part.dy
    return SimulatedPass(cut, lifted, stride * along, lowered)
