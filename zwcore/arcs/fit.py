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
   tangents (``LOOP_START_TURNS``) and the shortest valid chain is kept.
7. Verification: every piece is checked two-sided with conservative analytic
   bounds while fitting; the finished chain is measured densely
   (:mod:`zwcore.arcs.verify`), and a bridged chain that fails that measurement is
   refitted without bridges.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from zwcore.arcs._geometry import rotate
from zwcore.arcs._lines import Anchor, StraightRuns, refit_along_straight_runs
from zwcore.arcs._pieces import Piece
from zwcore.arcs._search import Fitter, Stuck
from zwcore.arcs._start import free_start
from zwcore.arcs.verify import densify, deviations
from zwcore.errors import InvalidInputError

FloatArray = NDArray[np.float64]

__all__ = ["ArcChain", "Segment", "chain_tangents", "fit_arcs", "segment_points"]

#: Turns (radians) of the start tangent tried for a corner-free closed curve.
LOOP_START_TURNS = (-0.015, 0.015, -0.03, 0.03, -0.05, 0.05, -0.07, 0.07)
#: Loops with more samples than this are fitted from one start tangent only (time).
LOOP_SWEEP_MAX_SAMPLES = 5_000

#: Default corner angle: turning sharper than this (over the tolerance scale) stays sharp.
DEFAULT_CORNER_ANGLE_DEG = 30.0
#: mm; a curve spanning less has no two points a machine tells apart: an error on
#: ``points``, whatever the tolerance (above it, merged points blame the tolerance)
MIN_CURVE_SPAN = 1e-6


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
# validation and preprocessing


def _validate(
    points: ArrayLike,
    tolerance: float,
    corner_angle_deg: float,
    max_radius: float | None,
) -> FloatArray:
    try:
        pts = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError("points", f"not a numeric (N, 2) array: {exc}") from None
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise InvalidInputError("points", f"expected shape (N, 2), got {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise InvalidInputError("points", "contains non-finite values")
    if not (isinstance(tolerance, int | float) and math.isfinite(tolerance) and tolerance > 0):
        raise InvalidInputError("tolerance", "must be a finite number > 0")
    if not (
        isinstance(corner_angle_deg, int | float)
        and math.isfinite(corner_angle_deg)
        and 0 < corner_angle_deg <= 180
    ):
        raise InvalidInputError("corner_angle_deg", "must be in (0, 180]")
    if max_radius is not None and not (
        isinstance(max_radius, int | float) and math.isfinite(max_radius) and max_radius > 0
    ):
        raise InvalidInputError("max_radius", "must be a finite number > 0 or null")
    return pts


def _dedupe(x: FloatArray, closed: bool, eps: float) -> FloatArray:
    """Drop points closer than ``eps`` to their kept predecessor (and a repeated closing point)."""
    keep = [0]
    last = x[0]
    d = np.hypot(*(np.diff(x, axis=0).T))
    if np.all(d > eps):
        out = x
    else:
        for i in range(1, len(x)):
            if math.hypot(x[i, 0] - last[0], x[i, 1] - last[1]) > eps:
                keep.append(i)
                last = x[i]
        out = x[keep]
    if closed:
        while len(out) > 1 and math.hypot(*(out[-1] - out[0])) <= eps:
            out = out[:-1]
    return out


def _interp_polyline(x: FloatArray, s: FloatArray, at: FloatArray) -> FloatArray:
    return np.stack([np.interp(at, s, x[:, 0]), np.interp(at, s, x[:, 1])], axis=1)


def _find_corners(x: FloatArray, closed: bool, tol: float, angle: float) -> list[int]:
    """Input indices where the curve turns by more than ``angle`` at the tolerance scale."""
    n = len(x)
    if n < 3 and not closed:
        return []
    d_probe = 3.0 * tol
    if closed:
        xx = np.vstack([x, x[:1]])
        seg = np.hypot(*(np.diff(xx, axis=0).T))
        total = float(seg.sum())
        s = np.concatenate([[0.0], np.cumsum(seg)])
        # three laps so that probes wrap around
        x3 = np.vstack([xx[:-1], xx[:-1], xx])
        s3 = np.concatenate([s[:-1] - total, s[:-1], s + total])
        si = s[:-1]
        before = _interp_polyline(x3, s3, si - min(d_probe, 0.25 * total))
        after = _interp_polyline(x3, s3, si + min(d_probe, 0.25 * total))
        idx = np.arange(n)
    else:
        seg = np.hypot(*(np.diff(x, axis=0).T))
        s = np.concatenate([[0.0], np.cumsum(seg)])
        si = s[1:-1]
        before = _interp_polyline(x, s, np.maximum(si - d_probe, 0.0))
        after = _interp_polyline(x, s, np.minimum(si + d_probe, s[-1]))
        idx = np.arange(1, n - 1)
    pc = x[idx]
    a = pc - before
    b = after - pc
    turn = np.abs(np.arctan2(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0], (a * b).sum(axis=1)))
    # a corner must also stand out of the chord between the probes by a visible amount
    # (half of what a corner of exactly `angle` shows at full probe length), so curves
    # that are small at the tolerance scale get no corners from their tiny wiggles
    chord = after - before
    clen = np.maximum(np.hypot(chord[:, 0], chord[:, 1]), 1e-300)
    height = np.abs(chord[:, 0] * a[:, 1] - chord[:, 1] * a[:, 0]) / clen
    hot = np.flatnonzero((turn > angle) & (height > 0.5 * d_probe * math.sin(0.5 * angle)))
    if hot.size == 0:
        return []
    # one corner per cluster of hot points (closer than two probe lengths): its sharpest point
    corners: list[int] = []
    start = 0
    for m in range(1, hot.size + 1):
        if m == hot.size or si[hot[m]] - si[hot[m - 1]] > 2.0 * d_probe:
            grp = hot[start:m]
            corners.append(int(idx[grp[np.argmax(turn[grp])]]))
            start = m
    if closed and len(corners) > 1:
        # the cluster may wrap around the start of the loop
        total = float(s[-1])
        first, last = corners[0], corners[-1]
        if total - si[last] + si[first] <= 2.0 * d_probe:
            keep = first if turn[first] >= turn[last] else last
            corners = [c for c in corners if c not in (first, last)] + [keep]
            corners.sort()
    return corners


