"""DXF curves to arc chains and back (issue 13, part 3b), with ezdxf.

Reading: the model space's LWPOLYLINE, POLYLINE (2-D and 3-D) and SPLINE
entities become chains.

- Straight polyline segments are fitted with :func:`zwcore.arcs.fit_arcs`
  within ``tolerance``; a polyline without bulges is one curve (closed when the
  entity is), so it comes out C1 except at its real corners.
- A bulged segment *is* an arc and stays that arc, exactly; the straight runs
  between bulges are fitted separately, ending at the bulges' end points.
- A spline is flattened to a polyline within ``SPLINE_SHARE * tolerance`` of it
  (ezdxf's adaptive flattening), which is then fitted within the rest of the
  tolerance, so the chain is within ``tolerance`` of the true spline.
- LINE, ARC and CIRCLE entities are already lines and arcs: they pass through
  unchanged (issue 13: arcs in the input stay arcs).

Entities whose plane is not the XY plane (extrusion not +-Z) are skipped with a
note; a mirrored OCS (extrusion -Z) is turned into world coordinates. 3-D
polylines and splines are projected on XY (a note says so when their Z varies).
Units are the drawing's: ``tolerance`` is in them.

Writing: chains as a DXF (R2010) of LINE and ARC entities (CIRCLE for a full
circle), each on its source entity's layer.
"""

from __future__ import annotations

import io
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from zwcore.arcs.fit import Segment, chain_tangents, fit_arcs
from zwcore.errors import InvalidInputError, LimitExceededError

__all__ = ["SPLINE_SHARE", "DxfChain", "DxfResult", "chains_to_dxf", "dxf_to_chains"]

#: Share of the tolerance spent on flattening splines (the fit gets the rest).
SPLINE_SHARE = 0.1
#: Largest coordinate read (drawing units); entities beyond are skipped with a note.
MAX_COORDINATE = 1e6
#: A junction turning more than this (radians) is a corner, not a smooth junction.
CORNER_KINK = 1e-6
_CURVES = ("LWPOLYLINE", "POLYLINE", "SPLINE")
_PASS = ("LINE", "ARC", "CIRCLE")


@dataclass(frozen=True)
class DxfChain:
    """The chain of one source entity (``fitted`` False for LINE/ARC/CIRCLE passed through).

    ``points`` is the ``(N, 2)`` polyline the chain was measured against (the
    polyline's vertices, or the flattened spline); deviations are the largest of
    its fitted runs (0 where every piece was kept).
    """

    source: str
    handle: str
    layer: str
    closed: bool
    segments: tuple[Segment, ...]
    points: np.ndarray
    fitted: bool
    max_deviation_points: float = 0.0
    max_deviation_chain: float = 0.0

    @property
    def corners(self) -> tuple[int, ...]:
        """Junctions (``i``: end of segment ``i``) where the chain is not tangent-continuous."""
        kinks = chain_tangents(self.segments, self.closed)
        return tuple(int(i) for i in np.flatnonzero(kinks > CORNER_KINK))


@dataclass(frozen=True)
class DxfResult:
    chains: tuple[DxfChain, ...]
    counts: dict[str, int]
    notes: tuple[str, ...] = field(default=())

    @property
    def max_deviation(self) -> float:
        return max((max(c.max_deviation_points, c.max_deviation_chain) for c in self.chains),
                   default=0.0)


def _read(data: bytes) -> Any:
    from ezdxf import recover

    if not data.strip():
        raise InvalidInputError("body", "empty DXF")
    if data.startswith(b"AutoCAD Binary DXF"):
        raise InvalidInputError("body", "binary DXF is not read; save the drawing as ASCII DXF")
    try:
        doc, _auditor = recover.read(io.BytesIO(data))
    except Exception as exc:  # ezdxf reports broken files in several exception types
        raise InvalidInputError("body", f"not a readable DXF file: {exc}"[:300]) from None
    return doc


def _bulge_arc(p1: np.ndarray, p2: np.ndarray, bulge: float) -> Segment:
    """The arc of a bulged segment: sweep ``4 atan(bulge)``, > 0 counter-clockwise."""
    sweep = 4.0 * math.atan(bulge)
    d = p2 - p1
    c = math.hypot(d[0], d[1])
    h = 0.5 * c / math.tan(0.5 * sweep)  # signed: the centre is left of p1->p2 when ccw
    mid = 0.5 * (p1 + p2)
    centre = mid + h * np.array([-d[1], d[0]]) / c
    radius = abs(0.5 * c / math.sin(0.5 * sweep))
    return Segment("arc", (float(p1[0]), float(p1[1])), (float(p2[0]), float(p2[1])),
                   (float(centre[0]), float(centre[1])), radius, sweep > 0, sweep)


