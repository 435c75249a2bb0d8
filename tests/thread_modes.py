"""Forcing the plan's thread splits in the tests (``zwcore.scanline._threads`` and the
kernels' size thresholds), shared by ``test_plan8_threads`` and ``test_plan9_threads``.

The plan splits a kernel between two threads only with two workers and only where the work
passes a size threshold; on the tests' small inputs the thresholds would never be passed,
so the tests set them: at 0 every kernel may split, at :data:`NEVER` none does.
"""

from __future__ import annotations

import pytest

from zwcore.scanline import _passes, _reach, _stock_lines, _threads
from zwcore.sim import _morph

#: A size threshold no test input reaches: the kernel runs whole.
NEVER = 1 << 62

#: (module, name) of every size threshold of a split kernel.
THRESHOLDS = ((_stock_lines, "THREAD_WORK"), (_reach, "THREAD_NODES"),
              (_passes, "THREAD_CELLS"), (_morph, "THREAD_WORK"))


def force_threads(mp: pytest.MonkeyPatch, workers: int, *, split: bool = True) -> None:
    """Run the plan on ``workers`` threads (the plan's and the dilation's), with every size
    threshold at 0 (``split``: any work may split) or at :data:`NEVER`."""
    mp.setattr(_threads, "WORKERS", workers)
    mp.setattr(_morph, "THREADS", workers)
    for module, name in THRESHOLDS:
        mp.setattr(module, name, 0 if split else NEVER)
