"""Straight runs of the input under a fitted chain: *flat* arcs, the maximal straight run
grown from a piece's samples, and the anchors (lines) a refit follows
(:mod:`zwcore.arcs._lines`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import NDArray

from zwcore.arcs._geometry import line_fit, sagitta1
from zwcore.arcs._kernels import line_spread
from zwcore.arcs._pieces import Piece

FloatArray = NDArray[np.float64]

__all__ = [
    "FLAT_MIN_LEN",
    "STRAIGHT_MIN_LEN",
    "Anchor",
    "anchors_of",
    "arcs_over_straight",
    "is_flat",
    "pinned_shorter",
    "straight_run",
]

# ---------------------------------------------------------------------------
# flat arcs and the straight runs under them (line anchors)

#: an arc at least :data:`FLAT_MIN_LEN` tolerances long whose sagitta is below this
#: share of the tolerance is *flat*: its chord, a line, is within a quarter tolerance of
#: it, so the input there is a straight run the chain should follow with a line
FLAT_SAGITTA = 0.25
FLAT_MIN_LEN = 20.0
#: a straight run keeps all its samples within this share of ``tol`` of one line
#: (the rest of the band is left for the pieces joining it) ...
STRAIGHT_BAND = 0.5
#: ... over at least this many tolerances (15 mm at 0.1 mm): a circle stays that
#: straight only above a radius of ``L^2 / (16 * 0.5 tol)`` = 2800 tolerances, and a
#: sine's inflection (amplitude 10, wavelength 50: 12 mm) is not a straight run
STRAIGHT_MIN_LEN = 150.0
#: a straight run at the start or end of a fitted run is followed by the line through
#: that end sample (the chain passes through it), which carries the sample's noise:
#: that line keeps the run's samples within this share of ``tol``
PINNED_BAND = 0.75
#: shares of :data:`PINNED_BAND` a shorter pinned run keeps (:func:`pinned_shorter`):
#: on NACA 2412 sampled at 0.1-0.3 mm, at 0.05, no arc landed on a line through the
#: trailing edge that left the samples more than 0.2 tol (share 0.25); the first
#: landing came at 0.064-0.11 tol
PINNED_SHRINK = (0.125, 0.0625, 0.03125)


def is_flat(kappa: float, length: float, tol: float) -> bool:
    """True for an arc of ``length`` >= :data:`FLAT_MIN_LEN` tolerances whose sagitta is
    below :data:`FLAT_SAGITTA` tolerances (a line where the tangent missed the run)."""
    return (
        kappa != 0.0
        and length >= FLAT_MIN_LEN * tol
        and sagitta1(kappa, length) < FLAT_SAGITTA * tol
    )


@dataclass
class Anchor:
    """A straight run of the samples: ``i0..i1`` lie within :data:`STRAIGHT_BAND`
    tolerances of the line through ``q`` with unit direction ``d`` (along the travel)."""

    i0: int
    i1: int
    q: FloatArray
    d: FloatArray


@njit(cache=True, nogil=True, error_model="numpy")
def _straight(samples: FloatArray, i0: int, i1: int, band: float) -> bool:
    """Samples ``i0..i1`` lie within ``band`` of their least-squares line."""
    return i1 - i0 < 2 or line_spread(samples, i0, i1, False, 0.0, 0.0) <= band


@njit(cache=True, nogil=True, error_model="numpy")
def _grow(samples: FloatArray, fixed: int, moving: int, limit: int, sgn: int,
          band: float) -> int:
    """The straight run ``fixed..moving`` grown at its ``moving`` end towards ``limit``
    (``sgn``: the direction) by galloping, then bisection: its new end."""
    good, step = moving, max(1, abs(moving - fixed) // 4)
    while good != limit:
        cand = good + sgn * step
        cand = min(cand, limit) if sgn > 0 else max(cand, limit)
        ok = _straight(samples, fixed, cand, band) if sgn > 0 else _straight(
            samples, cand, fixed, band)
        if ok:
            good = cand
            step *= 2
            continue
        lo, hi = good, cand  # lo straight, hi not
        while abs(hi - lo) > 1:
            mid = (lo + hi) // 2
            if (_straight(samples, fixed, mid, band) if sgn > 0
                    else _straight(samples, mid, fixed, band)):
                lo = mid
            else:
                hi = mid
        return lo
    return good


@njit(cache=True, nogil=True, error_model="numpy")
def straight_span(samples: FloatArray, k: int, j: int, a: int, b: int,
                  band: float) -> tuple[int, int]:
    """The first and last sample of the maximal straight run (samples within ``band`` of
    their least-squares line, within ``a..b``) grown from samples ``k..j``, else from
    their last, first or middle half; ``(-1, -1)`` when none of these is straight. One
    compiled call for the whole gallop and bisection (dozens of line fits), which cost
    a kernel call each from Python."""
    q4 = (j - k) // 4
    found = False
    for kk, jj in ((k, j), (k + 2 * q4, j), (k, j - 2 * q4), (k + q4, j - q4)):
        if jj - kk >= 2 and _straight(samples, kk, jj, band):
            k, j = kk, jj
            found = True
            break
    if not found:
        return -1, -1
    i1 = _grow(samples, k, j, b, 1, band)
    i0 = _grow(samples, i1, k, a, -1, band)
    return i0, i1


def straight_run(
    samples: FloatArray, k: int, j: int, a: int, b: int, tol: float, pin_start: bool,
    pin_end: bool,
) -> Anchor | None:
    """The maximal straight run (within ``a..b``) grown from samples ``k..j`` (or from
    their first, last or middle half), or None when none of these is straight (see
    :data:`STRAIGHT_BAND`).

    Grown both ways by galloping and bisection. ``pin_start``/``pin_end``: a run that
    reaches sample ``a``/``b`` gets the line through that sample (the chain must
    start/end exactly there, on the line), if that line still keeps the band.
    """
    i0, i1 = straight_span(samples, k, j, a, b, STRAIGHT_BAND * tol)
    if i0 < 0:
        return None
    q, d, _ = line_fit(samples[i0 : i1 + 1])
    for pin, flag in ((a, pin_start and i0 == a), (b, pin_end and i1 == b)):
        if not flag:
            continue

        # the longest part of the run from the pinned end that a line through it keeps
        far = _pinned_part(samples, pin, i1 if pin == a else i0, PINNED_BAND * tol)
        if abs(far - pin) >= 2:
            lo, hi = (pin, far) if pin == a else (far, pin)
            i0, i1 = lo, hi
            q = samples[pin].copy()
            d = line_fit(samples[lo : hi + 1], q)[1]
            break
    return Anchor(i0, i1, q, d)


def _pinned_part(samples: FloatArray, pin: int, far: int, band: float) -> int:
    """The sample nearest ``far`` (towards the pinned sample ``pin``) up to which the
    line through ``pin`` keeps every sample between them within ``band`` (bisection)."""

    def ok(m: int) -> bool:
        lo, hi = (pin, m) if pin < far else (m, pin)
        return hi - lo < 2 or line_spread(
            samples, lo, hi, True, samples[pin, 0], samples[pin, 1]) <= band

    if ok(far):
        return far
    good, bad = pin, far
    while abs(bad - good) > 1:
        mid = (good + bad) // 2
        if ok(mid):
            good = mid
        else:
            bad = mid
    return good


def pinned_shorter(an: Anchor, samples: FloatArray, a: int, b: int,
                   tol: float) -> list[Anchor]:
    """Shorter runs from the pinned end of the straight run ``an`` (its line passes through
    sample ``a`` or ``b``), longest first: the parts the line through that sample keeps
    within :data:`PINNED_SHRINK` shares of :data:`PINNED_BAND` tolerances.

    A straight run that bows a little (the rear of an airfoil: radius 7,000 mm over
    40 mm at 0.05 mm) is straight to :data:`STRAIGHT_BAND`, but the line through its end
    sample leaves the samples at its far end most of the band: no arc lands on it there,
    and the chain keeps a flat arc to the end. A shorter run from the pin hugs the
    samples, and the arc before it can land (one segment more than the flat arc). Runs
    of fewer than three samples are not returned.
    """
    pins = [pin for pin in (a, b) if (an.i0 == pin or an.i1 == pin)
            and np.array_equal(an.q, samples[pin])]
    if len(pins) != 1:
        return []
    pin = pins[0]
    far = an.i1 if pin == an.i0 else an.i0
    out: list[Anchor] = []
    for share in PINNED_SHRINK:
        m = _pinned_part(samples, pin, far, share * PINNED_BAND * tol)
        if abs(m - pin) < 2:
            break
        far = m
        lo, hi = (pin, m) if pin < m else (m, pin)
        if hi - lo < an.i1 - an.i0 and not (out and out[-1].i0 == lo and out[-1].i1 == hi):
            q = samples[pin].copy()
            out.append(Anchor(lo, hi, q, line_fit(samples[lo : hi + 1], q)[1]))
    return out


# ---------------------------------------------------------------------------
# finding the arcs over straight runs in a fitted run, and refitting it


def arcs_over_straight(
    pieces: Sequence[Piece], samples: FloatArray, a: int, b: int, tol: float, *,
    pin_start: bool, pin_end: bool, cum: FloatArray | None = None,
) -> dict[int, Anchor]:
    """The arcs of a run's chain that lie over a straight run of the input, with it.

    An arc is over a straight run when it is flat (:func:`is_flat`) or when its samples
    (or their first, last or middle half) lie within the straight band of a line that
    grows to a run of at least :data:`STRAIGHT_MIN_LEN` tolerances, more than half of
    which the arc covers (a fillet whose end lies in the run's band lands on it).
    ``cum``: the polyline's length at each sample, when known (else computed here).
    """
    out: dict[int, Anchor] = {}
    cum_len = cum
    for i, pc in enumerate(pieces):
        if pc.kappa == 0.0 or pc.length < FLAT_MIN_LEN * tol:
            continue
        an = straight_run(samples, pc.k, pc.j, a, b, tol, pin_start, pin_end)
        if an is None:
            continue
        if cum_len is None:
            cum_len = np.concatenate(
                [[0.0], np.cumsum(np.hypot(*(np.diff(samples, axis=0).T)))])
        run_len = cum_len[an.i1] - cum_len[an.i0]
        covered = cum_len[min(pc.j, an.i1)] - cum_len[max(pc.k, an.i0)]
        if is_flat(pc.kappa, pc.length, tol) or (
                run_len >= STRAIGHT_MIN_LEN * tol and covered > 0.5 * run_len):
            out[i] = an
    return out


def anchors_of(
    pieces: Sequence[Piece], bad: dict[int, Anchor], samples: FloatArray, a: int, b: int,
    tol: float, *, pin_start: bool, pin_end: bool, own_lines: bool = False,
) -> list[Anchor]:
    """Anchors of a refit: the straight runs under the arcs ``bad`` and the long lines
    (``own_lines``: a long line away from the run's ends on its own line, so the refit
    can keep the pieces joining it; else on the run's least-squares line)."""
    out: list[Anchor] = []
    for i, pc in enumerate(pieces):
        if out and pc.j <= out[-1].i1:
            continue
        an: Anchor | None = None
        if i in bad:
            an = bad[i]
        elif pc.kappa == 0.0 and pc.length >= FLAT_MIN_LEN * tol:
            an = straight_run(samples, pc.k, pc.j, a, b, tol, pin_start, pin_end)
            if own_lines and an is not None and not (
                    np.array_equal(an.q, samples[a]) or np.array_equal(an.q, samples[b])):
                an = Anchor(an.i0, an.i1, pc.p.copy(), pc.t.copy())
        if an is None:
            continue
        if out and an.i1 <= out[-1].i1:
            continue
        if out and out[-1].i1 - an.i0 > 0.5 * min(out[-1].i1 - out[-1].i0, an.i1 - an.i0):
            # mostly the same run, grown from different pieces: the longer one
            if an.i1 - an.i0 > out[-1].i1 - out[-1].i0:
                out[-1] = an
            continue
        # (runs may overlap a little where a short fillet joins them: both bands hold it)
        out.append(an)
    return out
