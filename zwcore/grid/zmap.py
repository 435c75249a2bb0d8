"""The z-map: a regular height grid of the finished part.

``z[i, k]`` is the height at ``(x0 + k*dx, y0 + i*dy)``: rows run along y,
columns along x (design section 1).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from zwcore.errors import InvalidInputError

__all__ = [
    "INTERPOLATIONS",
    "MAX_ABS_HEIGHT",
    "Interpolation",
    "ZMap",
    "as_heights",
    "finite_number",
    "positive_number",
    "stock_top_at_or_above",
]

#: Heights beyond a kilometre are not a part on a machine tool; rejecting them
#: also keeps every sum and difference of heights far from overflow.
MAX_ABS_HEIGHT = 1.0e6

Interpolation = Literal["bilinear", "cell"]
INTERPOLATIONS: tuple[Interpolation, ...] = ("bilinear", "cell")


def as_heights(z: ArrayLike, field: str = "z") -> NDArray[np.float64]:
    """Normalise a height grid: 2-D, at least 2 x 2, finite, float64.

    Parameters
    ----------
    z : (ny, nx) array_like
        Heights, rows along y.
    field : str
        Name used in the error when the grid is rejected.

    Returns
    -------
    z : (ny, nx) float64
        C-contiguous; the input itself when it already is.
    """
    try:
        arr = np.asarray(z, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(field, f"heights must be numbers ({exc})") from None
    if arr.ndim != 2:
        raise InvalidInputError(field, f"must be a 2-D grid of rows, got {arr.ndim} dimension(s)")
    ny, nx = arr.shape
    if ny < 2 or nx < 2:
        raise InvalidInputError(field, f"grid must be at least 2 x 2 nodes, got {ny} x {nx}")
    # Fast path: min and max propagate NaN and expose ±inf, two passes and no temporaries.
    lo, hi = float(arr.min()), float(arr.max())
    if not (np.isfinite(lo) and np.isfinite(hi)):
        i, k = np.argwhere(~np.isfinite(arr))[0]
        raise InvalidInputError(
            field, f"heights must be finite; row {i}, column {k} holds {arr[i, k]!r}"
        )
    if lo < -MAX_ABS_HEIGHT or hi > MAX_ABS_HEIGHT:
        i, k = np.argwhere(np.abs(arr) > MAX_ABS_HEIGHT)[0]
        raise InvalidInputError(
            field, f"heights must lie within ±{MAX_ABS_HEIGHT:g} mm; row {i}, column {k} "
            f"holds {arr[i, k]!r}")
    return np.ascontiguousarray(arr)


def finite_number(value: object, field: str) -> float:
    """``value`` as a finite float, or :class:`InvalidInputError` naming ``field``."""
    try:
        v = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise InvalidInputError(field, f"must be a number, got {value!r}") from None
    if not np.isfinite(v):
        raise InvalidInputError(field, f"must be finite, got {value!r}")
    return v


def positive_number(value: object, field: str) -> float:
    """``value`` as a finite float > 0, or :class:`InvalidInputError` naming ``field``."""
    v = finite_number(value, field)
    if v <= 0.0:
        raise InvalidInputError(field, f"must be a finite number > 0, got {value!r}")
    return v


def stock_top_at_or_above(value: object, part_top: float) -> float:
    """A requested stock top: finite, within the height range, not below the part."""
    v = finite_number(value, "stock_top")
    if abs(v) > MAX_ABS_HEIGHT:
        raise InvalidInputError("stock_top", f"must lie within ±{MAX_ABS_HEIGHT:g} mm, got {v!r}")
    if v < part_top:
        raise InvalidInputError("stock_top", f"must be at or above the part's highest point "
                                f"({part_top!r} mm), got {v!r}")
    return v


@dataclass(frozen=True, eq=False)
class ZMap:
    """A validated z-map.

    Parameters
    ----------
    z : (ny, nx) float64
        Heights; node ``(k, i)`` sits at ``(x0 + k*dx, y0 + i*dy)``.
    x0, y0 : float
        Position of node ``(0, 0)`` in mm.
    dx, dy : float
        Node spacing in mm, > 0.
    """

    z: NDArray[np.float64]
    x0: float = 0.0
    y0: float = 0.0
    dx: float = 1.0
    dy: float = 1.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "z", as_heights(self.z))
        object.__setattr__(self, "x0", finite_number(self.x0, "x0"))
        object.__setattr__(self, "y0", finite_number(self.y0, "y0"))
        object.__setattr__(self, "dx", positive_number(self.dx, "dx"))
        object.__setattr__(self, "dy", positive_number(self.dy, "dy"))

    @property
    def shape(self) -> tuple[int, int]:
        """``(ny, nx)``."""
        ny, nx = self.z.shape
        return int(ny), int(nx)

    @property
    def cell_area(self) -> float:
        """Area one node stands for, ``dx * dy`` in mm²."""
        return self.dx * self.dy
