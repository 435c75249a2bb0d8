"""Signed tool offset of an arc chain (the cutter-centre path of a C1 chain).

Sign convention: ``distance > 0`` offsets to the LEFT of the travel direction
(G41 side), ``distance < 0`` to the right (G42 side). With tangent-continuous
pieces the offset is exact and cheap: a line moves along its normal, an arc
keeps its centre and changes its radius (``r - d`` for counter-clockwise arcs,
``r + d`` for clockwise ones), so smooth junctions stay smooth.

Degenerate arcs: where ``r - d`` (ccw) or ``r + d`` (cw) is ``<= 0`` the tool is
larger than the arc allows, the offset arc vanishes or turns inside out. Those
arcs are reported by index (in the input chain) and replaced by a straight
connector between their offset end points; the junctions around a connector are
reported as corners of the offset chain, so the caller sees that the path is no
longer a clean offset there (choose a smaller tool, or re-fit with a larger
corner radius).

Reversed segments: at an inner corner the two offset pieces are trimmed at their
intersection; when the offset is larger than a piece allows, that intersection
lies beyond the piece's other end and the trimmed piece would run backwards (a
line whose direction flips, an arc whose trimmed sweep wraps the other way round).
The chain is still returned, but such pieces are reported by index (in the input
chain), like vanished arcs: the path gouges there.

Sharp corners of the input: on the outside of a corner the offset pieces do
not meet and a rounding arc of radius ``|distance|`` about the corner point
joins them tangentially (as NC cutter compensation does); on the inside they
overlap and are trimmed at their intersection (a sharp corner of the offset).

Limits: trimming is local only (neighbouring pieces at a corner). There is no
global self-intersection removal: where the offset distance exceeds the local
"width" of the curve (a narrow neck, a hairpin narrower than ``2 |distance|``, a
concave pocket smaller than the tool) the offset path can cross itself or cut
through other parts of the chain, and loops formed that way are not removed.
The result is then not a valid cutter path; callers must check for
self-intersections or use a tool small enough for the part's features.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from zwcore.arcs.fit import ArcChain, Segment, chain_tangents
from zwcore.errors import InvalidInputError

__all__ = ["OffsetResult", "offset_chain"]


class OffsetResult(NamedTuple):
    """What :func:`offset_chain` returns (a tuple: ``chain, vanished, reversed``)."""

    #: the offset chain
    chain: ArcChain
    #: indices (input chain) of arcs whose offset radius would be zero or negative
    vanished: tuple[int, ...]
    #: indices (input chain) of segments whose trimmed offset runs backwards
    reversed: tuple[int, ...]

_Pt = tuple[float, float]


def _arc_from(center: _Pt, radius: float, start: _Pt, end: _Pt, ccw: bool, sweep_hint: float
              ) -> Segment:
    a0 = math.atan2(start[1] - center[1], start[0] - center[0])
    a1 = math.atan2(end[1] - center[1], end[0] - center[0])
    sw = a1 - a0
    if ccw:
        sw = sw % (2 * math.pi)
    else:
        sw = -((-sw) % (2 * math.pi))
    if abs(sweep_hint) > math.pi and abs(sw) < 1e-9:
        sw = math.copysign(2 * math.pi, sweep_hint)  # full circle
    return Segment("arc", start, end, center, radius, ccw, sw)


def _offset_segment(seg: Segment, d: float) -> tuple[Segment | None, _Pt, _Pt]:
    """Offset one segment; ``None`` when an arc vanishes. Also its offset end points."""
    ts = seg.start_tangent()
    te = seg.end_tangent()
    s = (seg.start[0] - d * ts[1], seg.start[1] + d * ts[0])
    e = (seg.end[0] - d * te[1], seg.end[1] + d * te[0])
    if seg.kind == "line":
        return Segment("line", s, e), s, e
    assert seg.radius is not None and seg.center is not None and seg.sweep is not None
    r = seg.radius - d if seg.ccw else seg.radius + d
    if r <= 1e-12 * max(seg.radius, abs(d)):
        return None, s, e
    return Segment("arc", s, e, seg.center, r, seg.ccw, seg.sweep), s, e


def _intersections(a: Segment, b: Segment) -> list[_Pt]:
    """Intersection points of the supporting line/circle of ``a`` and ``b``."""

    def circle(seg: Segment) -> tuple[np.ndarray, float] | None:
        if seg.kind == "line" or seg.center is None or seg.radius is None:
            return None
        return np.array(seg.center), seg.radius

    ca, cb = circle(a), circle(b)
    out: list[_Pt] = []
    if ca is None and cb is None:
        p, r = np.array(a.start), np.array(a.end) - np.array(a.start)
        q, s = np.array(b.start), np.array(b.end) - np.array(b.start)
        den = r[0] * s[1] - r[1] * s[0]
        if abs(den) > 1e-15:
            t = ((q[0] - p[0]) * s[1] - (q[1] - p[1]) * s[0]) / den
            x = p + t * r
            out.append((float(x[0]), float(x[1])))
        return out
    if ca is None or cb is None:
        line, circ = (a, cb) if ca is None else (b, ca)
        assert circ is not None
        c, rad = circ
        p = np.array(line.start)
        dvec = np.array(line.end) - p
        dd = float(dvec @ dvec)
        if dd == 0:
            return out
        f = p - c
        bq = float(f @ dvec)
        disc = bq * bq - dd * (float(f @ f) - rad * rad)
        if disc < 0:
            return out
        for sg in (-1.0, 1.0):
            t = (-bq + sg * math.sqrt(disc)) / dd
            x = p + t * dvec
            out.append((float(x[0]), float(x[1])))
        return out
    (c1, r1), (c2, r2) = ca, cb
    dv = c2 - c1
    dist = float(np.hypot(*dv))
    if dist == 0 or dist > r1 + r2 or dist < abs(r1 - r2):
        return out
    aa = (r1 * r1 - r2 * r2 + dist * dist) / (2 * dist)
    h = math.sqrt(max(r1 * r1 - aa * aa, 0.0))
    m = c1 + aa * dv / dist
    n = np.array([-dv[1], dv[0]]) / dist
    for sg in (-1.0, 1.0):
        x = m + sg * h * n
        out.append((float(x[0]), float(x[1])))
    return out


def _with_end(seg: Segment, end: _Pt) -> Segment:
    if seg.kind == "line":
        return Segment("line", seg.start, end)
    assert seg.center is not None and seg.radius is not None and seg.sweep is not None
    return _arc_from(seg.center, seg.radius, seg.start, end, bool(seg.ccw), 0.0)


def _with_start(seg: Segment, start: _Pt) -> Segment:
    if seg.kind == "line":
        return Segment("line", start, seg.end)
    assert seg.center is not None and seg.radius is not None and seg.sweep is not None
    return _arc_from(seg.center, seg.radius, start, seg.end, bool(seg.ccw), 0.0)


def offset_chain(chain: ArcChain, distance: float) -> OffsetResult:
    """Offset a chain by a signed ``distance`` (mm; ``> 0`` = left of travel).

    Parameters
    ----------
    chain : ArcChain
        The chain to offset (typically the part contour from ``fit_arcs``).
    distance : float
        Signed offset, e.g. ``+R`` for a tool of radius ``R`` on the left.

    Returns
    -------
    OffsetResult
        ``(chain, vanished, reversed)``:
    chain : ArcChain
        The offset chain. Its ``corners`` are the junctions that are not C1:
        trimmed inner corners and the ends of connectors that replace vanished
        arcs; outer corners are rounded and therefore smooth. Deviation fields
        are 0 (the offset is exact, not fitted), ``max_kink_smooth`` is measured.
    vanished : tuple of int
        Indices (into ``chain.segments``) of arcs whose offset radius would be
        zero or negative; each is replaced by a straight connector.
    reversed : tuple of int
        Indices (into ``chain.segments``) of segments whose offset, trimmed at an
        inner corner, runs backwards: a line whose offset direction is opposite to
        its own (or that shrank to nothing), an arc whose trimmed offset sweeps the
        other way or further than its untrimmed offset. The path gouges there.

    Raises
    ------
    InvalidInputError
        ``distance`` not finite.
    """
    if not (isinstance(distance, int | float) and math.isfinite(distance)):
        raise InvalidInputError("offset", "must be a finite number (mm)")
    d = float(distance)
    segs = chain.segments
    n = len(segs)
    if d == 0.0 or n == 0:
        return OffsetResult(chain, (), ())
    out, kinds, vanished = _offset_all(segs, d)
    result, rkinds, rsrc = _join_corners(chain, out, kinds, d)
    m = len(result)
    mj = m if chain.closed else m - 1
    kinks = chain_tangents(result, chain.closed)
    corners: list[int] = []
    for jn in range(mj):
        a_k, b_k = rkinds[jn], rkinds[(jn + 1) % m]
        if "conn" in (a_k, b_k) or kinks[jn] > 1e-6:
            corners.append(jn)
    smooth = [kinks[jn] for jn in range(mj) if jn not in corners]
    off_chain = ArcChain(
        segments=tuple(result),
        closed=chain.closed,
        corners=tuple(corners),
        max_deviation_points=0.0,
        max_deviation_chain=0.0,
        max_kink_smooth=float(max(smooth)) if smooth else 0.0,
        tolerance=chain.tolerance,
    )
    reversed_: list[int] = []
    for seg, kind, i in zip(result, rkinds, rsrc, strict=True):
        if kind == "seg" and _runs_backwards(seg, segs[i], out[i]):
            reversed_.append(i)
    return OffsetResult(off_chain, tuple(vanished), tuple(sorted(set(reversed_))))


def _offset_all(segs: tuple[Segment, ...], d: float) -> tuple[list[Segment], list[str], list[int]]:
    """Every segment offset: the segments (a vanished arc's straight connector in its
    place), their kinds (``"seg"``, ``"conn"``) and the vanished arcs' indices."""
    out: list[Segment] = []
    kinds: list[str] = []
    vanished: list[int] = []
    for i, seg in enumerate(segs):
        off, s, e = _offset_segment(seg, d)
        if off is None:
            vanished.append(i)
            out.append(Segment("line", s, e))
            kinds.append("conn")
        else:
            out.append(off)
            kinds.append("seg")
    return out, kinds, vanished


