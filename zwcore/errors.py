"""The error family of zwcore.

One base class, a small family under it (as in shapely 2): callers catch
:class:`ZwError` for anything the core rejects, or a subclass for one kind.
Every error names the offending ``field`` so the HTTP layer can report it
without parsing messages.
"""

from __future__ import annotations

__all__ = ["InvalidInputError", "LimitExceededError", "PlanningError", "ZwError"]


class ZwError(Exception):
    """Base class of every error raised by zwcore.

    Parameters
    ----------
    field : str
        Dotted path of the offending input (``"grid.z"``, ``"tolerance"``).
    reason : str
        What is wrong with it, phrased for the person who sent it.
    """

    def __init__(self, field: str, reason: str) -> None:
        super().__init__(f"{field}: {reason}")
        self.field = field
        self.reason = reason

    def __reduce__(self) -> tuple[type[ZwError], tuple[str, str]]:
        # pickled as (field, reason), so an error raised in a worker process
        # arrives whole (the default would re-call __init__ with the message only)
        return type(self), (self.field, self.reason)


class InvalidInputError(ZwError, ValueError):
    """The input is malformed: wrong shape, non-finite values, bad option."""


class LimitExceededError(InvalidInputError):
    """The input is well formed but larger than a configured limit allows."""


class PlanningError(ZwError):
    """A valid input admits no plan (for instance no library tool can do the job)."""