def _line(p1: np.ndarray, p2: np.ndarray) -> Segment:
    return Segment("line", (float(p1[0]), float(p1[1])), (float(p2[0]), float(p2[1])))


def _to_wcs(entity: Any, pts: np.ndarray) -> tuple[np.ndarray, bool] | None:
    """OCS points to world XY and whether the OCS is mirrored; None off the XY plane."""
    ext = entity.dxf.get("extrusion", (0.0, 0.0, 1.0))
    ez = float(ext[2]) / max(math.sqrt(sum(float(v) ** 2 for v in ext)), 1e-300)
    if abs(abs(ez) - 1.0) > 1e-9:
        return None
    if ez > 0:
        return pts, False
    # arbitrary-axis algorithm for (0, 0, -1): OCS x is world -x, y is world y
    return np.column_stack([-pts[:, 0], pts[:, 1]]), True


def _mirror(seg: Segment) -> Segment:
    assert seg.sweep is not None and seg.ccw is not None
    return Segment("arc", seg.start, seg.end, seg.center, seg.radius, not seg.ccw, -seg.sweep)


def _polyline_pieces(entity: Any) -> tuple[np.ndarray, np.ndarray, bool] | None:
    """Vertices ``(N, 2)`` in world XY, bulges ``(N,)`` (world orientation), closed flag."""
    kind = entity.dxftype()
    if kind == "LWPOLYLINE":
        raw = np.array([(x, y, b) for x, y, b in entity.get_points(format="xyb")], dtype=float)
        closed = bool(entity.closed)
    else:
        if not (entity.is_2d_polyline or entity.is_3d_polyline):
            return None  # polyface and polygon meshes are surfaces, not curves
        raw = np.array([(v.dxf.location[0], v.dxf.location[1], v.dxf.get("bulge", 0.0))
                        for v in entity.vertices], dtype=float)
        closed = bool(entity.is_closed)
        if entity.is_3d_polyline:
            return (raw[:, :2], np.zeros(len(raw)), closed) if len(raw) else None
    if len(raw) == 0:
        return None
    got = _to_wcs(entity, raw[:, :2])
    if got is None:
        return None
    xy, mirrored = got
    bulges = -raw[:, 2] if mirrored else raw[:, 2]
    if not np.all(np.isfinite(bulges)) or np.abs(bulges).max(initial=0.0) > 1e6:
        raise InvalidInputError("body", "a bulge is not finite or beyond 1e6")
    return xy, bulges, closed


def _fit_open(pts: np.ndarray, tol: float, corner: float, closed: bool = False
              ) -> tuple[tuple[Segment, ...], float, float]:
    if len(pts) == 2 and not closed:
        return (_line(pts[0], pts[1]),), 0.0, 0.0
    chain = fit_arcs(pts, tol, closed=closed, corner_angle_deg=corner)
    return chain.segments, chain.max_deviation_points, chain.max_deviation_chain


def _polyline_chain(xy: np.ndarray, bulges: np.ndarray, closed: bool, tol: float,
                    corner: float) -> tuple[tuple[Segment, ...], float, float]:
    """Bulged segments kept as arcs, straight runs between them fitted."""
    keep = np.ones(len(xy), dtype=bool)
    keep[1:] = np.hypot(*np.diff(xy, axis=0).T) > 1e-12
    xy, bulges = xy[keep], bulges[keep]
    if closed and len(xy) > 1 and math.hypot(*(xy[-1] - xy[0])) <= 1e-12:
        xy, bulges = xy[:-1], bulges[:-1]
    n = len(xy)
    if n < 2:
        return (), 0.0, 0.0
    nseg = n if closed else n - 1
    if not np.any(bulges[:nseg] != 0.0):
        return _fit_open(xy, tol, corner, closed=closed)
    segs: list[Segment] = []
    dev_p = dev_c = 0.0
    run = [0]
    for i in range(nseg):
        j = (i + 1) % n
        if bulges[i] == 0.0:
            run.append(j)
            continue
        if len(run) > 1:
            s, a, b = _fit_open(xy[run], tol, corner)
            segs.extend(s)
            dev_p, dev_c = max(dev_p, a), max(dev_c, b)
        segs.append(_bulge_arc(xy[i], xy[j], float(bulges[i])))
        run = [j]
    if len(run) > 1:
        s, a, b = _fit_open(xy[run], tol, corner)
        segs.extend(s)
        dev_p, dev_c = max(dev_p, a), max(dev_c, b)
    return tuple(segs), dev_p, dev_c


