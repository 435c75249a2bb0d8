"""Z-map validation."""

from __future__ import annotations

import numpy as np
import pytest

from zwcore.errors import InvalidInputError
from zwcore.grid.zmap import ZMap, as_heights


@pytest.mark.parametrize(("z", "message"), [
    ([[1.0, 2.0]], "at least 2 x 2"),
    ([1.0, 2.0, 3.0], "2-D"),
    ([[1.0, float("nan")], [0.0, 0.0]], "row 0, column 1"),
    ([[1.0, 2.0], [float("inf"), 0.0]], "finite"),
    ([[1.0, 2.0], [1e9, 0.0]], "within"),
    ([["a", 2.0], [1.0, 0.0]], "numbers"),
])
def test_bad_heights_are_rejected_with_the_reason(z: object, message: str) -> None:
    with pytest.raises(InvalidInputError, match=message) as err:
        as_heights(z)  # type: ignore[arg-type]
    assert err.value.field == "z"


@pytest.mark.parametrize("name", ["dx", "dy"])
@pytest.mark.parametrize("value", [0.0, -1.0, float("nan"), float("inf")])
def test_spacing_must_be_positive_and_finite(name: str, value: float) -> None:
    with pytest.raises(InvalidInputError) as err:
        ZMap(np.zeros((2, 2)), **{name: value})
    assert err.value.field == name


def test_zmap_normalises_to_float64() -> None:
    zm = ZMap(np.ones((3, 4), dtype=np.float32), x0=1, y0=2, dx=0.5, dy=0.25)
    assert zm.z.dtype == np.float64 and zm.shape == (3, 4)
    assert zm.cell_area == pytest.approx(0.125)
