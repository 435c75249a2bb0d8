"""Contour tool paths of flat-end-mill stages (design section 4, issue 12).

At each contour height ``h`` of a stage the tool centre may go where no terrace of the
stage model above ``h`` lies within the tool radius (plus a margin): with ``d`` the
Euclidean distance transform from those terrace nodes (``scipy.ndimage``), the allowed
region is ``d >= R + margin`` inside the stock outline. Its boundary (the profile pass)
and the inward offsets at the stepover (the clearing rings) are level sets of one field,
``min(d - R - margin, distance to the stock edge)``, traced with
:func:`skimage.measure.find_contours`; every point of a ring at offset ``a`` is within
``a`` of the ring before it (a distance field's level sets), so rings ``stepover < R``
apart leave nothing between them. A traced vertex lies between nodes, up to a step closer
to a terrace than the field says: each is pushed straight away from its nearest terrace
node (a KD-tree) to ``R + margin``; the margin is the arc tolerance plus 1 µm.

Each ring is fitted with :func:`zwcore.arcs.fit_arcs` into a C1 chain of arcs and lines
(G02/G03 in the program), oriented with the allowed region on its left: with a clockwise
spindle (M3) the material is on the cutter's right, i.e. climb milling.

Rings of one height are cut part by part of the allowed region (its connected parts),
innermost offsets first, the nearest ring next, each started at its vertex nearest the end
of the ring before (:func:`order_rings`). Where the straight step from that end to the next
start keeps the tool centre at least ``R + margin / 2`` from every terrace node above the
height (exact point-to-segment distances, :func:`link_is_clear`), the tool stays down and
feeds across at the cutting height: it cuts only material above ``h`` inside the allowed
region grown by ``R``, which that height clears anyway, never a terrace. Otherwise it
retracts to the clearance and enters the next ring by ramping down along its own chain
(a helix on arcs) within the tool's ramp angle, from just above the previous height,
instead of plunging. Heights are written rounded up to the program's 4 decimals, so a
floor at ``h`` is never cut below.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage
from scipy.spatial import cKDTree
from skimage.measure import find_contours

from zwcore.arcs import fit_arcs
from zwcore.arcs.fit import ArcChain
from zwcore.contour.results import ContourStage
from zwcore.grid.sampling import cells_at_fine_nodes
from zwcore.grid.zmap import ZMap
from zwcore.toolpath.program import ARC_CCW, ARC_CW, LINE, RAPID, CuttingData, Moves, StagePath

__all__ = ["contour_stage_path", "link_is_clear", "order_rings", "rings"]

F64 = NDArray[np.float64]

#: Height above the previous contour height where a ramp starts, mm.
RAMP_START_GAP = 0.5
#: Decimals of the program's coordinates (heights are rounded up to them).
DECIMALS = 4
#: Rings shorter than this many grid steps are not machined (nothing fits inside them).
MIN_RING_STEPS = 2.0


def _field(part: ZMap, model_fine: F64, h: float, radius: float, margin: float
           ) -> tuple[F64, F64]:
    """``(profile field, clearing field)`` on the nodes: ``> 0`` where the centre may go."""
    forbidden = model_fine > h + 1e-9
    if forbidden.any():
        dist = ndimage.distance_transform_edt(~forbidden, sampling=(part.dy, part.dx))
    else:
        dist = np.full(part.shape, 1e9)
    f = dist - radius - margin
    ny, nx = part.shape
    half = 0.5 * min(part.dx, part.dy)
    ex = np.minimum(np.arange(nx), np.arange(nx)[::-1]) * part.dx
    ey = np.minimum(np.arange(ny), np.arange(ny)[::-1]) * part.dy
    edge = np.minimum(ey[:, None], ex[None, :]) + half
    return f, np.minimum(f, edge)


def _trace(f: F64, level: float, part: ZMap) -> list[F64]:
    """Closed level lines of ``f`` (padded by one node outside the stock, below any level),
    as ``(m, 2)`` xy loops with ``f > level`` on their left."""
    pad = np.pad(f, 1, constant_values=min(float(f.min()), level) - 1.0)
    out = []
    for c in find_contours(pad, level):
        if len(c) < 4 or not np.allclose(c[0], c[-1]):
            continue
        xy = np.column_stack([part.x0 + (c[:, 1] - 1) * part.dx, part.y0 + (c[:, 0] - 1) * part.dy])
        length = float(np.hypot(*np.diff(xy, axis=0).T).sum())
        if length < MIN_RING_STEPS * max(part.dx, part.dy):
            continue
        # which side is allowed: sample just left of the longest segment
        seg = np.diff(xy, axis=0)
        j = int(np.argmax(np.hypot(seg[:, 0], seg[:, 1])))
        mid = 0.5 * (xy[j] + xy[j + 1])
        nrm = np.array([-seg[j, 1], seg[j, 0]]) / np.hypot(*seg[j])
        probe = mid + nrm * 0.25 * min(part.dx, part.dy)
        val = ndimage.map_coordinates(pad, [[(probe[1] - part.y0) / part.dy + 1],
                                            [(probe[0] - part.x0) / part.dx + 1]], order=1)[0]
        out.append(xy[:-1] if val > level else xy[::-1][:-1])
    return out


def _push_out(loop: F64, tree: cKDTree | None, clear: float) -> F64:
    """Move loop vertices closer than ``clear`` to a forbidden node straight away from it
    (a traced vertex sits between nodes, so the field's own distance is a step off)."""
    if tree is None:
        return loop
    for _ in range(4):
        d, j = tree.query(loop)
        close = d < clear
        if not close.any():
            break
        q = tree.data[j[close]]
        away = (loop[close] - q) / np.maximum(d[close], 1e-12)[:, None]
        loop = loop.copy()
        loop[close] = q + away * clear
    return loop


def _forbidden_tree(part: ZMap, model_fine: F64, h: float) -> cKDTree | None:
    """KD-tree of the boundary nodes of the terraces above ``h``."""
    forbidden = model_fine > h + 1e-9
    if not forbidden.any():
        return None
    edge = forbidden & ~ndimage.binary_erosion(forbidden, border_value=1)
    i, k = np.nonzero(edge)
    return cKDTree(np.column_stack([part.x0 + k * part.dx, part.y0 + i * part.dy]))


def _level_rings(part: ZMap, model_fine: F64, h: float, radius: float, margin: float,
                 stepover: float) -> tuple[list[tuple[int, F64]], cKDTree | None,
                                           NDArray[np.int32]]:
    """:func:`rings`, the terrace boundary nodes' KD-tree and the labels of the allowed
    region's connected parts on the nodes (0 outside it)."""
    f, g = _field(part, model_fine, h, radius, margin)
    tree = _forbidden_tree(part, model_fine, h)
    clear = radius + margin
    out = [(0, _push_out(loop, tree, clear)) for loop in _trace(f, 0.0, part)]
    k = 1
    top = float(g.max())
    while k * stepover < top:
        for loop in _trace(g, k * stepover, part):
            span = float(np.hypot(*(loop.max(axis=0) - loop.min(axis=0))))
            # a ring this small lies within (stepover + span/2) < R of the ring around it
            if span >= 0.2 * radius:
                out.append((k, _push_out(loop, tree, clear)))
        k += 1
    out.sort(key=lambda item: -item[0])
    labels, _ = ndimage.label(f > 0)
    return out, tree, labels.astype(np.int32)


def rings(part: ZMap, model_fine: F64, h: float, radius: float, margin: float,
          stepover: float) -> list[tuple[int, F64]]:
    """Profile and clearing rings at one height, innermost offsets first.

    Returns
    -------
    list of (offset index, (m, 2) float64 loop)
        Offset index 0 is the profile pass; loops have the allowed region on the left.
    """
    return _level_rings(part, model_fine, h, radius, margin, stepover)[0]


def _ring_part(part: ZMap, labels: NDArray[np.int32], loop: F64) -> int:
    """The connected part of the allowed region a ring runs in (most of its vertices' nearest
    nodes; -1 when none lies in it)."""
    ny, nx = labels.shape
    i = np.clip(np.rint((loop[:, 1] - part.y0) / part.dy).astype(np.int64), 0, ny - 1)
    k = np.clip(np.rint((loop[:, 0] - part.x0) / part.dx).astype(np.int64), 0, nx - 1)
    lab = labels[i, k]
    lab = lab[lab > 0]
    return int(np.bincount(lab).argmax()) if len(lab) else -1


def order_rings(part: ZMap, labels: NDArray[np.int32], items: list[tuple[int, F64]],
                start: F64) -> list[F64]:
    """Rings of one height in cutting order, each rolled to start at its vertex nearest the
    previous ring's start (where the previous ring ends).

    Part by part of the allowed region (the nearest part next); within a part innermost
    offsets first, and among rings of one offset the nearest next.

    Parameters
    ----------
    part : ZMap
    labels : (ny, nx) int32
        Connected parts of the allowed region.
    items : list of (offset index, (m, 2) float64 loop)
    start : (2,) float64
        Where the tool is before the height.

    Returns
    -------
    list of (m, 2) float64
    """
    groups: dict[int, list[tuple[int, F64]]] = {}
    for k, loop in items:
        groups.setdefault(_ring_part(part, labels, loop), []).append((k, loop))
    pos = np.asarray(start, np.float64)[:2]
    out: list[F64] = []

    def nearest(loops: list[tuple[int, F64]]) -> tuple[int, int, float]:
        best = (0, 0, math.inf)
        for n, (_, loop) in enumerate(loops):
            d = np.hypot(loop[:, 0] - pos[0], loop[:, 1] - pos[1])
            j = int(np.argmin(d))
            if d[j] < best[2]:
                best = (n, j, float(d[j]))
        return best

    while groups:
        # the part whose innermost rings come nearest
        key = min(groups, key=lambda g: nearest(
            [it for it in groups[g] if it[0] == max(x[0] for x in groups[g])])[2])
        rest = groups.pop(key)
        while rest:
            top = max(x[0] for x in rest)
            cand = [it for it in rest if it[0] == top]
            n, j, _ = nearest(cand)
            loop = np.roll(cand[n][1], -j, axis=0)
            # by identity: ``list.remove`` compares with ``==``, and two rings of the same
            # offset compare their arrays (an ambiguous truth value)
            rest.pop(next(i for i, it in enumerate(rest) if it is cand[n]))
            out.append(loop)
            pos = loop[0]
    return out


def link_is_clear(tree: cKDTree | None, a: F64, b: F64, clear: float) -> bool:
    """Whether the straight move from ``a`` to ``b`` (xy) keeps at least ``clear`` from
    every terrace boundary node (exact point-to-segment distances over the nodes near it)."""
    if tree is None:
        return True
    a, b = np.asarray(a, np.float64)[:2], np.asarray(b, np.float64)[:2]
    ab = b - a
    length = float(np.hypot(*ab))
    step = max(clear, 1e-6)
    n = max(2, math.ceil(length / step) + 1)
    samples = a + np.linspace(0.0, 1.0, n)[:, None] * ab
    # a node within ``clear`` of the move is within ``clear + step / 2`` of a sample
    near = tree.query_ball_point(samples, clear + 0.5 * step + 1e-9)
    idx = np.unique(np.concatenate([np.asarray(x, np.int64) for x in near]))
    if not len(idx):
        return True
    q = tree.data[idx]
    t = np.clip(((q - a) @ ab) / max(length * length, 1e-300), 0.0, 1.0)
    d = np.hypot(*(q - (a + t[:, None] * ab)).T)
    return bool(d.min() >= clear)


def _chain_moves(chain: ArcChain, z_start: float, z_end: float, plunge: bool) -> Moves:
    """One lap of a chain, z linear in path length from ``z_start`` to ``z_end``."""
    segs = chain.segments
    lengths = np.array([s.length for s in segs])
    total = max(float(lengths.sum()), 1e-12)
    z = z_start + (z_end - z_start) * np.cumsum(lengths) / total
    kind = np.array([LINE if s.kind == "line" else (ARC_CCW if s.ccw else ARC_CW) for s in segs],
                    np.int8)
    end = np.column_stack([[s.end[0] for s in segs], [s.end[1] for s in segs], z])
    center = np.array([s.center if s.center is not None else (np.nan, np.nan) for s in segs],
                      np.float64).reshape(-1, 2)
    return Moves(kind, end, center, np.full(len(segs), plunge))


def _ring_moves(chain: ArcChain, z_from: float, h: float, clearance: float,
                ramp_angle_deg: float, linked: bool) -> Moves:
    """A ring at ``h``: entered by a feed link at ``h`` to its start (``linked``), else by a
    rapid over its start, a rapid down to ``z_from`` and ramp laps; then one lap at ``h``
    (the caller adds the retract)."""
    sx, sy = chain.segments[0].start
    if linked:
        return Moves.concat([Moves.lines(np.array([[sx, sy, h]])),
                             _chain_moves(chain, h, h, False)])
    length = sum(s.length for s in chain.segments)
    drop = max(z_from - h, 0.0)
    laps = max(1, math.ceil(drop / math.tan(math.radians(ramp_angle_deg)) / max(length, 1e-9)))
    parts = [Moves.lines(np.array([[sx, sy, clearance], [sx, sy, z_from]]), kind=RAPID)]
    for lap in range(laps):
        parts.append(_chain_moves(chain, z_from - drop * lap / laps,
                                  z_from - drop * (lap + 1) / laps, True))
    parts.append(_chain_moves(chain, h, h, False))
    return Moves.concat(parts)


def contour_stage_path(part: ZMap, stage: ContourStage, index: int, cutting: CuttingData, *,
                       clearance: float, tolerance: float, stepover: float,
                       start_top: float | None = None) -> StagePath:
    """Tool path of one contour stage.

    Parameters
    ----------
    part : ZMap
    stage : ContourStage
        Tool, terraced model and contour heights (``z_levels[0]`` is the top it starts from).
    index : int
    cutting : CuttingData
    clearance : float
        Safe height for rapids, mm.
    tolerance : float
        Arc fit tolerance, mm.
    stepover : float
        Distance between clearing rings, mm (< the tool radius for full coverage).
    start_top : float, optional
        Highest material the stage meets (default ``z_levels[0]``); the first height's
        ramps start just above it.

    Returns
    -------
    StagePath
        ``figures``: ``rings``, ``arcs``, ``lines``, ``levels``, ``links`` (rings entered
        by a feed link from the ring before), ``retracts``.
    """
    tool = stage.tool
    model_fine = cells_at_fine_nodes(stage.model, stage.scale, part.shape)
    margin = tolerance + 1e-3  # the arc fit's band and rounding
    # a feed link keeps this far from the terraces: inside the allowed region (whose
    # rings keep R + margin) with room for the rounding of its ends
    link_clear = tool.radius + 0.5 * margin
    prev = stage.z_levels[0] if start_top is None else start_top
    parts: list[Moves] = []
    n_rings = n_arcs = n_lines = n_links = n_retracts = 0
    pos = np.array([part.x0, part.y0])
    for h in stage.z_levels[1:]:
        items, tree, labels = _level_rings(part, model_fine, h, tool.radius, margin, stepover)
        # the program's 4 decimals rounded up: a floor at ``h`` is never cut below
        h_out = math.ceil(h * 10.0**DECIMALS - 1e-6) / 10.0**DECIMALS
        at: F64 | None = None  # where the tool is at ``h`` (None: at the clearance)
        for loop in order_rings(part, labels, items, pos):
            chain = fit_arcs(loop, tolerance, closed=True)
            if not chain.segments:
                continue
            start = np.array(chain.segments[0].start)
            linked = at is not None and link_is_clear(tree, at, start, link_clear)
            if at is not None and not linked:
                parts.append(Moves.lines(np.array([[at[0], at[1], clearance]]), kind=RAPID))
                n_retracts += 1
            parts.append(_ring_moves(chain, prev + RAMP_START_GAP, h_out, clearance,
                                     cutting.ramp_angle_deg, linked))
            at = pos = start
            n_links += linked
            n_rings += 1
            n_arcs += chain.n_arcs
            n_lines += chain.n_lines
        if at is not None:
            parts.append(Moves.lines(np.array([[at[0], at[1], clearance]]), kind=RAPID))
            n_retracts += 1
        prev = h
    moves = Moves.concat(parts)
    start = moves.end[0].copy() if len(moves) else np.array([part.x0, part.y0, clearance])
    figures = {"rings": float(n_rings), "arcs": float(n_arcs), "lines": float(n_lines),
               "levels": float(len(stage.z_levels) - 1), "links": float(n_links),
               "retracts": float(n_retracts)}
    return StagePath(index, "contour", tool, cutting, start, moves, figures)
