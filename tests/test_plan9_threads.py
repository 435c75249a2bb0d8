"""The plan's second thread only where it can run (``zwcore.scanline._threads.split``).

- the core count is the process's affinity mask (not the machine's count);
- :func:`split` is false on one worker and on the helper thread, true on the caller's
  thread with two workers;
- on one thread no kernel is split: one envelope sweep and one drop per line sweep over
  every row and line, one per-position call over every position, one concave-radius pass
  (a split would only add its halo, its halves run in turn), whatever the thresholds;
  the results equal those of a forced two-thread split, bit for bit;
- on one thread the chain search computes no candidate's cost it does not use (no
  speculative pair), and ends with the chain and figures of the two-thread search.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.test_plan8_threads import _fillet_part
from tests.test_scanline_stock_sweep import _cases
from tests.thread_modes import force_threads
from zwcore.grid.tools import default_tools
from zwcore.scanline import _reach, _regions, _stock_lines, _threads, _tool_choice
from zwcore.scanline import _stock_kernels as _k
from zwcore.scanline import _stock_sweep as _sw
from zwcore.scanline._stock_state import BLOCK, block_max

_Case = tuple[np.ndarray, float, float, float, np.ndarray, np.ndarray, np.ndarray]


def test_cores_follow_the_affinity_mask() -> None:
    if hasattr(os, "sched_getaffinity"):
        assert _threads.cores() == len(os.sched_getaffinity(0))
    assert _threads.cores() >= 1


def test_split_only_on_the_callers_thread_with_two_workers(
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(_threads, "WORKERS", 1)
    assert not _threads.split()
    monkeypatch.setattr(_threads, "WORKERS", 2)
    assert _threads.split()
    on_helper, here = _threads.both(_threads.split, _threads.split)
    assert here and not on_helper


def _counting(monkeypatch: pytest.MonkeyPatch, module: Any, name: str
              ) -> list[tuple[Any, ...]]:
    """Record the trailing arguments of every call of ``module.name``."""
    calls: list[tuple[Any, ...]] = []
    real: Callable[..., Any] = getattr(module, name)

    def spy(*args: Any) -> Any:
        calls.append(args[-2:])
        return real(*args)

    monkeypatch.setattr(module, name, spy)
    return calls


@settings(max_examples=40, deadline=None)
@given(case=_cases(), along_x=st.booleans())
def test_one_thread_splits_nothing(case: _Case, along_x: bool) -> None:
    """With one worker (thresholds at 0) every kernel runs once over everything, and gives
    what the forced two-thread split gives, bit for bit."""
    z, r, dx, dy, u, v, c = case
    x, y = (u, v) if along_x else (v, u)
    stock = z + 2.0
    cl0 = np.where(np.arange(c.size) % 3 == 0, -np.inf, c - 3.0)
    smax = block_max(stock)
    runs = []
    with pytest.MonkeyPatch.context() as mp:
        for workers in (1, 2):
            force_threads(mp, workers)  # thresholds at 0 on one worker too
            cuts = _counting(mp, _sw, "cut_lines")
            drops = _counting(mp, _sw, "cl_lines")
            tops = _counting(mp, _k, "top")
            concave = _counting(mp, _reach, "_concave_kernel")
            sweep = _stock_lines.LineSweep.of(x, y, "x" if along_x else "y", r, dx, dy)
            s = stock.copy()
            t = np.zeros(smax.shape, dtype=bool)
            drop = None
            if sweep is not None:
                sweep.cut(s, c, t, np.zeros_like(t))
                drop = sweep.drop(z, cl0)
            top = _stock_lines.per_position(
                lambda a, b: _k.top(stock, smax, BLOCK, x[a:b], y[a:b], r, dx, dy), x.size,
                r, dx, dy)
            rho = _reach.concave_radii(z, dx, dy)
            runs.append((s, t, drop, top, rho))
            if workers == 1:
                if sweep is not None:
                    assert cuts == [(0, -1)]  # every row, one call
                    assert len(drops) == 1
                assert len(tops) == 1
                assert concave == [(0, z.shape[0])]
            mp.undo()
    for a, b in zip(*runs, strict=True):
        assert (a is None and b is None) or np.array_equal(a, b)
    assert np.array_equal(runs[0][3], _k.top(stock, smax, BLOCK, x, y, r, dx, dy))


def test_one_thread_chain_search_computes_only_what_it_uses(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """One worker: every cost the chain search computes is one it goes on with (no pair
    computed ahead); two (forced): the same chain and figures."""
    part = _fillet_part()
    balls = list(default_tools("ball"))
    runs = []
    for workers in (1, 2):
        monkeypatch.setattr(_threads, "WORKERS", workers)
        reach = _regions._Reach(part.z, part.dx, part.dy, 0.01)
        computed: list[tuple[float, float]] = []
        used: list[tuple[float, float]] = []
        real_cost, real_costs = reach.cost, reach.costs

        def cost(prev: float, nxt: Any, real: Any = real_cost,
                 seen: list[tuple[float, float]] = computed) -> Any:
            seen.append((prev, nxt.radius))
            return real(prev, nxt)

        def costs(prev: float, bs: list[Any], order: list[int], *rest: Any,
                  real: Any = real_costs, seen: list[tuple[float, float]] = used) -> Any:
            for i, minutes in real(prev, bs, order, *rest):
                seen.append((prev, bs[i].radius))
                yield i, minutes

        monkeypatch.setattr(reach, "cost", cost)
        monkeypatch.setattr(reach, "costs", costs)
        chain, times = _regions._plan(balls, reach)
        runs.append((chain, times, sorted(computed), sorted(used)))
    assert runs[0][2] == runs[0][3]  # one thread: nothing computed for nothing
    assert set(runs[1][3]) <= set(runs[1][2])
    assert runs[0][0] == runs[1][0] and runs[0][1] == runs[1][1]
    assert runs[0][3] == runs[1][3]  # the same candidates went on
    assert len(runs[0][0]) >= 2  # a chain with rest balls: the pair search ran


def test_roughing_rests_in_pairs_equal_one_by_one(monkeypatch: pytest.MonkeyPatch) -> None:
    """The roughing choice's simulated rests (``_tool_choice._rests``): on two threads, two
    at a time, the values of :func:`ball_rest` one by one; on one thread computed only
    as asked for."""
    x = np.arange(40) * 0.5
    xx, yy = np.meshgrid(x, x)
    model = np.maximum(np.abs(xx - 10.0), np.abs(yy - 10.0)) * 0.8  # a sharp-cornered pit
    lev = _tool_choice.Level(5, model, 0.5, 0.5, model.shape, (39, 39), 1.0, None, 0, 0)
    radii = [3.0, 2.5, 2.0, 1.5, 1.0]
    want = [_tool_choice.ball_rest(lev, r) for r in radii]
    assert len(set(want)) > 1  # the radii leave different rests
    asked = _counting(monkeypatch, _tool_choice, "ball_rest")
    monkeypatch.setattr(_threads, "WORKERS", 2)
    assert list(_tool_choice._rests(lev, radii)) == want
    monkeypatch.setattr(_threads, "WORKERS", 1)
    asked.clear()
    got = _tool_choice._rests(lev, radii)
    assert [next(got), next(got)] == want[:2] and len(asked) == 2
