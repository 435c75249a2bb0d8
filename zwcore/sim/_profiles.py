"""Structuring functions of ball and flat end mills on a node grid.

The tool's lower surface above its tip is ``h(d) = R - sqrt(R² - d²)`` for a ball
and ``0`` for a flat end mill, ``d <= R`` the distance from its axis. Offsets are
node offsets ``(a, b)``: ``a`` rows (``a*dy`` along y), ``b`` columns (``b*dx``).
Every profile is mirror-symmetric in ``a`` and ``b`` (what :mod:`._morph` needs).

Drop-cutter profiles (``s``, added to the surface heights, -inf off the element)
bound the tool over the surface's continuous meaning:

- ``cell``: a node's flat square meets the tool first at its nearest point, so
  ``s = -h(d_min(square))``: exact.
- ``bilinear``: on a cell ``Q`` the surface is bilinear; for any bilinear ``T <= h``
  on ``Q ∩ disc`` (a tangent plane of the convex ``h``, or the constant
  ``h(d_min(Q))``), ``z(p) - h(p) <= z(p) - T(p)``, which is bilinear and so peaks at
  a corner. Lowering ``h`` at each node to the least ``T_Q`` of its cells therefore
  gives a node dilation that is never below the continuous drop-cutter height. Per
  cell the plane is picked (among the tangent planes at its centre, its corners and
  its nearest point, and the constant) to stay closest to ``h`` at its corners; on a
  cell the disc only partly covers, the corners outside the disc are then raised as
  far as the weight the disc's part of the cell gives them allows
  (:func:`_outside_corners_raised`).

Envelope profiles (``e``, +inf off the element) put the tool tip at each node:
``bilinear`` evaluates at the nodes (``e = h(d)``), ``cell`` takes the farthest
point of a node's square (``e = h(d_max)``), the highest the tool leaves there.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterator

import numpy as np
from numpy.typing import NDArray

from zwcore.grid.tools import Tool
from zwcore.grid.zmap import Interpolation

F64 = NDArray[np.float64]

#: Tangent points per axis tried in a cell that crosses the ball's rim ("rim" planes).
_RIM_POINTS = 8

#: Relative slack on the reach test, so rounding never drops a point the tool touches.
_REACH = 1.0 + 1e-12

#: Share of R a cell that the disc covers only in part gives up below its plane, so that
#: its corners outside the disc may rise (:func:`_outside_corners_raised`). Small: the
#: corners inside lose that much; a corner the disc barely reaches rises by about this
#: over its weight there.
_RAISE_SHARE = 1e-6

#: The cells' corners, (row, column) steps from their lower corner, in the order of the
#: last axis of :func:`_cell_geometry`'s ``cy, cx``.
_CORNERS = ((0, 0), (0, 1), (1, 0), (1, 1))


def _h(tool: Tool, d: F64) -> F64:
    """Height of the tool's lower surface above its tip at distance ``d`` (clipped to R)."""
    r = tool.radius
    if tool.kind == "flat":
        return np.zeros_like(d)
    dd = np.minimum(d, r)
    return r - np.sqrt(np.maximum(r * r - dd * dd, 0.0))


def _offsets(n_rows: int, n_cols: int, dx: float, dy: float) -> tuple[F64, F64]:
    """Coordinates (y, x) in mm of node offsets ``-n..n``, shape (2n_rows+1, 2n_cols+1)."""
    a = np.arange(-n_rows, n_rows + 1, dtype=np.float64) * dy
    b = np.arange(-n_cols, n_cols + 1, dtype=np.float64) * dx
    return a[:, None] + 0.0 * b[None, :], b[None, :] + 0.0 * a[:, None]


def _symmetric(p: F64, pick: str) -> F64:
    """Mirror-symmetrise ``p`` (max or min over its four reflections). ``h`` is symmetric,
    so a reflected bound is a bound: the max of drop profiles stays >= -h."""
    f = np.maximum if pick == "max" else np.minimum
    q = f(p, p[::-1])
    return f(q, q[:, ::-1])