def _passed(entity: Any) -> tuple[Segment, ...] | None:
    kind = entity.dxftype()
    if kind == "LINE":
        s, e = entity.dxf.start, entity.dxf.end
        return (Segment("line", (float(s[0]), float(s[1])), (float(e[0]), float(e[1]))),)
    pts = np.array([[0.0, 0.0], [float(entity.dxf.center[0]), float(entity.dxf.center[1])]])
    got = _to_wcs(entity, pts)
    if got is None:
        return None
    c, mirrored = got[0][1], got[1]
    r = float(entity.dxf.radius)
    if kind == "CIRCLE":
        a0, sweep = 0.0, 2.0 * math.pi
    else:
        a0 = math.radians(float(entity.dxf.start_angle))
        sweep = (math.radians(float(entity.dxf.end_angle)) - a0) % (2.0 * math.pi)
        sweep = sweep or 2.0 * math.pi
    if mirrored:
        a0 = math.pi - a0  # OCS x is world -x
    sweep = -sweep if mirrored else sweep
    p0 = (float(c[0] + r * math.cos(a0)), float(c[1] + r * math.sin(a0)))
    p1 = (float(c[0] + r * math.cos(a0 + sweep)), float(c[1] + r * math.sin(a0 + sweep)))
    return (Segment("arc", p0, p1, (float(c[0]), float(c[1])), r, sweep > 0, sweep),)


def _spline_points(entity: Any, tol: float, max_points: int) -> np.ndarray:
    ctrl = np.asarray(entity.control_points or entity.fit_points, dtype=float).reshape(-1, 3)
    if not (np.all(np.isfinite(ctrl)) and np.abs(ctrl).max(initial=0.0) <= MAX_COORDINATE):
        raise InvalidInputError("body", f"control points not finite or beyond {MAX_COORDINATE:g}")
    # a B-spline lies in its control polygon's hull and is no longer than it: the
    # polygon's length bounds the flattening's point count before it runs
    bound = float(np.hypot(*np.diff(ctrl[:, :2], axis=0).T).sum()) if len(ctrl) > 1 else 0.0
    step = SPLINE_SHARE * tol
    if bound / step > 50.0 * max_points:
        raise LimitExceededError(
            "tolerance", f"a spline of length up to {bound:.6g} flattened within {step:g} "
            f"would exceed the point limit of {max_points}; use a larger tolerance")
    pts = np.array([(v[0], v[1]) for v in entity.flattening(step, segments=8)], dtype=float)
    return pts


def dxf_to_chains(data: bytes, tolerance: float, *, corner_angle_deg: float = 30.0,
                  max_points: int = 2_000_000, max_resolution: float = math.inf) -> DxfResult:
    """The model space's curves as arc chains.

    Parameters
    ----------
    data : bytes
        A DXF file (ASCII or binary; ezdxf's recovering reader).
    tolerance : float
        Two-sided band (drawing units) between each chain and its source curve.
    corner_angle_deg : float
        As in :func:`zwcore.arcs.fit_arcs`.
    max_points : int
        Most polyline vertices and spline samples in total.
    max_resolution : float
        Most total curve length over ``tolerance`` (the fit's work measure).

    Returns
    -------
    DxfResult
        One chain per curve entity (and per passed-through LINE/ARC/CIRCLE), in
        model-space order; entity counts by type; notes on what was skipped.

    Raises
    ------
    InvalidInputError
        Not a DXF, or no LWPOLYLINE, POLYLINE or SPLINE entity in the model space.
    LimitExceededError
        More than ``max_points`` vertices and samples, or ``max_resolution`` exceeded.
    """
    if not (isinstance(tolerance, int | float) and math.isfinite(tolerance) and tolerance > 0):
        raise InvalidInputError("tolerance", "must be a finite number > 0")
    doc = _read(data)
    counts: dict[str, int] = {}
    notes: list[str] = []
    chains: list[DxfChain] = []
    budget = _Budget(tolerance, max_points, max_resolution)
    entities = list(doc.modelspace())
    for e in entities:
        counts[e.dxftype()] = counts.get(e.dxftype(), 0) + 1
    if not any(counts.get(k) for k in _CURVES):
        found = ", ".join(f"{v} {k}" for k, v in sorted(counts.items())) or "no entities"
        raise InvalidInputError(
            "body", f"the drawing has no LWPOLYLINE, POLYLINE or SPLINE entity ({found})")
    for e in entities:
        kind = e.dxftype()
        if kind not in _CURVES and kind not in _PASS:
            continue
        try:
            chain = _entity_chain(e, tolerance, corner_angle_deg, budget, notes)
        except InvalidInputError as exc:
            if isinstance(exc, LimitExceededError):
                raise
            notes.append(f"{kind} {e.dxf.handle}: skipped ({exc.reason})")
            continue
        if chain is not None:
            chains.append(chain)

    if not any(c.fitted for c in chains):
        raise InvalidInputError("body", "no LWPOLYLINE, POLYLINE or SPLINE entity of the "
                                "drawing is a curve in the XY plane: " + "; ".join(notes[:5]))
    return DxfResult(tuple(chains), counts, tuple(notes))


