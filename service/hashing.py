"""Task ids: SHA-256 of the canonical request.

The canonical request is the operation, its parameters (defaults filled in),
the core version and the numeric content of every array as little-endian
float64, so the same grid sent as JSON rows or as float32/float64 base64 is
the same task.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from typing import Any

import numpy as np
import orjson

import zwcore


def task_id(operation: str, params: Mapping[str, Any],
            arrays: Mapping[str, np.ndarray] | None = None) -> str:
    """Hex SHA-256 naming the result of ``operation`` on these inputs."""
    h = hashlib.sha256()
    head = {"operation": operation, "core_version": zwcore.__version__, "params": params}
    h.update(orjson.dumps(head, option=orjson.OPT_SORT_KEYS))
    for name in sorted(arrays or {}):
        a = np.ascontiguousarray((arrays or {})[name], dtype="<f8")
        h.update(orjson.dumps({"array": name, "shape": list(a.shape)}))
        h.update(memoryview(a).cast("B"))
    return h.hexdigest()
