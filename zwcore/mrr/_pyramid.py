"""Fast kernels behind :func:`zwcore.mrr.wavelets.analyse` (private): the Haar
pyramid and the shared two-thread schedule (the single-knot step, built on the
same schedule and knobs, is :mod:`zwcore.mrr._hat`).

Every function here computes *exactly* what the reference steps in
:mod:`zwcore.mrr.wavelets` compute (``_haar_split``, ``_hat_split`` on an edge-padded
grid): the same floating-point operations on the same operands in the same
order, so the results are bit-identical (the tests check this). Only the
schedule differs:

- no padded copies: a level's padded last row/column is handled by pairing it
  with itself, which is what edge padding means;
- row strips: each strip's temporaries stay in cache, and per-strip outputs are
  written straight into the result arrays;
- Haar cache blocking: a Haar coarse row depends on exactly two finer rows, so
  the ``ll`` rows a strip produces are fed to the next level while they are
  still in cache (a pipeline over levels);
- memory: a pyramid's result arrays are carved from one fresh block, and the
  strip scratch is kept per thread between calls (a fresh buffer costs a page
  fault per 4 KiB, which at these sizes rivals the arithmetic);
- two threads (numpy releases the GIL inside ufuncs) taking row bands in turn,
  for large grids. Haar bands start on a multiple of ``2**k`` rows, so they
  stay aligned through ``k`` levels; single-knot bands are computed level by
  level (each level's guard needs the previous level's extremes), each strip
  reading the two rows of halo it needs.

Arrays are float64 and C-contiguous.
"""

from __future__ import annotations

import itertools
import os
import threading
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from functools import partial

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]

#: Elements of a level's input processed per ufunc call (about 1 MiB), so a
#: strip and its temporaries stay in the per-core cache.
STRIP_ELEMENTS = 1 << 17
#: Grids smaller than this (input nodes) stay single-threaded: below it the
#: hand-off to a second thread costs more than it saves.
THREAD_MIN_ELEMENTS = 1 << 18
#: Row bands a large grid is cut into for the two threads to share: at most
#: BANDS, and at least BAND_ELEMENTS nodes each. Each band costs Python calls
#: and GIL hand-offs, so a 1024 x 1024 grid gets only 2 (one per thread); more
#: bands only help to balance the threads on large grids.
BANDS = 8
BAND_ELEMENTS = 1 << 19
#: Levels with at most this many input nodes are done whole, in one go.
SMALL_ELEMENTS = 1 << 12
#: Fewest rows a Haar band may have at its last threaded step (the coarser
#: steps are cheap, and run on one thread without the hand-offs).
MIN_BAND_ROWS = 64
#: Scratch (float64 elements) each thread keeps between calls.
SCRATCH_KEEP = 1 << 19

_pool: ThreadPoolExecutor | None = None
_pool_lock = threading.Lock()


def worker_count() -> int:
    """Threads used for large grids: 2 when the machine has 2+ cores, else 1."""
    return 2 if (os.cpu_count() or 1) >= 2 else 1


def _executor() -> ThreadPoolExecutor:
    global _pool
    with _pool_lock:
        if _pool is None:
            _pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="zw-pyramid")
        return _pool


def _forget_pool() -> None:
    # A forked child inherits the pool object but not its thread: start afresh.
    global _pool, _pool_lock
    _pool, _pool_lock = None, threading.Lock()


os.register_at_fork(after_in_child=_forget_pool)


def run_shared(tasks: Sequence[Callable[[], object]]) -> None:
    """Run independent tasks on this thread and the helper thread, each taking
    the next unclaimed task; re-raise the first error. Claiming (rather than a
    fixed half each) keeps both threads busy when one of them gets less CPU."""
    lock = threading.Lock()
    todo = iter(tasks)

    def drain() -> None:
        while True:
            with lock:
                task = next(todo, None)
            if task is None:
                return
            task()

    if len(tasks) < 2:
        drain()
        return
    fut: Future[None] = _executor().submit(drain)
    try:
        drain()
    finally:
        fut.result()