def footprint(tool: Tool, dx: float, dy: float) -> tuple[int, int]:
    """Half-sizes ``(A, B)`` in nodes of the drop-cutter element (one cell beyond R)."""
    return math.ceil(tool.radius / dy) + 1, math.ceil(tool.radius / dx) + 1


def drop_profile(tool: Tool, dx: float, dy: float, interpolation: Interpolation) -> F64:
    """Cached :func:`_drop_profile` (a planner simulates the same tools again and again)."""
    return _drop_profile_cached(tool.kind, float(tool.diameter), float(dx), float(dy),
                                interpolation)


@functools.lru_cache(maxsize=32)
def _drop_profile_cached(kind: str, diameter: float, dx: float, dy: float,
                         interpolation: Interpolation) -> F64:
    out = _drop_profile(Tool("_", kind, diameter, 1.0), dx, dy, interpolation)  # type: ignore[arg-type]
    out.flags.writeable = False
    return out


def _drop_profile(tool: Tool, dx: float, dy: float, interpolation: Interpolation) -> F64:
    """Structuring functions of the drop cutter: ``CL = min over v of max over o of
    z[c + o] + s[v, o]``.

    For ``bilinear`` balls, three sets of safe planes, each tight where the others are
    not (measured on Mount Rushmore, a dome, a valley and the R 8 pocket): per cell
    the tangent plane closest to ``h`` at its worst corner among those at its centre,
    corners and nearest point (``balanced``); the tangent plane at its nearest point
    (exact for a ball on a flat at a node); ``balanced`` plus an 8 x 8 grid of tangent
    points in cells crossing the rim (walls met by the ball's steep side).

    Returns
    -------
    (V, 2A + 1, 2B + 1) float64
        -inf off the element; see :func:`footprint` for ``A, B``.
    """
    A, B = footprint(tool, dx, dy)
    y, x = _offsets(A, B, dx, dy)
    r = tool.radius
    if interpolation == "cell":
        # nearest point of the node's dx x dy square
        dmin = np.hypot(np.maximum(np.abs(x) - dx / 2, 0.0), np.maximum(np.abs(y) - dy / 2, 0.0))
        s = np.where(dmin <= r * _REACH, -_h(tool, dmin), -np.inf)
        return _symmetric(s, "max")[None]
    sets = ("balanced", "nearest", "rim") if tool.kind == "ball" else ("balanced",)
    out = []
    for planes in sets:
        h_low = _bilinear_lowered(tool, dx, dy, A, B, planes)
        out.append(_symmetric(np.where(np.isfinite(h_low), -h_low, -np.inf), "max"))
    return np.stack(out)


def _tangent(tool: Tool, p: tuple[F64, F64], cy: F64, cx: F64) -> F64:
    """Tangent plane of ``h`` at points ``p`` = (py, px), evaluated at corners (cy, cx);
    +nan where ``p`` is not strictly inside the disc (no finite plane)."""
    py, px = p
    r = tool.radius
    q2 = r * r - px * px - py * py
    ok = q2 > (1e-9 * r) ** 2
    root = np.sqrt(np.where(ok, q2, 1.0))
    hp = r - root
    t = hp[..., None] + (px[..., None] * (cx - px[..., None])
                         + py[..., None] * (cy - py[..., None])) / root[..., None]
    return np.where(ok[..., None], t, np.nan)


def _cell_geometry(dx: float, dy: float, A: int, B: int) -> dict[str, F64]:
    """Cells with lower corner at offsets ``(-A..A-1, -B..B-1)``: their corners (last axis
    (0,0) (0,1) (1,0) (1,1) in (row, column)), lower-corner coordinates and the point
    of each cell nearest the axis."""
    qa = np.arange(-A, A, dtype=np.float64)[:, None] * dy + 0.0 * np.arange(2 * B)[None, :]
    qb = np.arange(-B, B, dtype=np.float64)[None, :] * dx + 0.0 * np.arange(2 * A)[:, None]
    return {"qa": qa, "qb": qb,
            "cy": np.stack([qa, qa, qa + dy, qa + dy], axis=-1),
            "cx": np.stack([qb, qb + dx, qb, qb + dx], axis=-1),
            "ny": np.clip(0.0, qa, qa + dy), "nx": np.clip(0.0, qb, qb + dx)}


