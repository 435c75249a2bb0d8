"""Task ids: SHA-256 of the canonical request.

The canonical request is the operation, its parameters (defaults filled in),
the core version and a digest of the core's source code (results of different
code never share an id, even when a change forgot to bump the version: cached
results outlive deploys, in Redis and on disk), and the numeric content of every
array, so the same grid sent as JSON rows or as float32/float64 base64 is the
same task. An array
whose every value is exactly a float32 is hashed as little-endian float32
(half the bytes to hash, and float32 uploads need no check); any other as
little-endian float64.
"""

from __future__ import annotations

import functools
import hashlib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import orjson

import zwcore


def canonical_bytes(a: np.ndarray, exact_float32: bool | None = None) -> tuple[str, memoryview]:
    """The dtype name and bytes an array is hashed as (see the module docstring).

    ``exact_float32`` may be passed when already known (the upload was float32).
    """
    a64 = np.ascontiguousarray(a, dtype="<f8")
    a32 = a64.astype("<f4")
    if exact_float32 is None:
        exact_float32 = bool(np.array_equal(a32, a64))
    # Adding +0.0 turns -0.0 into +0.0: the same height must be the same task.
    chosen = a32 if exact_float32 else a64 + 0.0
    if exact_float32:
        chosen += np.float32(0.0)
    return str(chosen.dtype), memoryview(chosen.tobytes() if not chosen.flags.c_contiguous
                                         else chosen.data).cast("B")


@functools.cache
def core_build() -> str:
    """``<version>+<first 16 hex of SHA-256 over the core's modules>``."""
    h = hashlib.sha256()
    root = Path(zwcore.__file__).parent
    for path in sorted(root.rglob("*.py")):
        h.update(path.relative_to(root).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    return f"{zwcore.__version__}+{h.hexdigest()[:16]}"


def task_id(operation: str, params: Mapping[str, Any],
            arrays: Mapping[str, np.ndarray] | None = None,
            exact_float32: Mapping[str, bool] | None = None) -> str:
    """Hex SHA-256 naming the result of ``operation`` on these inputs."""
    h = hashlib.sha256()
    head = {"operation": operation, "core_version": core_build(), "params": params}
    h.update(orjson.dumps(head, option=orjson.OPT_SORT_KEYS))
    for name in sorted(arrays or {}):
        a = (arrays or {})[name]
        dtype, data = canonical_bytes(a, (exact_float32 or {}).get(name))
        h.update(orjson.dumps({"array": name, "shape": list(a.shape), "dtype": dtype}))
        h.update(data)
    return h.hexdigest()