# ---------------------------------------------------------------------------
# public entry point


def fit_arcs(
    points: ArrayLike,
    tolerance: float = 0.1,
    *,
    closed: bool = False,
    corner_angle_deg: float = DEFAULT_CORNER_ANGLE_DEG,
    max_radius: float | None = None,
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

    Returns
    -------
    ArcChain
        Segments in input coordinates with the two-sided deviations measured by
        dense sampling, the largest tangent kink at smooth junctions and the
        corner junctions.

    Raises
    ------
    InvalidInputError
        Bad ``points`` (shape, non-finite, fewer than two distinct), or an
        option out of range.
    """
    raw = _validate(points, tolerance, corner_angle_deg, max_radius)
    tol = float(tolerance)
    closed = bool(closed)
    if len(raw) < 2:
        raise InvalidInputError("points", "need at least two points")
    origin = raw[0].copy()
    # work relative to the first point so large coordinates keep their precision
    x = raw - origin
    # points a few ulps of the *absolute* coordinates apart are one point: arcs built
    # between them would not survive the shift back to input coordinates
    scale = max(float(np.abs(x).max()), float(np.abs(raw).max()))
    eps = max(1e-9 * tol, 1e-14 * scale)
    x_all = x
    x = _dedupe(x, closed, eps)
    if len(x) < 2:
        # A curve of measurable size merged only by the tolerance term: the tolerance
        # is what is out of scale, not the points.
        span = float(np.ptp(x_all, axis=0).max())
        if span >= MIN_CURVE_SPAN and len(_dedupe(x_all, closed, 1e-14 * scale)) >= 2:
            raise InvalidInputError(
                "tolerance", f"{tol:g} mm is too large for this curve: all its points lie "
                f"within {1e-9 * tol:g} mm (1e-9 tolerances) of each other")
        raise InvalidInputError("points", "fewer than two distinct points")
    corners_in = _find_corners(x, closed, tol, math.radians(corner_angle_deg))
    poly = np.vstack([x, x[:1]]) if closed else x
    # densify long polyline segments so junctions can sit between sparse input points
    seg = np.hypot(*(np.diff(poly, axis=0).T))
    nsub = np.maximum(np.ceil(seg / (6.0 * tol)).astype(np.int64), 1)
    samples = densify(poly, 6.0 * tol) if np.any(nsub > 1) else poly
    sample_of_input = np.concatenate([[0], np.cumsum(nsub)])
    m_last = len(samples) - 1
    cs = [int(sample_of_input[c]) for c in corners_in]
    # a closed curve with corners, whose first point is not one of them, wraps: the run
    # from the last corner round to the first one passes the first point with a smooth
    # junction there (the chain starts and ends at the first point)
    wrap = closed and bool(cs) and cs[0] != 0
    if closed and cs and not wrap:
        bounds = [*cs, m_last]
    elif closed and not cs:
        bounds = [0, m_last]
    else:
        bounds = [0, *cs, m_last]
    loop = closed and not cs

    def assemble(bridge: bool) -> tuple[list[Piece], list[int], list[int]]:
        def mk(work: float, anchors: list[Anchor]) -> Fitter:
            f = Fitter(samples, tol, work, max_radius)
            f.use_bridge = bridge
            if anchors:
                f.straight = StraightRuns(f.band, anchors)
            return f

        def fit_beam(
            a: int, b: int, t_start: FloatArray | None, anchors: list[Anchor]
        ) -> tuple[list[Piece], list[int]]:
            for work in (0.95, 0.8, 0.6, 0.4):
                try:
                    return mk(work, anchors).run(a, b, loop, allow_forced=False,
                                                 t_start=t_start)
                except Stuck:
                    continue
            # the beam with a filleted-polyline fallback wherever it is stuck: never fails
            return mk(0.9, anchors).run(a, b, loop, allow_forced=True, t_start=t_start)

        def fit_run(a: int, b: int, t_start: FloatArray | None) -> tuple[list[Piece], list[int]]:
            # arcs over straight runs (the tangent missed the run) are refitted with those
            # runs as anchors the chain follows with lines (zwcore.arcs._lines)
            return refit_along_straight_runs(
                lambda anchors: fit_beam(a, b, t_start, anchors), samples, a, b, tol,
                pin_start=t_start is None and not loop, pin_end=not loop,
                band=mk(0.95, []).band)

        n_runs = len(bounds) - 1
        results: list[tuple[list[Piece], list[int]] | None] = [None] * n_runs
        if wrap:
            last_run = fit_run(bounds[-2], bounds[-1], None)
            results[-1] = last_run
            results[0] = fit_run(bounds[0], bounds[1], last_run[0][-1].t_end)
        for r in range(n_runs):
            if results[r] is None:
                results[r] = fit_run(bounds[r], bounds[r + 1], None)
        pieces: list[Piece] = []
        corner_j: list[int] = []
        forced_j: list[int] = []
        for r, got in enumerate(results):
            assert got is not None
            run_pieces, run_forced = got
            base = len(pieces)
            forced_j.extend(-1 if f == -1 else base + f for f in run_forced)
            pieces.extend(run_pieces)
            if r < n_runs - 1 or (closed and cs and not wrap):
                corner_j.append(len(pieces) - 1)
        return pieces, corner_j, forced_j

    pieces, corner_j, forced_j = assemble(True)
    dev_p, dev_c = deviations(samples, pieces, tol)
    lim = tol * (1.0 + 1e-12)
    # (written so that a NaN figure counts as a failure: ``max`` would let it through)
    if not (dev_p <= lim and dev_c <= lim):
        # safety net: a bridged chain that the dense measurement rejects is refitted
        # without bridges (forced corners instead, never a tolerance violation)
        pieces, corner_j, forced_j = assemble(False)
        dev_p, dev_c = deviations(samples, pieces, tol)
    if loop and len(pieces) > 2 and m_last <= LOOP_SWEEP_MAX_SAMPLES:
        # The first point is a junction with a free tangent that the closing biarc must
        # meet again; the count depends on that tangent in a way no local rule predicts
        # (the closure lands at a good or a bad place), so a few separate fits from
        # turned start tangents are tried and the shortest valid chain is kept.
        fz = Fitter(samples, tol, 0.95, max_radius)
        t0, _ = free_start(fz.band, samples[0].copy(), 0, m_last)
        for d in LOOP_START_TURNS:
            tt = rotate(t0, d)
            try:
                alt, _ = Fitter(samples, tol, 0.95, max_radius).run(
                    0, m_last, True, allow_forced=False, t_start=tt)
            except Stuck:
                continue
            if len(alt) >= len(pieces):
                continue
            ap, ac = deviations(samples, alt, tol)
            if ap <= lim and ac <= lim:
                pieces, dev_p, dev_c = alt, ap, ac
                corner_j, forced_j = [], []
    n_seg = len(pieces)
    forced_j = [n_seg - 1 if f == -1 else f for f in forced_j]
    all_corners = sorted(set(corner_j) | set(forced_j))

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