def _candidate_planes(tool: Tool, g: dict[str, F64], dx: float, dy: float, planes: str
                      ) -> Iterator[F64]:
    """Affine minorants of ``h`` per cell, evaluated at its corners, (2A, 2B, 4) each, nan
    where a tangent point lies outside the disc: the constant ``h(d_min)`` and the
    tangent plane at the nearest point (``nearest``), plus those at the centre and
    corners (``balanced``, ``rim``). One at a time: a large ball's cells are many."""
    qa, qb, cy, cx = g["qa"], g["qb"], g["cy"], g["cx"]
    dmin = np.hypot(g["ny"], g["nx"])
    yield np.broadcast_to(_h(tool, dmin)[..., None], cy.shape)
    yield _tangent(tool, (g["ny"], g["nx"]), cy, cx)
    if planes != "nearest":
        yield _tangent(tool, (qa + dy / 2, qb + dx / 2), cy, cx)
        for j in range(4):
            yield _tangent(tool, (cy[..., j], cx[..., j]), cy, cx)


def _worst_corner(planes: F64, hc: F64) -> F64:
    """How far a plane lies below ``h`` at its worst corner (<= 0; -inf: no plane)."""
    score = np.min(np.minimum(planes - hc, 0.0), axis=-1)
    return np.where(np.isnan(score), -np.inf, score)


def _refine_rim(tool: Tool, g: dict[str, F64], dx: float, dy: float, best: F64, hc: F64
                ) -> None:
    """In cells crossing the rim, try tangent planes on a grid of points (in place)."""
    rim = np.hypot(g["cy"], g["cx"]).max(axis=-1) > tool.radius
    cy, cx, hcr = g["cy"][rim], g["cx"][rim], hc[rim]
    qa, qb = g["qa"][rim], g["qb"][rim]
    top = best[rim]
    score = _worst_corner(top, hcr)
    n = _RIM_POINTS
    for u in range(n):
        for v in range(n):
            plane = _tangent(tool, (qa + (u + 0.5) / n * dy, qb + (v + 0.5) / n * dx), cy, cx)
            s = _worst_corner(plane, hcr)
            better = s > score
            top[better], score[better] = plane[better], s[better]
    best[rim] = top


def _bilinear_lowered(tool: Tool, dx: float, dy: float, A: int, B: int, planes: str) -> F64:
    """Per node offset, the least of its cells' affine minorants of ``h`` (inf: no cell
    reaches the disc); per cell the candidate plane closest to ``h`` at its worst corner."""
    g = _cell_geometry(dx, dy, A, B)
    dmin = np.hypot(g["ny"], g["nx"])
    reach = dmin <= tool.radius * _REACH
    if tool.kind == "flat":
        best = np.zeros_like(g["cy"])
    else:
        hc = _h(tool, np.hypot(g["cy"], g["cx"]))
        best = np.empty_like(g["cy"])
        score = np.full(dmin.shape, -np.inf)
        for n, plane in enumerate(_candidate_planes(tool, g, dx, dy, planes)):
            s = _worst_corner(plane, hc)
            better = s > score if n else np.ones(dmin.shape, dtype=bool)
            best[better], score[better] = plane[better], s[better]
        if planes == "rim":
            _refine_rim(tool, g, dx, dy, best, hc)
    best = np.where(reach[..., None], _outside_corners_raised(tool, g, dx, dy, best), np.inf)
    low = np.full((2 * A + 1, 2 * B + 1), np.inf)
    for j, (da, db) in enumerate(_CORNERS):
        view = low[da:da + 2 * A, db:db + 2 * B]
        np.minimum(view, best[..., j], out=view)
    return low


