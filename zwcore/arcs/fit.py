"""C1 arc-and-line chains fitted to an ordered 2-D point curve (design section 5, seed 004).

Method (as built)
-----------------
1. Preprocessing: coordinates relative to the first point; repeated points
   dropped; real corners found (turning over ``corner_angle_deg`` measured over
   +-3 tolerances of arc length, standing out of the chord, one per cluster);
   long polyline segments densified to ``6 tol`` so junctions can sit between
   sparse input points. Corners split the curve into runs fitted separately.
2. Curvature-interval pieces (:mod:`zwcore.arcs._pieces`): a piece starts at a
   junction ``(P, T)`` and is one number, its signed curvature (0 = line). For a
   fixed ``(P, T)`` each sample admits an interval of curvatures; the running
   intersection (``cummax``/``cummin``) gives every feasible piece at once.
3. Beam look-ahead (:mod:`zwcore.arcs._search`): the chain grows level by level as a
   beam of junction states; candidate pieces (several ends, several curvatures in
   the interval) are ranked by how far the *next* piece reaches from their end
   state, and the best few verified ones survive. This keeps junctions mid-band
   with tangents along the curve, the cause of the seed's sequential failures.
3b. Straight runs (:mod:`zwcore.arcs._lines`): where the fitted chain of a run lays an
   arc over a straight run of the input -- a *flat* arc (sagitta below a quarter
   tolerance over at least 20 tolerances), or an arc whose samples (or half of them) a
   line keeps within half a tolerance over at least 150 tolerances -- the tangent
   entering the run missed it. The run is refitted with those straight runs (and those
   under long lines) as *anchors*: the beam also proposes the arc landing tangentially
   on the next anchor's line, a biarc landing on it where one arc does not fit, and
   from a state on an anchor's line the line to the tangent point of the fillet onto
   the next one; chains with fewer arcs over anchors rank and finish first. Anchors at
   a run's ends pass through its end point. Long lines are anchored on the run's
   least-squares line, else on their own line; a pinned end is also redone from the
   last few junctions (:func:`zwcore.arcs._start.shorter_ends`). The best refit is kept
   when it has fewer arcs over straight runs and at most one more segment per arc it
   removed.
3c. Runs fitted backwards (:func:`zwcore.arcs._runs.assemble`): a run between two
   corners of a closed curve is also fitted on the reversed samples (where its
   junctions fall depends on the direction the beam grows in); the backward chain
   replaces the run when it is shorter with no more flat arcs or arcs over straight
   runs.
4. Bridges: a state from which nothing verified can be placed tries a biarc onto
   a nearby sample with the polyline's direction (the second arc is verified
   with the true distance of its first sample).
5. Fallback: if the beam is still stuck (after retries at tighter working
   tolerances), a short stretch is covered by the polyline with tangent fillet
   arcs at its vertices (:mod:`zwcore.arcs._fallback`), joined C1 to the pieces on
   both sides; it is within the tolerance by construction, so the fit never
   fails and ``forced_corners`` stays empty (kept for API compatibility).
6. Closure: a closed curve without corners is one full circle if that fits,
   else closes with a biarc onto the start tangent (C1 at the seam), tried from
   any state within ``Fitter.CLOSE_SPAN`` single-piece reaches of the end. The
   count depends on the start tangent at the seam, so loops of up to
   ``LOOP_SWEEP_MAX_SAMPLES`` samples are also fitted from a few turned start
   tangents (``LOOP_START_TURNS``) and the shortest valid chain is kept; a turned fit
   is dropped as soon as its whole beam is ``LOOP_SWEEP_BEHIND`` pieces behind the
   first fit at the same sample.
6b. Seam ``"free"`` (closed curves only; the default ``"first_point"`` starts the chain
   at the first point): a closed curve with corners starts at its first corner (a
   smooth first point would be a junction the chain does not need) and each of its
   runs of more than one piece is also fitted backwards (the fewer pieces kept); a
   loop whose first fit closes with a short biarc is fitted again from other seams
   (``LOOP_SEAMS``) instead of the turned tangents, and the whole loop is also fitted
   reversed; the shortest valid chain is kept, returned in the input's direction, with
   where it starts (``seam_index``) and whether it was fitted reversed.
7. Verification: every piece is checked two-sided with conservative analytic
   bounds while fitting; the finished chain is measured densely
   (:mod:`zwcore.arcs.verify`), and a bridged chain that fails that measurement is
   refitted without bridges.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from zwcore.arcs._pieces import Piece
from zwcore.arcs._prepare import Prepared, prepare, validate
from zwcore.arcs._runs import (
    LOOP_SWEEP_MAX_SAMPLES,
    assemble,
    sweep_loop_seams,
    sweep_loop_start,
)
from zwcore.arcs.verify import deviations
from zwcore.errors import InvalidInputError

FloatArray = NDArray[np.float64]

__all__ = ["ArcChain", "Segment", "chain_tangents", "fit_arcs", "segment_points"]

#: Default corner angle: turning sharper than this (over the tolerance scale) stays sharp.
DEFAULT_CORNER_ANGLE_DEG = 30.0
#: Where a closed chain may start: at the first input point (the contract of design.md,
#: the default) or wherever fewer segments result (:func:`fit_arcs`, ``seam``).
SEAMS = ("first_point", "free")
Seam = Literal["first_point", "free"]


@dataclass(frozen=True)
class Segment:
    """One piece of a chain, in input coordinates (mm).

    ``sweep`` is signed (radians, ``> 0`` when ``ccw``); lines carry ``None`` in
    the arc-only fields.
    """

    kind: Literal["arc", "line"]
    start: tuple[float, float]
    end: tuple[float, float]
    center: tuple[float, float] | None = None
    radius: float | None = None
    ccw: bool | None = None
    sweep: float | None = None

    @property
    def length(self) -> float:
        """Arc length of the segment (mm)."""
        if self.kind == "line":
            return math.hypot(self.end[0] - self.start[0], self.end[1] - self.start[1])
        assert self.radius is not None and self.sweep is not None
        return abs(self.radius * self.sweep)

    def start_tangent(self) -> tuple[float, float]:
        """Unit tangent at the start."""
        return _tangent_at(self, self.start)

    def end_tangent(self) -> tuple[float, float]:
        """Unit tangent at the end."""
        return _tangent_at(self, self.end)


def _tangent_at(seg: Segment, pt: tuple[float, float]) -> tuple[float, float]:
    if seg.kind == "line":
        dx = seg.end[0] - seg.start[0]
        dy = seg.end[1] - seg.start[1]
        n = math.hypot(dx, dy)
        return (dx / n, dy / n) if n > 0 else (1.0, 0.0)
    assert seg.center is not None and seg.radius is not None
    rx = pt[0] - seg.center[0]
    ry = pt[1] - seg.center[1]
    n = math.hypot(rx, ry)
    if not n > 0.0:  # degenerate (radius below the coordinates' precision): no direction
        return (math.nan, math.nan)
    # ccw: tangent is the radius vector turned +90 degrees
    if seg.ccw:
        return (-ry / n, rx / n)
    return (ry / n, -rx / n)


@dataclass(frozen=True)
class ArcChain:
    """A fitted chain of arcs and lines.

    Junction ``i`` joins segment ``i`` to ``i + 1``; for closed chains junction
    ``len(segments) - 1`` joins the last segment to the first.
    """

    segments: tuple[Segment, ...]
    closed: bool
    corners: tuple[int, ...]
    max_deviation_points: float
    max_deviation_chain: float
    max_kink_smooth: float
    tolerance: float = 0.0
    forced_corners: tuple[int, ...] = field(default=())
    #: Index of the input point the chain starts at: 0 unless ``seam="free"`` moved the
    #: start of a closed chain; when it starts between two input points, the first of
    #: them (in the input's order; the start itself is ``segments[0].start``).
    seam_index: int = 0
    #: The chain was fitted to the reversed curve (``seam="free"``); it is returned in
    #: the input's direction all the same.
    seam_reversed: bool = False

    @property
    def n_arcs(self) -> int:
        """Number of arc segments."""
        return sum(1 for s in self.segments if s.kind == "arc")

    @property
    def n_lines(self) -> int:
        """Number of line segments."""
        return sum(1 for s in self.segments if s.kind == "line")

    @property
    def n_junctions(self) -> int:
        """Number of junctions (the closing one included for closed chains)."""
        n = len(self.segments)
        return n if self.closed else max(n - 1, 0)

    def kinks(self) -> FloatArray:
        """Tangent turn (radians, in [0, pi]) at every junction, ``(n_junctions,)``."""
        return chain_tangents(self.segments, self.closed)


def chain_tangents(segments: Sequence[Segment], closed: bool) -> FloatArray:
    """Tangent kink (radians) at each junction of ``segments``."""
    n = len(segments)
    m = n if closed else n - 1
    out = np.zeros(max(m, 0))
    for i in range(max(m, 0)):
        a = segments[i].end_tangent()
        b = segments[(i + 1) % n].start_tangent()
        out[i] = abs(math.atan2(a[0] * b[1] - a[1] * b[0], a[0] * b[0] + a[1] * b[1]))
    return out


def segment_points(seg: Segment, step: float) -> FloatArray:
    """Points ``(K, 2)`` along ``seg`` at spacing at most ``step``, both ends included."""
    n = max(math.ceil(seg.length / step), 1) + 1
    f = np.linspace(0.0, 1.0, n)
    s = np.array(seg.start)
    if seg.kind == "line":
        e = np.array(seg.end)
        return s[None, :] + f[:, None] * (e - s)[None, :]
    assert seg.center is not None and seg.radius is not None and seg.sweep is not None
    c = np.array(seg.center)
    a0 = math.atan2(s[1] - c[1], s[0] - c[0])
    ang = a0 + f * seg.sweep
    pts = c[None, :] + seg.radius * np.stack([np.cos(ang), np.sin(ang)], axis=1)
    pts[0] = s
    pts[-1] = seg.end
    return pts


# ---------------------------------------------------------------------------
# public entry point


def fit_arcs(
    points: ArrayLike,
    tolerance: float = 0.1,
    *,
    closed: bool = False,
    corner_angle_deg: float = DEFAULT_CORNER_ANGLE_DEG,
    max_radius: float | None = None,
    reserve: float = 0.0,
    seam: Seam = "first_point",
) -> ArcChain:
    """Fit a tangent-continuous chain of arcs and lines to an ordered point curve.

    Parameters
    ----------
    points : (N, 2) float64
        The curve, in order (mm). Consecutive repeated points are dropped; for
        ``closed`` a repeated closing point is dropped too. Points closer than
        ``1e-9 * tolerance`` (or 1e-14 of the coordinates' magnitude) count as
        repeats: they are the same point at any machine's resolution. N >= 2
        distinct.
    tolerance : float
        Two-sided band (mm): every point of the input polyline is within
        ``tolerance`` of the chain and every point of the chain within
        ``tolerance`` of the polyline.
    closed : bool
        Treat the points as a loop; the chain closes on itself (C1 at the closing
        junction unless the input has a corner there).
    corner_angle_deg : float
        Where the input turns by more than this (measured over +-3 tolerances of
        arc length, so noise does not count) the chain keeps a sharp corner at
        that input point; everywhere else it is C1.
    max_radius : float or None
        Arcs of larger radius are not used (such pieces are lines or shorter
        arcs); ``None`` means no cap (lines are still preferred whenever a line
        fits).
    reserve : float
        Part of ``tolerance`` kept free for what follows the fit, in ``[0,
        tolerance)``: the chain is fitted within ``tolerance - reserve`` (for a G-code
        program within ``tolerance``: :func:`zwcore.arcs.gcode.rounding_budget`).
    seam : {"first_point", "free"}
        Where a closed chain starts. ``"first_point"``: at the first input point.
        ``"free"``: where fewer segments result (a closed curve with corners at its
        first corner, a loop possibly at another point of the input polyline, fitted
        in either direction); the chain still runs in the input's direction and
        ``seam_index`` / ``seam_reversed`` say where it starts and how it was fitted.
        Ignored for open curves.

    Returns
    -------
    ArcChain
        Segments in input coordinates with the two-sided deviations measured by
        dense sampling, the largest tangent kink at smooth junctions and the corner
        junctions (its ``tolerance`` is the one fitted to, ``tolerance - reserve``).

    Raises
    ------
    InvalidInputError
        Bad ``points`` (shape, non-finite, fewer than two distinct), or an
        option out of range.
    """
    raw = validate(points, tolerance, corner_angle_deg, max_radius)
    if not (isinstance(reserve, int | float) and 0.0 <= reserve < tolerance):
        raise InvalidInputError(
            "tolerance", f"must exceed the reserve {reserve:g} mm (the G-code rounding)")
    if seam not in SEAMS:
        raise InvalidInputError("seam", f"must be one of {', '.join(SEAMS)}")
    tol = float(tolerance) - float(reserve)
    closed = bool(closed)
    if closed and seam == "free":
        return _fit_free(raw, tol, corner_angle_deg, max_radius)
    return _fit(raw, tol, closed, corner_angle_deg, max_radius, False)[0]


def _fit_free(
    raw: FloatArray, tol: float, corner_angle_deg: float, max_radius: float | None
) -> ArcChain:
    """The closed chain of ``raw`` ``(N, 2)`` with ``seam="free"``: where it starts and
    whether it was fitted reversed filled in."""
    chain, loop = _fit(raw, tol, True, corner_angle_deg, max_radius, True)
    rev = False
    if loop:
        # a loop's count depends on its direction as on its seam: fitted reversed too
        # (the runs of a curve with corners were each fitted both ways in _fit), from
        # the same first point (the reversed fit starts where the forward one did)
        back_raw = np.ascontiguousarray(np.roll(raw[::-1], 1, axis=0))
        back, _ = _fit(back_raw, tol, True, corner_angle_deg, max_radius, True)
        if len(back.segments) < len(chain.segments):
            chain, rev = _reversed(back), True
    return replace(chain, seam_index=_seam_index(raw, chain.segments[0].start),
                   seam_reversed=rev)


def _fit(
    raw: FloatArray, tol: float, closed: bool, corner_angle_deg: float,
    max_radius: float | None, free: bool,
) -> tuple[ArcChain, bool]:
    """The chain of ``raw`` ``(N, 2)`` at ``tol`` (steps 1-7) and whether it is a loop
    fitted from more than one start (not a closed form, at most
    ``LOOP_SWEEP_MAX_SAMPLES`` samples). ``free``: seam ``"free"`` (a closed curve with
    corners from its first corner, each of its runs fitted both ways; a loop's second
    fits from other seams)."""
    prep = _prepared(raw, tol, closed, corner_angle_deg, free)
    samples = prep.samples
    pieces, corner_j, forced_j, closed_form = assemble(prep, max_radius, True, free)
    dev_p, dev_c = deviations(samples, pieces, tol)
    lim = tol * (1.0 + 1e-12)
    # (written so that a NaN figure counts as a failure: ``max`` would let it through)
    if not (dev_p <= lim and dev_c <= lim):
        # safety net: a bridged chain that the dense measurement rejects is refitted
        # without bridges (forced corners instead, never a tolerance violation)
        pieces, corner_j, forced_j, closed_form = assemble(prep, max_radius, False, free)
        dev_p, dev_c = deviations(samples, pieces, tol)
    # (a closed-form loop, a filleted polygon, has no start tangent to sweep)
    sweep = (prep.loop and not closed_form and len(pieces) > 2
             and prep.m_last <= LOOP_SWEEP_MAX_SAMPLES)
    if sweep:
        if free:
            seamed = sweep_loop_seams(prep, max_radius, pieces, lim)
            if seamed is not None:
                pieces, dev_p, dev_c, _s = seamed
                corner_j, forced_j = [], []
        else:
            swept = sweep_loop_start(prep, max_radius, pieces, lim)
            if swept is not None:
                pieces, dev_p, dev_c = swept
                corner_j, forced_j = [], []
    n_seg = len(pieces)
    forced_j = [n_seg - 1 if f == -1 else f for f in forced_j]
    all_corners = sorted(set(corner_j) | set(forced_j))
    chain = _chain_of(pieces, prep.origin, closed, all_corners, forced_j, dev_p, dev_c, tol)
    return chain, sweep


def _prepared(
    raw: FloatArray, tol: float, closed: bool, corner_angle_deg: float, free: bool
) -> Prepared:
    """:func:`prepare` of ``raw`` ``(N, 2)``; with ``free``, a closed curve with corners
    from its first corner on (a junction at a smooth first point costs the two runs
    meeting there a short piece each: 1-4 segments a glyph row, 21 on noisy 0.01)."""
    prep = prepare(raw, tol, closed, corner_angle_deg)
    if not (free and prep.wrap):
        return prep
    # (the corner's sample is an input point)
    at = prep.samples[prep.cs[0]] + prep.origin
    i = int(np.argmin(np.hypot(raw[:, 0] - at[0], raw[:, 1] - at[1])))
    return prepare(np.roll(raw, -i, axis=0), tol, closed, corner_angle_deg)


def _seam_index(raw: FloatArray, start: tuple[float, float]) -> int:
    """Index of the input point ``raw`` ``(N, 2)`` (a closed curve) where a chain
    starting at ``start`` (a point of the closed polyline) starts: that point, else the
    first point of the polyline segment it lies on (the nearest)."""
    p = np.asarray(start)
    b = np.roll(raw, -1, axis=0)
    d = b - raw
    dd = np.einsum("ij,ij->i", d, d)
    f = np.clip(np.einsum("ij,ij->i", p - raw, d) / np.where(dd > 0.0, dd, 1.0), 0.0, 1.0)
    gap = np.hypot(*(raw + f[:, None] * d - p).T)
    # (the nearest point first: a start at a point is also the end of the segment before)
    at = np.hypot(*(raw - p).T)
    i = int(np.argmin(at))
    scale = max(float(np.abs(raw).max()), 1.0)
    return i if at[i] <= max(float(gap.min()), 1e-9 * scale) else int(np.argmin(gap))


def _reversed(chain: ArcChain) -> ArcChain:
    """The closed ``chain`` run the other way round, from the same start: segments in
    reverse order, each reversed; junction ``i`` becomes ``n - 2 - i`` (mod ``n``)."""
    n = len(chain.segments)
    segs = tuple(
        Segment(s.kind, s.end, s.start, s.center, s.radius,
                None if s.ccw is None else not s.ccw, None if s.sweep is None else -s.sweep)
        for s in reversed(chain.segments))
    return replace(
        chain, segments=segs,
        corners=tuple(sorted((n - 2 - c) % n for c in chain.corners)),
        forced_corners=tuple(sorted((n - 2 - c) % n for c in chain.forced_corners)))


def _chain_of(
    pieces: list[Piece], origin: FloatArray, closed: bool, all_corners: list[int],
    forced_j: list[int], dev_p: float, dev_c: float, tol: float,
) -> ArcChain:
    """The :class:`ArcChain` of the fitted pieces (local frame about ``origin``)."""
    segments = tuple(_to_segment(pc, origin) for pc in pieces)
    if closed:
        # the loop closes exactly on its first point
        last = segments[-1]
        segments = (*segments[:-1], _replace_end(last, segments[0].start))
    kinks = chain_tangents(segments, closed)
    if not (math.isfinite(dev_p) and math.isfinite(dev_c) and np.all(np.isfinite(kinks))):
        # only curves at the precision limit of their coordinates get here
        raise InvalidInputError(
            "points", "curve too small for its coordinates' precision at this tolerance")
    smooth = np.ones(len(kinks), dtype=bool)
    for c in all_corners:
        if 0 <= c < len(kinks):
            smooth[c] = False
    max_kink = float(kinks[smooth].max()) if np.any(smooth) else 0.0
    return ArcChain(
        segments=segments,
        closed=closed,
        corners=tuple(all_corners),
        max_deviation_points=dev_p,
        max_deviation_chain=dev_c,
        max_kink_smooth=max_kink,
        tolerance=tol,
        forced_corners=tuple(sorted(set(forced_j))),
    )


def _replace_end(seg: Segment, end: tuple[float, float]) -> Segment:
    return Segment(seg.kind, seg.start, end, seg.center, seg.radius, seg.ccw, seg.sweep)


def _to_segment(pc: Piece, origin: FloatArray) -> Segment:
    start = (float(pc.p[0] + origin[0]), float(pc.p[1] + origin[1]))
    end = (float(pc.end[0] + origin[0]), float(pc.end[1] + origin[1]))
    if pc.kappa == 0.0:
        return Segment("line", start, end)
    n = np.array([-pc.t[1], pc.t[0]])
    c = pc.p + n / pc.kappa
    return Segment(
        "arc",
        start,
        end,
        center=(float(c[0] + origin[0]), float(c[1] + origin[1])),
        radius=float(1.0 / abs(pc.kappa)),
        ccw=bool(pc.kappa > 0),
        sweep=float(pc.kappa * pc.length),
    )
