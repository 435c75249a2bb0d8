"""Grid decoding and encoding at the HTTP boundary.

Decoding turns either encoding into a validated :class:`zwcore.ZMap`; encoding
writes a model back in the encoding the request used. Results are cached in
one canonical form (float64 base64) and rendered per request.
"""

from __future__ import annotations

import binascii
import io
from typing import Any

# pybase64 (SIMD) decodes and validates a 2048² float32 upload in ~1.5 ms where the
# standard library takes ~30 ms, the largest single cost of a large /v1/mrr call.
import numpy as np
import pybase64
from numpy.typing import NDArray

from service.schemas.common import Grid
from zwcore import ZMap
from zwcore.errors import InvalidInputError, LimitExceededError
from zwcore.grid.zmap import Interpolation

_DTYPES: dict[str, np.dtype[np.floating]] = {"float32": np.dtype("<f4"),
                                              "float64": np.dtype("<f8")}


def grid_encoding(grid: Grid) -> str:
    """``"rows"``, ``"float32"`` or ``"float64"``: how the request sent its heights."""
    return "rows" if grid.z is not None else str(grid.dtype)


def decode_grid(grid: Grid, max_cells: int, field: str = "grid") -> ZMap:
    """Validate a request grid and return it as a z-map (float64).

    Raises
    ------
    InvalidInputError
        Both or neither encoding, ragged rows, bad base64, a length that does not
        match ``shape`` and ``dtype``, non-finite heights.
    LimitExceededError
        More cells than ``max_cells``.
    """
    if (grid.z is None) == (grid.z_b64 is None):
        raise InvalidInputError(field, "give exactly one of z (rows) or z_b64 (with shape, dtype)")
    if grid.z is not None:
        if grid.shape is not None or grid.dtype is not None:
            raise InvalidInputError(field, "shape and dtype go with z_b64, not with z rows")
        rows = grid.z
        ny = len(rows)
        nx = len(rows[0]) if ny else 0
        if ny * nx > max_cells:
            raise LimitExceededError(f"{field}.z", f"{ny} x {nx} grid exceeds {max_cells} cells")
        for i, row in enumerate(rows):
            if len(row) != nx:
                raise InvalidInputError(f"{field}.z[{i}]",
                                        f"ragged rows: row {i} has {len(row)} values, row 0 {nx}")
        z = np.array(rows, dtype=np.float64) if ny else np.zeros((0, 0))
        where = f"{field}.z"
    else:
        if grid.shape is None or grid.dtype is None:
            missing = "shape" if grid.shape is None else "dtype"
            raise InvalidInputError(f"{field}.{missing}", "required with z_b64")
        ny, nx = grid.shape
        # Checked before any size arithmetic: a huge side times a zero side is no cells,
        # and numpy cannot even describe a (2**63, 0) array (it raised a 500).
        if ny < 2 or nx < 2:
            raise InvalidInputError(f"{field}.shape",
                                    f"grid must be at least 2 x 2 nodes, got {[ny, nx]}")
        if ny * nx > max_cells:
            raise LimitExceededError(f"{field}.shape",
                                     f"{ny} x {nx} grid exceeds {max_cells} cells")
        dtype = _DTYPES[grid.dtype]
        try:
            raw = pybase64.b64decode(grid.z_b64 or "", validate=True)
        except (binascii.Error, ValueError):
            raise InvalidInputError(f"{field}.z_b64", "is not valid base64") from None
        expected = ny * nx * dtype.itemsize
        if len(raw) != expected:
            raise InvalidInputError(
                f"{field}.z_b64", f"decodes to {len(raw)} bytes; shape {[ny, nx]} of "
                f"{grid.dtype} needs {expected}")
        z = np.frombuffer(raw, dtype=dtype).reshape(ny, nx).astype(np.float64)
        where = f"{field}.z_b64"
    try:
        return ZMap(z, grid.x0, grid.y0, grid.dx, grid.dy)
    except InvalidInputError as exc:
        name = where if exc.field == "z" else f"{field}.{exc.field}"
        raise InvalidInputError(name, exc.reason) from None


def canonical_grid(z: NDArray[np.float64], *, x0: float, y0: float, dx: float, dy: float,
                   interpolation: Interpolation) -> dict[str, Any]:
    """A grid as cached: float64 base64, rendered per request by :func:`render_grids`."""
    zz = np.ascontiguousarray(z, dtype="<f8")
    ny, nx = zz.shape
    return {"x0": x0, "y0": y0, "dx": dx, "dy": dy, "nx": nx, "ny": ny,
            "interpolation": interpolation, "shape": [ny, nx], "dtype": "float64",
            "z_b64": pybase64.b64encode(zz.tobytes()).decode("ascii")}


def _float32_upward(z: NDArray[np.float64]) -> NDArray[np.float32]:
    # Rounding a stage model to float32 must never move it down into the part.
    f = z.astype(np.float32)
    below = f.astype(np.float64) < z
    if below.any():
        f[below] = np.nextafter(f[below], np.float32(np.inf))
    return f