def envelope_profile(tool: Tool, dx: float, dy: float, interpolation: Interpolation) -> F64:
    """Additive profile ``e`` of the envelope: ``M[p] = min(CL[p - o] + e[o])``.

    Returns
    -------
    (2A + 1, 2B + 1) float64
        +inf off the element (``A = floor(R/dy)``, ``B = floor(R/dx)``).
    """
    r = tool.radius
    A, B = math.floor(r / dy), math.floor(r / dx)
    y, x = _offsets(A, B, dx, dy)
    if interpolation == "cell":
        d = np.hypot(np.abs(x) + dx / 2, np.abs(y) + dy / 2)
    else:
        d = np.hypot(x, y)
    e = np.where(d <= r, _h(tool, d), np.inf)
    return _symmetric(e, "max")


def flat_reach_profile(radius: float, dx: float, dy: float, interpolation: Interpolation
                       ) -> F64:
    """Flat disc of ``radius`` for the highest surface point within it (0 on, -inf off):
    a flat end mill's drop-cutter element, used for the stock a tool's cylinder meets."""
    return drop_profile(Tool("_reach", "flat", 2.0 * radius, 1.0), dx, dy, interpolation)[0]


def _outside_corners_raised(tool: Tool, g: dict[str, F64], dx: float, dy: float, best: F64
                            ) -> F64:
    """Corner values ``(2A, 2B, 4)`` of a bilinear minorant of ``h`` per cell: the plane
    ``best`` where the disc covers the whole cell, else raised at the corners outside it.

    The bound needs ``T <= h`` only on ``Q ∩ disc``. With ``P`` the cell's plane and
    ``w_j`` the bilinear weight of corner ``j``, ``T = P - δ + Σ_out δ w_j / (n W_j)``
    (``n`` corners outside the disc, ``W_j >= max w_j`` over ``Q ∩ disc``, from the box
    the disc spans in the cell) is bilinear and ``T <= P <= h`` there. A corner the disc
    barely reaches rises by ``δ / (n W_j)``: the top of a wall just beyond the ball's rim
    then weighs what the ramp towards it really brings within the rim, instead of
    counting as if the ball touched it (on Mount Rushmore's 0.1 mm grid a Ø1 ball's CL
    stood up to 2.2 mm above the true height beside the cliffs, 0.19 mm at the 95th
    percentile; 0.96 and 0.05 mm with the raise, against the same surface refined eight
    times).
    """
    r = tool.radius
    outside = np.hypot(g["cy"], g["cx"]) > r * (1.0 + 1e-9)
    n_out = outside.sum(axis=-1)
    if not n_out.any():
        return best
    qa, qb = g["qa"], g["qb"]
    rr = r * (1.0 + 1e-15)  # the box a little larger than the disc's part: W only larger
    yr = np.sqrt(np.maximum(rr * rr - g["nx"] ** 2, 0.0))  # |y| on the disc in the columns
    xr = np.sqrt(np.maximum(rr * rr - g["ny"] ** 2, 0.0))
    xlo, xhi = np.maximum(qb, -xr), np.minimum(qb + dx, xr)
    ylo, yhi = np.maximum(qa, -yr), np.minimum(qa + dy, yr)
    delta = _RAISE_SHARE * r
    raised = best - np.where(n_out > 0, delta, 0.0)[..., None]
    share = delta / np.maximum(n_out, 1)
    for j, (ja, jb) in enumerate(_CORNERS):
        u = (xhi - qb) / dx if jb else (qb + dx - xlo) / dx
        v = (yhi - qa) / dy if ja else (qa + dy - ylo) / dy
        w = np.clip(u, 0.0, 1.0) * np.clip(v, 0.0, 1.0) + 1e-9  # never 0: finite raises
        raised[..., j] += np.where(outside[..., j], share / w, 0.0)
    return raised