@dataclass
class _Budget:
    """Work bounds checked before each fit: points, and length over tolerance."""

    tolerance: float
    max_points: int
    max_resolution: float
    points: int = 0
    length: float = 0.0

    def spend(self, pts: np.ndarray) -> None:
        if not (np.all(np.isfinite(pts)) and np.abs(pts).max(initial=0.0) <= MAX_COORDINATE):
            raise InvalidInputError("body", f"coordinates not finite or beyond {MAX_COORDINATE:g}")
        self.points += len(pts)
        self.length += float(np.hypot(*np.diff(pts, axis=0).T).sum()) if len(pts) > 1 else 0.0
        if self.points > self.max_points:
            raise LimitExceededError(
                "body", f"more than {self.max_points} polyline vertices and spline samples")
        if self.length / self.tolerance > self.max_resolution:
            raise LimitExceededError(
                "tolerance", f"curves of total length over {self.length:.6g} at tolerance "
                f"{self.tolerance:g} exceed {self.max_resolution:g}; use a larger tolerance")


def _entity_chain(e: Any, tol: float, corner: float, budget: _Budget, notes: list[str]
                  ) -> DxfChain | None:
    kind, handle, layer = e.dxftype(), str(e.dxf.handle), str(e.dxf.get("layer", "0"))
    if kind in _PASS:
        segs = _passed(e)
        if segs is None:
            notes.append(f"{kind} {handle}: not in the XY plane, skipped")
            return None
        pts = np.array([segs[0].start, segs[-1].end])
        seg = segs[0]
        numbers = [*seg.start, *seg.end, *(seg.center or ()), seg.radius or 0.0]
        if not all(math.isfinite(v) and abs(v) <= MAX_COORDINATE for v in numbers):
            raise InvalidInputError("body", f"coordinates not finite or beyond "
                                    f"{MAX_COORDINATE:g}")
        return DxfChain(kind, handle, layer, kind == "CIRCLE", segs, pts, False)
    if kind == "SPLINE":
        pts = _spline_points(e, tol, budget.max_points - budget.points)
        closed = bool(e.closed) or (len(pts) > 2 and math.hypot(*(pts[-1] - pts[0])) < 1e-12)
        if closed:
            pts = pts[:-1] if math.hypot(*(pts[-1] - pts[0])) < 1e-12 else pts
        budget.spend(pts)
        segs, dp, dc = _fit_open(pts, (1.0 - SPLINE_SHARE) * tol, corner, closed=closed)
        return DxfChain(kind, handle, layer, closed, segs, pts, True, dp, dc)
    got = _polyline_pieces(e)
    if got is None:
        notes.append(f"{kind} {handle}: a mesh or not in the XY plane, skipped")
        return None
    xy, bulges, closed = got
    budget.spend(xy if not closed else np.vstack([xy, xy[:1]]))
    segs, dp, dc = _polyline_chain(xy, bulges, closed, tol, corner)
    if not segs:
        notes.append(f"{kind} {handle}: fewer than two distinct vertices, skipped")
        return None
    return DxfChain(kind, handle, layer, closed, segs, xy, True, dp, dc)


def _arc_entity(msp: Any, seg: Segment, layer: str) -> None:
    assert seg.center is not None and seg.radius is not None and seg.sweep is not None
    cx, cy = seg.center
    if abs(abs(seg.sweep) - 2.0 * math.pi) < 1e-9:
        msp.add_circle((cx, cy), seg.radius, dxfattribs={"layer": layer})
        return
    a_start = math.degrees(math.atan2(seg.start[1] - cy, seg.start[0] - cx))
    a_end = math.degrees(math.atan2(seg.end[1] - cy, seg.end[0] - cx))
    if not seg.ccw:  # DXF arcs run counter-clockwise
        a_start, a_end = a_end, a_start
    msp.add_arc((cx, cy), seg.radius, a_start, a_end, dxfattribs={"layer": layer})


def chains_to_dxf(chains: Iterable[tuple[str, Sequence[Segment]]]) -> str:
    """A DXF (R2010, ASCII) of LINE and ARC entities.

    Parameters
    ----------
    chains : iterable of (layer, segments)
        Each chain's layer name and its segments.

    Returns
    -------
    str
        The DXF text (coordinates at full float precision).
    """
    import ezdxf

    doc = ezdxf.new("R2010")
    msp = doc.modelspace()
    for layer, segments in chains:
        if not doc.layers.has_entry(layer):
            doc.layers.add(layer)
        for seg in segments:
            if seg.kind == "line":
                msp.add_line(seg.start, seg.end, dxfattribs={"layer": layer})
            else:
                _arc_entity(msp, seg, layer)
    out = io.StringIO()
    doc.write(out)
    return out.getvalue()
