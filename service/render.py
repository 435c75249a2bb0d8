"""Stored results streamed to the client, grids re-encoded piece by piece.

A result is stored once, with its grids as float64 base64. A client that asked
for rows gets every height as a JSON number: for a 2048² plan with models that
is over a gigabyte of text, which was built whole, on the event loop. Here the
body is produced in pieces by a generator that Starlette runs in worker threads
(``StreamingResponse`` iterates a plain iterator in the thread pool): the loop
only forwards bytes, and memory holds one block of rows at a time.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import orjson
import pybase64

from service.compute import TRIM_AFTER_BYTES, want_trim
from service.grids import render_grids

#: Bytes per piece of a stored body sent as it is.
CHUNK_BYTES = 1 << 20
#: Heights per piece of a grid sent as rows.
ROW_BLOCK_VALUES = 1 << 16
_MARK = "\u0000zw-grid-{}\u0000"


def _is_grid(node: Any) -> bool:
    return isinstance(node, dict) and "z_b64" in node and "interpolation" in node


def _skeleton(node: Any, grids: list[dict[str, Any]]) -> Any:
    """The result with each grid replaced by a marker string, the grids collected."""
    if _is_grid(node):
        grids.append(node)
        return _MARK.format(len(grids) - 1)
    if isinstance(node, dict):
        return {k: _skeleton(v, grids) for k, v in node.items()}
    if isinstance(node, list):
        return [_skeleton(v, grids) for v in node]
    return node


def _rows(grid: dict[str, Any]) -> Iterator[bytes]:
    """One grid as ``{..., "z": [[...], ...]}``, in blocks of rows; the same JSON as
    :func:`service.grids.render_grids` would give (orjson writes numpy float64 as it
    writes Python floats)."""
    ny, nx = grid["shape"]
    z = np.frombuffer(pybase64.b64decode(grid["z_b64"]), dtype="<f8").reshape(ny, nx)
    head = {k: v for k, v in grid.items() if k not in ("shape", "dtype", "z_b64")}
    yield orjson.dumps(head)[:-1] + (b',"z":[' if head else b'"z":[')
    step = max(1, ROW_BLOCK_VALUES // max(nx, 1))
    for a in range(0, ny, step):
        block = orjson.dumps(z[a:a + step], option=orjson.OPT_SERIALIZE_NUMPY)[1:-1]
        yield block if a == 0 else b"," + block
    yield b"]}"


def stream_body(body: bytes, encoding: str) -> Iterator[bytes]:
    """The JSON of a stored result for a client that wants ``encoding`` grids."""
    large = len(body) >= TRIM_AFTER_BYTES
    try:
        if encoding == "float64" or b'"z_b64"' not in body:
            view = memoryview(body)
            for a in range(0, len(body), CHUNK_BYTES):
                yield bytes(view[a:a + CHUNK_BYTES])
            return
        grids: list[dict[str, Any]] = []
        skeleton = orjson.dumps(_skeleton(orjson.loads(body), grids))
        del body
        for index, grid in enumerate(grids):
            before, skeleton = skeleton.split(orjson.dumps(_MARK.format(index)), 1)
            yield before
            if encoding == "rows":
                yield from _rows(grid)
            else:
                yield orjson.dumps(render_grids(grid, encoding))
            grids[index] = {}  # its heights are sent: let them go
        yield skeleton
    finally:
        if large:
            want_trim()  # the rendering's buffers are freed: the idle trimmer may run
