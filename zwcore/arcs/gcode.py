"""G-code text for an arc chain (ISO 6983 / Fanuc dialect, XY plane, mm, absolute).

Arcs are written as G02 (clockwise) / G03 (counter-clockwise) with the centre
given incrementally (I, J from the arc's start point). The start point an NC
control sees is the *rounded* previous end point, so I and J are computed from
that rounded point; this keeps the start and end radii of every arc equal to
within a few units of the last digit (far inside the 0.001 mm controls accept).

Rounding budget: with ``d`` decimals every written end point and centre is within
``e = 0.5 sqrt(2) 10^-d`` of the chain's; the arc a control runs (centre = rounded start
+ I J, radius going from the start's to the end's) stays within ``3 e`` of the chain's
arc, and the chain's points within ``5 e`` of the control's path (same share of the
sweep: centre, radius and start angle each moved). :func:`rounding_budget` is
``4 10^-d`` (> 5 e): a chain fitted within ``tolerance - rounding_budget(d)``
(:func:`zwcore.arcs.fit_arcs` with ``reserve``) gives a program within ``tolerance``
of the input, both ways (0.0004 mm at 4 decimals).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from zwcore.arcs.fit import ArcChain, Segment
from zwcore.errors import InvalidInputError

__all__ = ["rounding_budget", "to_gcode"]


def rounding_budget(decimals: int = 4) -> float:
    """Largest deviation (mm) the rounding to ``decimals`` digits adds to a chain's path,
    both ways: ``4 * 10**-decimals`` (see the module notes)."""
    return 4.0 * 10.0 ** (-decimals)


def _fmt(v: float, decimals: int) -> str:
    s = f"{v:.{decimals}f}"
    # "-0.0000" reads badly and some controls reject it
    if s.startswith("-") and float(s) == 0.0:
        s = s[1:]
    return s


def segment_blocks(segments: Sequence[Segment], start: tuple[float, float], decimals: int,
                   feed_word: str = "") -> list[str]:
    """G01/G02/G03 blocks for ``segments`` from ``start`` (the control's position).

    End points are rounded to ``decimals``; I, J are taken from the rounded start the
    control sees, so start and end radii agree. Moves that round to nothing are left
    out (a full circle is kept). ``feed_word`` goes on the first block only (modal).
    """
    res = 10.0 ** (-decimals)
    cx, cy = round(start[0], decimals), round(start[1], decimals)
    out: list[str] = []
    for seg in segments:
        ex, ey = round(seg.end[0], decimals), round(seg.end[1], decimals)
        moved = abs(ex - cx) > 0.5 * res or abs(ey - cy) > 0.5 * res
        if seg.kind == "line" or seg.center is None:
            if not moved:
                continue
            out.append(f"G01 X{_fmt(ex, decimals)} Y{_fmt(ey, decimals)}{feed_word}")
        else:
            full = seg.sweep is not None and abs(seg.sweep) > math.pi and not moved
            if not moved and not full:
                continue
            i = round(seg.center[0] - cx, decimals)
            j = round(seg.center[1] - cy, decimals)
            out.append(f"{'G03' if seg.ccw else 'G02'} X{_fmt(ex, decimals)} "
                       f"Y{_fmt(ey, decimals)} I{_fmt(i, decimals)} J{_fmt(j, decimals)}"
                       f"{feed_word}")
        feed_word = ""
        cx, cy = ex, ey
    return out


def to_gcode(
    chain: ArcChain,
    *,
    feed: float,
    decimals: int = 4,
    rapid_to_start: bool = True,
    program_end: bool = True,
) -> str:
    """The chain as a G-code program (text, one block per line).

    Parameters
    ----------
    chain : ArcChain
        The chain to write (e.g. from :func:`zwcore.arcs.fit_arcs` or
        :func:`zwcore.arcs.offset.offset_chain`).
    feed : float
        Feed rate in mm/min (``F`` word), finite and > 0.
    decimals : int
        Digits after the decimal point, 4..8 (mm; 4 gives 0.1 micrometre).
    rapid_to_start : bool
        Emit ``G00`` to the first point.
    program_end : bool
        Emit ``M30`` at the end.

    Returns
    -------
    str
        ``G17 G21 G90``, then ``G00`` to the start, ``G01`` for lines and
        ``G02``/``G03`` with incremental ``I J`` for arcs. Segments shorter than
        the output resolution are merged into the next move (they would be
        zero-length blocks); full circles are written with end = start.

    Raises
    ------
    InvalidInputError
        ``feed`` not finite and positive, or ``decimals`` out of range.
    """
    if not (isinstance(feed, int | float) and math.isfinite(feed) and feed > 0):
        raise InvalidInputError("feed", "must be a finite number > 0 (mm/min)")
    if not (isinstance(decimals, int) and 4 <= decimals <= 8):
        raise InvalidInputError("decimals", "must be an integer in 4..8")
    lines = [
        f"(zwplan arc chain: {chain.n_arcs} arcs, {chain.n_lines} lines,"
        f" closed={'yes' if chain.closed else 'no'})",
        "G17 G21 G90",
    ]
    if not chain.segments:
        return "\n".join([*lines, "M30"] if program_end else lines) + "\n"
    x0, y0 = chain.segments[0].start
    cx, cy = round(x0, decimals), round(y0, decimals)
    if rapid_to_start:
        lines.append(f"G00 X{_fmt(cx, decimals)} Y{_fmt(cy, decimals)}")
    lines += segment_blocks(chain.segments, (x0, y0), decimals, f" F{_fmt(feed, 1)}")
    if program_end:
        lines.append("M30")
    return "\n".join(lines) + "\n"