def bands(n: int, parts: int, align: int) -> list[tuple[int, int]]:
    """``[start, stop)`` ranges covering ``range(n)`` in about ``parts`` pieces,
    every start a multiple of ``align``."""
    size = -(-n // (parts * align)) * align  # ceil(n / parts), rounded up to align
    return [(a, min(a + size, n)) for a in range(0, n, size)]


def strip_rows(width: int) -> int:
    """Even number of rows per strip for a level ``width`` nodes wide."""
    rows = max(2, STRIP_ELEMENTS // max(width, 1))
    return rows + (rows & 1)


# --------------------------------------------------------------------------
# Haar
# --------------------------------------------------------------------------


class _ThreadScratch(threading.local):
    buf: F64 | None = None


_scratch = _ThreadScratch()


def _thread_scratch(n: int) -> F64:
    """``n`` float64 of scratch for the calling thread. A buffer of at most
    ``SCRATCH_KEEP`` elements is kept for the thread's later calls: a fresh one
    would cost a page fault per 4 KiB on every call. Only one user at a time per
    thread (a Haar band runs its levels one strip at a time), and the contents
    never leave this module."""
    buf = _scratch.buf
    if buf is None or buf.size < n:
        buf = np.empty(n)
        if n <= SCRATCH_KEEP:
            _scratch.buf = buf
    return buf[:n]


def _carve(shapes: Sequence[tuple[int, int]]) -> list[tuple[F64, F64, F64, F64]]:
    """Four fresh C-contiguous arrays of each shape, carved from one allocation
    (one call into the allocator instead of four per level: fewer fresh pages
    to fault in), each starting on a 64-byte boundary of the block."""
    sizes = [-(-(ny * nx) // 8) * 8 for ny, nx in shapes]
    block = np.empty(4 * sum(sizes))
    out = []
    at = 0
    for (ny, nx), size in zip(shapes, sizes, strict=True):
        views = [block[at + i * size:at + i * size + ny * nx].reshape(ny, nx) for i in range(4)]
        out.append((views[0], views[1], views[2], views[3]))
        at += 4 * size
    return out


def _haar_pair(e: F64, o: F64, low: F64, high: F64, lifted: bool) -> None:
    """One Haar split of the pairs ``(e, o)``, as ``_haar_split`` computes it:
    ``low = max(e, o)`` (lifted) or ``(e + o) * 0.5``; ``high = (e - o) * 0.5``."""
    if lifted:
        np.maximum(e, o, out=low)
    else:
        np.add(e, o, out=low)
        np.multiply(low, 0.5, out=low)
    np.subtract(e, o, out=high)
    np.multiply(high, 0.5, out=high)


class _HaarLevel:
    """One Haar step over one band of rows: the outputs, where the strip scratch
    lives, and how far the band has got.

    A strip of ``n`` fine rows (``q`` even and ``p`` odd ones) is split into
    z's even and odd columns, each with its even rows first, then its odd rows:
    every ufunc below then runs as one flat 1-D loop (numpy's 2-D loops over
    the same elements are much slower), the x step on even and odd rows at once
    and in place where it can; the y step writes straight into the result rows.
    """

    def __init__(self, fine: F64, out: tuple[F64, F64, F64, F64], rows: tuple[int, int],
                 lifted: bool, track: bool = False) -> None:
        self.fine = fine
        self.flat = [a.reshape(-1) for a in out]  # ll, lh, hl, hh; views
        self.lifted = lifted
        self.start, self.stop = rows  # fine rows of this band
        self.done = rows[0]
        nx = fine.shape[1]
        self.strip = strip_rows(nx)
        self.half, self.mx = nx // 2, (nx + 1) // 2
        # the most coarse rows a strip makes
        self.pairs = (min(self.strip, rows[1] - rows[0]) + 1) // 2
        self.scratch: F64 = np.empty(0)  # set by the band: scratch_size() elements
        # min and max of the fine rows seen (input validation), when tracked
        self.track = track
        self.extremes: list[float] = []

    def scratch_size(self) -> int:
        if self.half == self.mx:
            return 6 * self.pairs * self.half
        return 4 * self.pairs * (self.half + self.mx)

    def run(self, r0: int, r1: int) -> None:
        """Analyse fine rows ``[r0, r1)`` (``r0`` even; ``r1`` odd only at the
        grid's last row, which is then paired with itself)."""
        z = self.fine[r0:r1]
        if self.track:
            self.extremes.append(float(z.min()))
            if not self.lifted:  # lifted, the coarsest ll holds the max
                self.extremes.append(float(z.max()))
        if self.half == self.mx:
            lo_e, lo_o, hi_e, hi_o = self._x_step_even(z)
        else:
            lo_e, lo_o, hi_e, hi_o = self._x_step_odd(z)
        # y step: row pairs, straight into the result rows. hl and hh are never lifted.
        a = (r0 >> 1) * self.mx
        b = a + lo_e.size
        ll, lh, hl, hh = self.flat
        _haar_pair(lo_e, lo_o, ll[a:b], lh[a:b], self.lifted)
        _haar_pair(hi_e, hi_o, hl[a:b], hh[a:b], False)
        self.done = r1

    def _x_step_even(self, z: F64) -> tuple[F64, F64, F64, F64]:
        """x step of the rows ``z`` (an even width): pairs ``(z[:, 2k], z[:, 2k+1])``.
        Returns the low and high outputs on even rows and on odd rows (an odd last
        row is paired with itself), flat."""
        n = z.shape[0]
        p = n >> 1  # odd rows
        q = n - p  # even rows = coarse rows
        h = self.half
        cap = 2 * self.pairs * h  # room for 2 * q rows of h
        s = self.scratch
        e, o, lo = s[:n * h], s[cap:cap + n * h], s[2 * cap:2 * cap + n * h]
        if p == q:  # all four phases in one copy
            dst = s[:2 * cap].reshape(2, cap)[:, :n * h].reshape(2, 2, q, h)
            np.copyto(dst, z.reshape(q, 2, h, 2).transpose(3, 1, 0, 2))
        else:
            np.copyto(e[:q * h].reshape(q, h), z[0::2, 0::2])
            np.copyto(e[q * h:].reshape(p, h), z[1::2, 0::2])
            np.copyto(o[:q * h].reshape(q, h), z[0::2, 1::2])
            np.copyto(o[q * h:].reshape(p, h), z[1::2, 1::2])
        # low, then high in place of the odd columns
        _haar_pair(e, o, lo, o, self.lifted)
        hi = s[cap:cap + 2 * q * h]
        lo = s[2 * cap:2 * cap + 2 * q * h]
        if q > p:  # an odd last row pairs with itself
            lo[n * h:] = lo[p * h:q * h]
            hi[n * h:] = hi[p * h:q * h]
        m = q * h
        return lo[:m], lo[m:], hi[:m], hi[m:]

    def _x_step_odd(self, z: F64) -> tuple[F64, F64, F64, F64]:
        """As :meth:`_x_step_even` for an odd width: the last column pairs with itself."""
        n = z.shape[0]
        p = n >> 1
        q = n - p
        h, mx = self.half, self.mx
        s = self.scratch
        c = self.pairs * h  # phase capacity
        d = 4 * c  # x step outputs start here, capacity self.pairs * mx each
        w = self.pairs * mx
        lo_e, lo_o = s[d:d + q * mx], s[d + w:d + w + q * mx]
        hi_e, hi_o = s[d + 2 * w:d + 2 * w + q * mx], s[d + 3 * w:d + 3 * w + q * mx]
        for k, rows, lo, hi in ((q, z[0::2], lo_e, hi_e), (p, z[1::2], lo_o, hi_o)):
            e, o = s[0:k * h].reshape(k, h), s[c:c + k * h].reshape(k, h)
            np.copyto(e, rows[:, 0:2 * h:2])
            np.copyto(o, rows[:, 1:2 * h:2])
            lo2, hi2 = lo[:k * mx].reshape(k, mx), hi[:k * mx].reshape(k, mx)
            _haar_pair(e, o, lo2[:, :h], hi2[:, :h], self.lifted)
            last = rows[:, -1:]
            _haar_pair(last, last, lo2[:, h:], hi2[:, h:], self.lifted)
        if q > p:  # an odd last row pairs with itself
            lo_o[p * mx:] = lo_e[p * mx:]
            hi_o[p * mx:] = hi_e[p * mx:]
        return lo_e, lo_o, hi_e, hi_o

    def produced(self) -> int:
        """Coarse rows written so far (absolute index, exclusive)."""
        return (self.done + 1) // 2


def _haar_band(levels: list[_HaarLevel]) -> None:
    """Run a band through consecutive Haar steps as a pipeline: after each strip
    of the finest step, every coarser step consumes the whole strips now
    available, while they are still in cache. The steps run one strip at a time,
    so they share this thread's scratch."""
    scratch = _thread_scratch(max(lev.scratch_size() for lev in levels))
    for lev in levels:
        lev.scratch = scratch
    first = levels[0]
    while first.done < first.stop:
        first.run(first.done, min(first.done + first.strip, first.stop))
        for finer, lev in itertools.pairwise(levels):
            avail = finer.produced()
            while lev.done < lev.stop:
                end = min(lev.done + lev.strip, lev.stop)
                if end > avail:
                    break
                lev.run(lev.done, end)


def _haar_small(z: F64, out: tuple[F64, F64, F64, F64], lifted: bool) -> None:
    """One Haar step of a small grid with even sides, in the fewest ufunc calls
    (the same operations as :class:`_HaarLevel`, on strided views)."""
    ll, lh, hl, hh = out
    lo, hi = np.empty((2, z.shape[0], z.shape[1] // 2))
    _haar_pair(z[:, 0::2], z[:, 1::2], lo, hi, lifted)
    _haar_pair(lo[0::2], lo[1::2], ll, lh, lifted)
    _haar_pair(hi[0::2], hi[1::2], hl, hh, False)


def haar_pyramid(z: F64, steps: int, lifted: bool, track: bool = False,
                 ) -> tuple[list[tuple[F64, F64, F64, F64]], tuple[float, float]]:
    """``steps >= 1`` Haar analysis steps of ``z``.

    Returns ``[(ll, lh, hl, hh), ...]`` from the finest step to the coarsest and,
    when ``track``, ``(z.min(), z.max())`` (NaN if ``z`` holds one), gathered
    while the strips are in cache; else ``(nan, nan)``.
    """
    shapes = [z.shape]
    for _ in range(steps):
        ny, nx = shapes[-1]
        shapes.append(((ny + 1) // 2, (nx + 1) // 2))
    out = _carve(shapes[1:])
    fines = [z] + [o[0] for o in out[:-1]]
    first_steps: list[_HaarLevel] = []

    def band(s0: int, s1: int, top: int, bottom: int) -> None:
        """Steps ``[s0, s1)`` over the step-``s0`` rows ``[top, bottom)``."""
        levels = []
        for s in range(s0, s1):
            k = s - s0
            rows = (top >> k, -(-bottom // (1 << k)))  # top is a multiple of 2**k
            levels.append(_HaarLevel(fines[s], out[s], rows, lifted, track and s == 0))
        if s0 == 0:
            first_steps.append(levels[0])
        if track:  # a grid that fails validation may hold inf: no warnings for it
            with np.errstate(all="ignore"):
                _haar_band(levels)
        else:
            _haar_band(levels)

    ny, nx = z.shape
    done = 0
    if worker_count() > 1 and ny * nx >= THREAD_MIN_ELEMENTS:
        # Bands starting at multiples of 2**k rows stay aligned for k steps; each
        # band keeps at least MIN_BAND_ROWS rows at its last threaded step.
        parts = min(BANDS, max(2, ny * nx // BAND_ELEMENTS))
        k = 0
        while k < steps and (ny // parts) >> (k + 1) >= MIN_BAND_ROWS:
            k += 1
        if k > 0:
            run_shared([partial(band, 0, k, top, bottom)
                         for top, bottom in bands(ny, parts, 1 << k)])
            done = k
    # The remaining (coarser) steps on this thread: pipelined while the levels
    # are large, then one small level at a time.
    small = done
    while small < steps and shapes[small][0] * shapes[small][1] > SMALL_ELEMENTS:
        small += 1
    if small > done:
        band(done, small, 0, shapes[done][0])
    for s in range(small, steps):
        if (track and s == 0) or shapes[s][0] % 2 or shapes[s][1] % 2:
            band(s, s + 1, 0, shapes[s][0])
        else:
            _haar_small(fines[s], out[s], lifted)
    if not track:
        return out, (np.nan, np.nan)
    seen = [v for lev in first_steps for v in lev.extremes]
    # The lifted coarsest level is the max over the grid, exactly (NaN included).
    top = float(out[-1][0].max()) if lifted else float(np.max(seen))
    return out, (float(np.min(seen)), top)
