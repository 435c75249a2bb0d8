"""Feeds and the machining-time estimate every planner and the NC program share.

The program's estimate (:meth:`zwcore.toolpath.program.StagePath.time_min`) and the
finishing chain's ranking (:mod:`zwcore.scanline._chain_time`) both price path length by
kind: cutting feed, plunge feed (moves down into material) and rapid traverse, each at
its rate, no acceleration. The formula lives here, below both layers, so the ranking
prices a path exactly as the program's estimate will.
"""

from __future__ import annotations

__all__ = ["DEFAULT_FEED", "DEFAULT_PLUNGE_FEED", "DEFAULT_RAPID_FEED", "machining_minutes"]

#: Cutting feed of a tool without cutting data, mm/min.
DEFAULT_FEED = 1_200.0
#: Feed of moves down into material (plunges, ramps) of a tool without cutting data, mm/min.
DEFAULT_PLUNGE_FEED = 400.0
#: Rapid traverse rate of the time estimate, mm/min.
DEFAULT_RAPID_FEED = 15_000.0


def machining_minutes(feed_length: float, plunge_length: float, rapid_length: float, *,
                      feed: float, plunge_feed: float, rapid_feed: float) -> float:
    """Time of a path, minutes: each length (mm) at its rate (mm/min), no acceleration.

    Parameters
    ----------
    feed_length, plunge_length, rapid_length : float
        Path length at the cutting feed, at the plunge feed and at rapid, mm.
    feed, plunge_feed, rapid_feed : float
        The rates, mm/min (> 0).
    """
    return rapid_length / rapid_feed + plunge_length / plunge_feed + feed_length / feed