def _render(grid: dict[str, Any], encoding: str) -> dict[str, Any]:
    if encoding == "float64":
        return grid
    ny, nx = grid["shape"]
    z = np.frombuffer(pybase64.b64decode(grid["z_b64"]), dtype="<f8").reshape(ny, nx)
    out = {k: v for k, v in grid.items() if k not in ("shape", "dtype", "z_b64")}
    if encoding == "rows":
        out["z"] = z.tolist()
    else:
        out["shape"] = [ny, nx]
        out["dtype"] = "float32"
        out["z_b64"] = pybase64.b64encode(_float32_upward(z).astype("<f4").tobytes()).decode()
    return out


def render_grids(node: Any, encoding: str) -> Any:
    """Re-encode every cached grid inside a result for the requesting client."""
    if encoding == "float64":
        return node
    if isinstance(node, dict):
        if "z_b64" in node and "interpolation" in node:
            return _render(node, encoding)
        return {k: render_grids(v, encoding) for k, v in node.items()}
    if isinstance(node, list):
        return [render_grids(v, encoding) for v in node]
    return node


#: Element kinds a binary grid may hold: floats, and integers (heights in whole units).
_NPY_KINDS = {"f": "floating point", "i": "integer", "u": "unsigned integer"}


def decode_npy(data: bytes, max_cells: int, field: str = "grid") -> NDArray[Any]:
    """Heights from the bytes of one ``.npy`` file (never a pickle: ``allow_pickle=False``).

    The header is read first, so a shape over the limit is refused before its data
    is looked at.

    Returns
    -------
    z : (ny, nx) array of the file's numeric dtype

    Raises
    ------
    InvalidInputError
        Not an ``.npy`` file (a pickle, an ``.npz``, text), object or other non-numeric
        dtype, not 2-D, fewer than 2 x 2 nodes, truncated data.
    LimitExceededError
        More than ``max_cells`` nodes.
    """
    if data[:6] != b"\x93NUMPY":
        what = ("a pickle" if data[:1] == b"\x80" else "an .npz archive" if data[:2] == b"PK"
                else "empty" if not data else "not an .npy file")
        raise InvalidInputError(field, f"{what}: send one array as .npy (numpy.save), "
                                "numeric dtype, shape (ny, nx)")
    buf = io.BytesIO(data)
    try:
        version = np.lib.format.read_magic(buf)
        if version == (1, 0):
            shape, _, dtype = np.lib.format.read_array_header_1_0(buf)
        elif version == (2, 0):
            shape, _, dtype = np.lib.format.read_array_header_2_0(buf)
        else:
            raise ValueError(f".npy format version {version} is not supported; use 1.0 or 2.0")
    except (ValueError, SyntaxError, EOFError, TypeError) as exc:
        raise InvalidInputError(field, f"unreadable .npy header ({exc})") from None
    if dtype.hasobject or dtype.kind not in _NPY_KINDS or dtype.fields is not None:
        raise InvalidInputError(field, f"dtype {dtype} is not a number type; send float32 or "
                                "float64 (object arrays and pickles are never loaded)")
    if len(shape) != 2:
        raise InvalidInputError(field, f"shape {list(shape)}: a grid is 2-D, (ny, nx)")
    ny, nx = shape
    if ny < 2 or nx < 2:
        raise InvalidInputError(field, f"grid must be at least 2 x 2 nodes, got {[ny, nx]}")
    if ny * nx > max_cells:
        raise LimitExceededError(field, f"{ny} x {nx} grid exceeds {max_cells} cells")
    try:
        z = np.load(io.BytesIO(data), allow_pickle=False)
    except (ValueError, EOFError, OSError) as exc:
        raise InvalidInputError(field, f"unreadable .npy data ({exc})") from None
    return np.asarray(z)


def zmap_from_heights(z: NDArray[Any], grid: Grid, field: str = "grid") -> ZMap:
    """A z-map of uploaded heights placed by a request grid's ``x0, y0, dx, dy``."""
    if grid.z is not None or grid.z_b64 is not None or grid.shape is not None:
        raise InvalidInputError(field, "the heights came as .npy: give only x0, y0, dx, dy")
    try:
        return ZMap(z, grid.x0, grid.y0, grid.dx, grid.dy)
    except InvalidInputError as exc:
        raise InvalidInputError(field if exc.field == "z" else exc.field, exc.reason) from None


def stored_grid(node: dict[str, Any]) -> tuple[NDArray[np.float64], dict[str, Any]]:
    """Heights and geometry of a grid as cached (:func:`canonical_grid`)."""
    ny, nx = node["shape"]
    z = np.frombuffer(pybase64.b64decode(node["z_b64"]), dtype="<f8").reshape(ny, nx)
    return z, {k: node[k] for k in ("x0", "y0", "dx", "dy", "interpolation")}


def npy_bytes(z: NDArray[np.float64], dtype: str = "float64") -> bytes:
    """A grid as an ``.npy`` file; float32 rounded upward (a model never moves into the part)."""
    arr = _float32_upward(z).astype("<f4") if dtype == "float32" else z.astype("<f8")
    buf = io.BytesIO()
    np.save(buf, np.ascontiguousarray(arr), allow_pickle=False)
    return buf.getvalue()
