"""Shared fixtures and hypothesis strategies."""

from __future__ import annotations

import os

import numpy as np
import pytest
from fastapi.testclient import TestClient
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

settings.register_profile(
    "default", max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
# CI: the same examples on every run, so a red build points at the change, not the dice;
# local runs keep exploring (and `thorough` explores ten times as far).
settings.register_profile("ci", parent=settings.get_profile("default"), derandomize=True)
settings.register_profile("thorough", parent=settings.get_profile("default"), max_examples=600)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))


@st.composite
def height_grids(draw: st.DrawFn, min_side: int = 2, max_side: int = 9) -> np.ndarray:
    """Random z-maps: noisy, flat, spiky, stepped, at every size from 2 to ``max_side``."""
    ny = draw(st.integers(min_side, max_side))
    nx = draw(st.integers(min_side, max_side))
    kind = draw(st.sampled_from(["random", "flat", "spiky", "steps"]))
    if kind == "flat":
        return np.full((ny, nx), draw(st.floats(-100, 100)))
    if kind == "random":
        return draw(hnp.arrays(np.float64, (ny, nx), elements=st.floats(-50, 50, width=64)))
    base = np.full((ny, nx), draw(st.floats(-10, 10)))
    cells = draw(st.lists(st.tuples(st.integers(0, ny - 1), st.integers(0, nx - 1),
                                    st.floats(-40, 40)), min_size=1, max_size=6))
    for i, k, h in cells:
        if kind == "spiky":
            base[i, k] += h
        else:
            base[i:, k:] += h
    return base


def make_client(tmp_path, **overrides: object) -> TestClient:  # type: ignore[no-untyped-def]
    """A test client on a fresh app with its own embedded store."""
    from service.main import create_app
    from service.settings import Settings

    # workers start on first use in tests: most tests never use them
    overrides.setdefault("prestart_workers", False)
    return TestClient(create_app(Settings(data_dir=tmp_path, **overrides)))  # type: ignore[arg-type]


@pytest.fixture
def client(tmp_path):  # type: ignore[no-untyped-def]
    with make_client(tmp_path) as c:
        yield c
