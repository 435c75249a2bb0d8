"""Haar and single-knot wavelet transforms of z-maps, with the overcut-free lift.

Unnormalised filters (Stollnitz, DeRose, Salesin), design section 2:

- Haar: ``a = (z0 + z1)/2``, ``w = (z0 - z1)/2``. Lifted: ``a' = a + |w| =
  max(z0, z1)``, so every coarse cell holds the maximum of the fine cells it
  covers.
- Single-knot (hat functions, lazy split + linear prediction):
  ``a_i = z_2i``, ``w_i = z_2i+1 - (z_2i + z_2i+2)/2``. Lifted:
  ``a'_i = a_i + max(0, w_i-1, w_i)``, the smallest lift that keeps the linear
  interpolant above every fine node.

Two dimensions use the non-standard decomposition: one x step then one y step
per level, giving four bands. Band names give the filter along x then y:
``ll`` (the approximation), ``lh`` (low in x, high in y), ``hl`` and ``hh``.
Only the approximation is ever lifted: the lift exists so that the coarse
model contains the fine one, and the detail bands are not models.

Every analysis step needs an even node count (Haar) or an odd one
(single-knot); a grid that does not halve evenly is padded by repeating its
last row/column (the part's edge extended flat). The padding is recorded per
level and synthesis removes it, so nothing inside the input changes.

Implementation: :func:`_reference_step` is the definition, written literally
(pad, x step, y step). :func:`analyse` and :func:`analysis_step` run the fast
kernels of :mod:`zwcore.mrr._pyramid` and :mod:`zwcore.mrr._hat` (row strips kept
in cache, the Haar levels pipelined strip by strip, two threads on large grids),
which perform the same
floating-point operations on the same operands and so give bit-identical
results; the tests compare the two bit for bit.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from zwcore.errors import InvalidInputError
from zwcore.grid.zmap import MAX_ABS_HEIGHT, Interpolation, as_heights
from zwcore.mrr import _hat, _pyramid

__all__ = [
    "WAVELETS",
    "Bands",
    "Multiresolution",
    "Wavelet",
    "analyse",
    "analysis_step",
    "interpolation_of",
    "level_count",
    "synthesis_step",
    "wavelet_name",
]

Wavelet = Literal["haar", "single_knot"]
WAVELETS: tuple[Wavelet, ...] = ("haar", "single_knot")

F64 = NDArray[np.float64]


def wavelet_name(name: str) -> Wavelet:
    """Normalise a wavelet name, listing the valid ones when it is unknown."""
    key = str(name).strip().lower().replace("-", "_")
    if key == "haar":
        return "haar"
    if key == "single_knot":
        return "single_knot"
    raise InvalidInputError("wavelet", f"unknown wavelet {name!r}; valid: {', '.join(WAVELETS)}")


def interpolation_of(wavelet: Wavelet) -> Interpolation:
    """The surface meaning of a level model: Haar values are flat cells, single-knot
    values are nodes of a bilinear surface."""
    return "cell" if wavelet == "haar" else "bilinear"


@dataclass(frozen=True, eq=False)
class Bands:
    """The detail bands produced by one 2-D analysis step.

    Attributes
    ----------
    lh, hl, hh : 2-D float64
        Detail coefficients (low/high filter along x, then along y).
    fine_shape : (int, int)
        Shape of the finer approximation before padding.
    padding : (int, int)
        Rows and columns appended to the finer approximation (0 or 1 each).
    guard : float
        Extra lift of every single-knot coarse node (a few ulps of the level's
        magnitude) so that float rounding in the prediction and in bilinear
        evaluation can never put the coarse surface below a fine node.
    """

    lh: F64
    hl: F64
    hh: F64
    fine_shape: tuple[int, int]
    padding: tuple[int, int]
    guard: float = 0.0

    def max_abs(self) -> float:
        """Largest detail magnitude in the three bands."""
        # max(-min, max) avoids an |b| temporary the size of the band.
        return float(max(max(-b.min(initial=0.0), b.max(initial=0.0))
                         for b in (self.lh, self.hl, self.hh)))

    def count_nonzero(self) -> int:
        """Number of non-zero detail coefficients."""
        return int(sum(np.count_nonzero(b) for b in (self.lh, self.hl, self.hh)))


# --------------------------------------------------------------------------
# 1-D steps along an axis (axis 0 or 1); arrays are already padded.
# --------------------------------------------------------------------------


def _take(z: F64, axis: int, sl: slice) -> F64:
    return z[sl] if axis == 0 else z[:, sl]


def _haar_split(z: F64, axis: int, lifted: bool) -> tuple[F64, F64]:
    z0 = _take(z, axis, slice(0, None, 2))
    z1 = _take(z, axis, slice(1, None, 2))
    w = np.subtract(z0, z1)
    w *= 0.5
    if lifted:
        a = np.maximum(z0, z1)  # a + |w|, computed exactly
    else:
        a = np.add(z0, z1)
        a *= 0.5
    return a, w


def _haar_merge(a: F64, w: F64, axis: int, lifted: bool) -> F64:
    m = a - np.abs(w) if lifted else a
    shape = list(a.shape)
    shape[axis] *= 2
    z = np.empty(shape)
    np.add(m, w, out=_take(z, axis, slice(0, None, 2)))
    np.subtract(m, w, out=_take(z, axis, slice(1, None, 2)))
    return z


def _hat_lift(w: F64, axis: int, guard: float) -> F64:
    """``max(0, w_{i-1}, w_i) + guard`` for every coarse node i (one more than ``w``)."""
    shape = list(w.shape)
    shape[axis] += 1
    lift = np.full(shape, guard)
    head = _take(lift, axis, slice(0, -1))
    tail = _take(lift, axis, slice(1, None))
    np.maximum(head, w + guard, out=head)
    np.maximum(tail, w + guard, out=tail)
    return lift


def _hat_split(z: F64, axis: int, lifted: bool, guard: float = 0.0) -> tuple[F64, F64]:
    even = _take(z, axis, slice(0, None, 2))
    odd = _take(z, axis, slice(1, None, 2))
    w = np.add(_take(even, axis, slice(0, -1)), _take(even, axis, slice(1, None)))
    w *= -0.5
    w += odd
    a = even + _hat_lift(w, axis, guard) if lifted else even.copy()
    return a, w


def _hat_merge(a: F64, w: F64, axis: int, lifted: bool, guard: float = 0.0) -> F64:
    even = a - _hat_lift(w, axis, guard) if lifted else a
    shape = list(a.shape)
    shape[axis] = 2 * shape[axis] - 1
    z = np.empty(shape)
    _take(z, axis, slice(0, None, 2))[...] = even
    odd = _take(z, axis, slice(1, None, 2))
    np.add(_take(even, axis, slice(0, -1)), _take(even, axis, slice(1, None)), out=odd)
    odd *= 0.5
    odd += w
    return z


def _rounding_guard(z: F64) -> float:
    return _guard_for(float(np.abs(z).max()))


def _guard_for(max_abs: float) -> float:
    # 16 ulps of the level's magnitude covers the rounding of the prediction,
    # the lift and a later bilinear evaluation, with room to spare.
    scale = float(max(max_abs, 1.0))
    return 16.0 * float(np.finfo(np.float64).eps) * scale


def _pad_for(wavelet: Wavelet, n: int) -> int:
    """Nodes to append so that ``n`` halves evenly for this wavelet."""
    if wavelet == "haar":
        return n % 2
    return 1 - n % 2


def _pad_edge(z: F64, padding: tuple[int, int]) -> F64:
    py, px = padding
    if py == 0 and px == 0:
        return z
    return np.pad(z, ((0, py), (0, px)), mode="edge")


# --------------------------------------------------------------------------
# 2-D steps
# --------------------------------------------------------------------------


def analysis_step(z: F64, wavelet: Wavelet, *, lifted: bool = True) -> tuple[F64, Bands]:
    """One level of the non-standard 2-D analysis.

    Parameters
    ----------
    z : (ny, nx) float64
        Approximation at level ``j``.
    wavelet : {"haar", "single_knot"}
    lifted : bool
        Apply the overcut-free lift, so the result contains ``z``.

    Returns
    -------
    ll : (my, mx) float64
        Approximation at level ``j - 1``; ``m = ceil(n/2)`` for Haar and
        ``floor(n/2) + 1`` for single-knot.
    bands : Bands
        The detail bands and the padding used.
    """
    zz = np.ascontiguousarray(z, dtype=np.float64)
    if wavelet == "haar":
        return _haar_steps(zz, 1, lifted)[0][0]
    return _hat_steps(zz, 1, lifted, max(-float(zz.min()), float(zz.max())))[0]


def _haar_steps(z: F64, steps: int, lifted: bool, track: bool = False,
                ) -> tuple[list[tuple[F64, Bands]], tuple[float, float]]:
    """``steps`` Haar analysis steps from ``z`` down, finest first; bit-identical
    to repeating :func:`_reference_step` (see :mod:`zwcore.mrr._pyramid`). With
    ``track``, also ``(z.min(), z.max())`` for input validation (NaN when
    ``steps`` is 0 or ``z`` holds a NaN)."""
    out: list[tuple[F64, Bands]] = []
    shape = z.shape
    if steps == 0:
        return out, (np.nan, np.nan)
    pyramid, extremes = _pyramid.haar_pyramid(z, steps, lifted, track)
    for ll, lh, hl, hh in pyramid:
        padding = (_pad_for("haar", shape[0]), _pad_for("haar", shape[1]))
        out.append((ll, Bands(lh=lh, hl=hl, hh=hh, fine_shape=shape, padding=padding)))
        shape = ll.shape
    return out, extremes


def _hat_steps(z: F64, steps: int, lifted: bool, max_abs: float) -> list[tuple[F64, Bands]]:
    """``steps`` single-knot analysis steps from ``z`` (whose largest magnitude is
    ``max_abs``) down, finest first; bit-identical to repeating
    :func:`_reference_step`."""
    out = []
    cur = z
    for _ in range(steps):
        guard = _guard_for(max_abs) if lifted else 0.0
        ll, lh, hl, hh, lo, hi = _hat.hat_step(cur, lifted, guard)
        padding = (_pad_for("single_knot", cur.shape[0]), _pad_for("single_knot", cur.shape[1]))
        out.append((ll, Bands(lh=lh, hl=hl, hh=hh, fine_shape=cur.shape, padding=padding,
                              guard=guard)))
        cur, max_abs = ll, max(-lo, hi)
    return out


def _reference_step(z: F64, wavelet: Wavelet, *, lifted: bool = True) -> tuple[F64, Bands]:
    """One level of the non-standard 2-D analysis, literally as defined: pad, x step,
    y step. The definition the fast path (:mod:`zwcore.mrr._pyramid`) must reproduce
    bit for bit; parameters and results as :func:`analysis_step`.
    """
    ny, nx = z.shape
    padding = (_pad_for(wavelet, ny), _pad_for(wavelet, nx))
    zp = _pad_edge(z, padding)
    if wavelet == "haar":
        lo, hi = _haar_split(zp, 1, lifted)
        ll, lh = _haar_split(lo, 0, lifted)
        hl, hh = _haar_split(hi, 0, False)
        guard = 0.0  # max() is exact: no rounding to guard against
    else:
        guard = _rounding_guard(zp) if lifted else 0.0
        lo, hi = _hat_split(zp, 1, lifted, guard)
        ll, lh = _hat_split(lo, 0, lifted, guard)
        hl, hh = _hat_split(hi, 0, False)
    return ll, Bands(lh=lh, hl=hl, hh=hh, fine_shape=(ny, nx), padding=padding, guard=guard)


def synthesis_step(ll: F64, bands: Bands, wavelet: Wavelet, *, lifted: bool = True) -> F64:
    """Invert :func:`analysis_step`: the level-``j`` approximation, padding removed."""
    if wavelet == "haar":
        lo = _haar_merge(ll, bands.lh, 0, lifted)
        hi = _haar_merge(bands.hl, bands.hh, 0, False)
        z = _haar_merge(lo, hi, 1, lifted)
    else:
        lo = _hat_merge(ll, bands.lh, 0, lifted, bands.guard)
        hi = _hat_merge(bands.hl, bands.hh, 0, False)
        z = _hat_merge(lo, hi, 1, lifted, bands.guard)
    ny, nx = bands.fine_shape
    return z[:ny, :nx]


def level_count(shape: tuple[int, int], wavelet: Wavelet) -> int:
    """Number of analysis steps down to the coarsest useful level.

    Haar stops at a single cell; single-knot at 2 x 2 nodes (a single bilinear
    patch), because a 2-node axis pads to 3 and halves back to 2.
    """
    n = max(shape)
    steps = 0
    if wavelet == "haar":
        while n > 1:
            n = (n + 1) // 2
            steps += 1
    else:
        while n > 2:
            n = n // 2 + 1
            steps += 1
    return steps


@dataclass(frozen=True, eq=False)
class Multiresolution:
    """A multiresolution representation (MRR) of a z-map.

    Attributes
    ----------
    wavelet : {"haar", "single_knot"}
    lifted : bool
        Whether the overcut-free lift was applied (each level contains the next).
    approximations : list of 2-D float64
        Level models from the coarsest (level 0) to the input (level ``J``).
    details : list of Bands
        ``details[j]`` turns level ``j`` into level ``j + 1``.
    """

    wavelet: Wavelet
    lifted: bool
    approximations: list[F64]
    details: list[Bands] = field(default_factory=list)

    @property
    def depth(self) -> int:
        """``J``: the number of analysis steps (the input is level ``J``)."""
        return len(self.details)

    @property
    def interpolation(self) -> Interpolation:
        return interpolation_of(self.wavelet)

    def scale(self, level: int) -> int:
        """Fine nodes per level-``level`` node along an axis, ``2**(J - level)``."""
        return 1 << (self.depth - level)

    def synthesize(self, coarsest: F64 | None = None, details: Sequence[Bands] | None = None,
                   *, to_level: int | None = None) -> F64:
        """Rebuild a level from the coarsest approximation and the details.

        Parameters
        ----------
        coarsest : 2-D float64, optional
            Level-0 approximation (default: this MRR's).
        details : sequence of Bands, optional
            Detail bands from coarse to fine (default: this MRR's); edited
            coefficients go here.
        to_level : int, optional
            Stop at this level (default: the finest).
        """
        z = self.approximations[0] if coarsest is None else coarsest
        bands = self.details if details is None else details
        stop = len(bands) if to_level is None else to_level
        for j in range(stop):
            z = synthesis_step(z, bands[j], self.wavelet, lifted=self.lifted)
        return z


def _plain_grid(z: object) -> bool:
    """A grid :func:`zwcore.grid.zmap.as_heights` would return unchanged if its values
    pass: a C-contiguous 2-D float64 ndarray of at least 2 x 2."""
    return (type(z) is np.ndarray and z.dtype == np.float64 and z.ndim == 2
            and min(z.shape) >= 2 and bool(z.flags.c_contiguous))


def _within_limits(lo: float, hi: float) -> bool:
    """Whether extremes ``lo``, ``hi`` pass as_heights' checks (finite, within
    ``MAX_ABS_HEIGHT``); NaN fails every comparison."""
    return -MAX_ABS_HEIGHT <= lo and hi <= MAX_ABS_HEIGHT


def _checked_heights(z: object) -> tuple[F64, float, float]:
    """:func:`zwcore.grid.zmap.as_heights` and the grid's min and max. A plain grid is
    checked by its extremes alone, without as_heights' full-size temporaries;
    anything else, or a grid that fails, goes through as_heights, which raises
    the documented error."""
    if _plain_grid(z):
        assert isinstance(z, np.ndarray)
        lo, hi = _hat.extremes(z)
        if _within_limits(lo, hi):
            return z, lo, hi
    zz = as_heights(z)  # type: ignore[arg-type]
    return zz, float(zz.min()), float(zz.max())


def analyse(z: NDArray[np.floating] | Sequence[Sequence[float]], wavelet: str = "haar", *,
            levels: int | None = None, lifted: bool = True) -> Multiresolution:
    """Multiresolution analysis of a z-map.

    Parameters
    ----------
    z : (ny, nx) array_like
        Heights of the finished part (finite, at least 2 x 2).
    wavelet : {"haar", "single_knot"}
    levels : int, optional
        Analysis steps to take; default all (see :func:`level_count`).
    lifted : bool
        Apply the overcut-free lift (default). Without it the transform is the
        plain wavelet transform, whose coarse levels may lie below the part.

    Returns
    -------
    Multiresolution
    """
    name = wavelet_name(wavelet)
    # A plain Haar grid is validated by the extremes of its first level's strips,
    # gathered while the transform reads them (as_heights is called if they fail).
    fused = name == "haar" and _plain_grid(z)
    zz: F64
    if fused:
        assert isinstance(z, np.ndarray)
        zz, lo, hi = z.astype(np.float64, copy=False), np.nan, np.nan
    else:
        zz, lo, hi = _checked_heights(z)
    most = level_count(zz.shape, name)
    if levels is None:
        levels = most
    if isinstance(levels, bool) or not isinstance(levels, (int, np.integer)):
        if fused:
            _checked_heights(zz)  # a bad grid is reported before bad levels
        raise InvalidInputError("levels", f"must be an integer, got {levels!r}")
    if levels < 0 or levels > most:
        if fused:
            _checked_heights(zz)
        raise InvalidInputError(
            "levels", f"must be between 0 and {most} for a {zz.shape[0]} x {zz.shape[1]} "
            f"grid with the {name} wavelet, got {levels}")
    if name == "haar":
        steps, (lo, hi) = _haar_steps(zz, int(levels), lifted, track=fused)
        if fused and not _within_limits(lo, hi):
            _checked_heights(zz)  # raises for a bad grid; passes when levels == 0
    else:
        steps = _hat_steps(zz, int(levels), lifted, max(-lo, hi))
    approximations = [zz] + [ll for ll, _ in steps]
    details = [bands for _, bands in steps]
    approximations.reverse()
    details.reverse()
    return Multiresolution(name, lifted, approximations, details)