def _join_corners(
    chain: ArcChain, out: list[Segment], kinds: list[str], d: float
) -> tuple[list[Segment], list[str], list[int]]:
    """The offset segments ``out`` joined at the input's corners: the outside rounded,
    the inside trimmed. Returns the segments, their kinds (``"seg"``, ``"conn"``,
    ``"round"``) and their input segment (-1: rounding arc or connector)."""
    segs = chain.segments
    n = len(segs)
    corner_set = set(chain.corners)
    result: list[Segment] = []
    rkinds: list[str] = []
    rsrc: list[int] = []
    n_j = n if chain.closed else n - 1
    pending_start: dict[int, _Pt] = {}
    for i in range(n):
        cur = out[i]
        if i in pending_start:
            cur = _with_start(cur, pending_start.pop(i))
        result.append(cur)
        rkinds.append(kinds[i])
        rsrc.append(i)
        if i >= n_j or i not in corner_set:
            continue
        nxt_i = (i + 1) % n
        a_end = cur.end
        b_start = out[nxt_i].start
        if math.hypot(a_end[0] - b_start[0], a_end[1] - b_start[1]) <= 1e-12 * max(1.0, abs(d)):
            continue
        ta = segs[i].end_tangent()
        tb = segs[nxt_i].start_tangent()
        turn = ta[0] * tb[1] - ta[1] * tb[0]
        # offset to the left and the path turning right (or vice versa): outer corner
        if (turn < 0) == (d > 0):
            result.append(_arc_from(segs[i].end, abs(d), a_end, b_start, d < 0, 0.0))
            rkinds.append("round")
            rsrc.append(-1)
            continue
        cands = _intersections(cur, out[nxt_i])
        if cands:
            x = min(cands, key=lambda q: math.hypot(q[0] - a_end[0], q[1] - a_end[1])
                    + math.hypot(q[0] - b_start[0], q[1] - b_start[1]))
            result[-1] = _with_end(cur, x)
            if nxt_i == 0:
                result[0] = _with_start(result[0], x)
            else:
                pending_start[nxt_i] = x
        else:
            result.append(Segment("line", a_end, b_start))
            rkinds.append("conn")
            rsrc.append(-1)
    if chain.closed and result:
        # the first segment may have been trimmed at its start after the loop went round
        last = result[-1]
        if last.end != result[0].start:
            result[-1] = _with_end(last, result[0].start)
    return result, rkinds, rsrc


def _runs_backwards(seg: Segment, orig: Segment, untrimmed: Segment) -> bool:
    """True when the trimmed offset ``seg`` of ``orig`` runs against it (see
    :func:`offset_chain`); ``untrimmed`` is the offset before trimming."""
    if seg.kind == "line":
        ox, oy = orig.end[0] - orig.start[0], orig.end[1] - orig.start[1]
        dx, dy = seg.end[0] - seg.start[0], seg.end[1] - seg.start[1]
        return dx * ox + dy * oy <= 0.0
    assert seg.sweep is not None and untrimmed.sweep is not None
    slack = 1e-9 * max(1.0, abs(untrimmed.sweep))
    return (seg.sweep > 0) != (untrimmed.sweep > 0) or abs(seg.sweep) > abs(untrimmed.sweep) + slack
