"""Contour heights for waterline roughing (design section 4, steps 3 and 4;
seed 000, 6.3 and Fig. 7): the public face of two private modules.

- :mod:`zwcore.contour._slabs`: heights in units of :data:`QUANTUM`, the
  slab-volume function :class:`SlabVolumes`, :func:`removed_between` and
  :func:`volume_spread`;
- :mod:`zwcore.contour._equal_volume`: :func:`place_equal_volume`, the
  equal-volume placement (its docstring states the rule).
"""

from __future__ import annotations

from zwcore.contour._equal_volume import EqualVolumeResult, place_equal_volume
from zwcore.contour._slabs import (
    QUANTUM,
    SlabVolumes,
    ceil_units,
    even_heights,
    floor_units,
    removed_between,
    volume_spread,
)

__all__ = [
    "QUANTUM",
    "EqualVolumeResult",
    "SlabVolumes",
    "ceil_units",
    "even_heights",
    "floor_units",
    "place_equal_volume",
    "removed_between",
    "volume_spread",
]
