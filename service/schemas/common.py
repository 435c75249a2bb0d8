"""Models shared by several operations: grids, tools, problems."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, StrictInt

# Request scalars are strict: "1", true or "yes" for a number or a flag are errors, as the
# schema says, not silently coerced (FastAPI validates the parsed body in Python mode, so
# model-wide strict=True would also refuse JSON arrays for tuples; these are per scalar).
FiniteFloat = Annotated[float, Field(allow_inf_nan=False, strict=True)]
Dtype = Literal["float32", "float64"]


class StrictModel(BaseModel):
    """Request models reject unknown fields, so a typo is an error, not a silent default."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class Grid(StrictModel):
    """A z-map: node ``(k, i)`` sits at ``(x0 + k*dx, y0 + i*dy)`` and holds ``z[i][k]``.

    Send either ``z`` (a list of rows) or ``shape``, ``dtype`` and ``z_b64``
    (little-endian row-major bytes in base64) for large grids.
    """

    model_config = ConfigDict(json_schema_extra={"examples": [
        {"x0": 0.0, "y0": 0.0, "dx": 1.0, "dy": 1.0, "z": [[0.0, 1.0], [2.0, 3.0]]}]})

    # Bounded so that every derived figure stays finite: a spacing of 1e300 overflowed
    # and one of 1e-300 divided by zero in the planners (500s), and a coarse level's
    # spacing or origin came back as null.
    x0: FiniteFloat = Field(0.0, ge=-1e6, le=1e6, description="x of node (0, 0), mm")
    y0: FiniteFloat = Field(0.0, ge=-1e6, le=1e6, description="y of node (0, 0), mm")
    dx: FiniteFloat = Field(ge=1e-6, le=1e6, description="node spacing along x, mm")
    dy: FiniteFloat = Field(ge=1e-6, le=1e6, description="node spacing along y, mm")
    # at least 2 x 2 nodes, said in the schema so generated clients know it too
    z: list[Annotated[list[FiniteFloat], Field(min_length=2)]] | None = Field(
        None, min_length=2, description="heights, one list per row (y); at least 2 x 2")
    shape: tuple[Annotated[StrictInt, Field(ge=2)], Annotated[StrictInt, Field(ge=2)]] | None = (
        Field(None, description="[ny, nx] of z_b64; at least 2 x 2"))
    dtype: Dtype | None = Field(None, description="element type of z_b64")
    z_b64: str | None = Field(None, description="little-endian row-major heights, base64")


#: A task id names a stored result (SHA-256, hex).
TASK_ID_PATTERN = "^[0-9a-f]{64}$"

GridTask = Annotated[str | None, Field(
    pattern=TASK_ID_PATTERN, description="instead of grid: the task id of a POST /v1/zmaps "
    "result (a z-map uploaded once, planned many times)")]


class GridOut(BaseModel):
    """A returned grid, in the encoding the request used."""

    x0: float
    y0: float
    dx: float
    dy: float
    nx: int
    ny: int
    interpolation: Literal["bilinear", "cell"] = Field(
        description="bilinear: surface through the nodes; cell: a flat dx x dy square per node")
    z: list[list[float]] | None = None
    shape: tuple[int, int] | None = None
    dtype: Dtype | None = None
    z_b64: str | None = None


ToolKind = Literal["ball", "flat"]


class ToolIn(StrictModel):
    """An end mill in the request's tool library (``GET /v1/tools`` entries can be sent
    back as they are)."""

    id: str = Field(min_length=1, max_length=64)
    kind: ToolKind | None = Field(
        None, description="optional; when given, the kind the plan takes: ball for the "
        "scan-line plan, flat for the contour plan")
    # 0.01 mm is the smallest micro end mill made; below it the planners' figures
    # (scallop heights, guard margins) lose their meaning in float64.
    diameter: FiniteFloat = Field(ge=0.01, le=1000, description="mm")
    flute_length: FiniteFloat = Field(ge=0.01, le=1000, description="length of cut, mm")
    # cutting data, used when a plan asks for tool paths (defaults: zwcore.toolpath)
    tool_number: StrictInt | None = Field(None, ge=1, le=9999, description="T and H word; "
                                          "default: the tool's place in the sequence")
    spindle_rpm: FiniteFloat | None = Field(None, gt=0, le=200_000, description="rev/min")
    feed: FiniteFloat | None = Field(None, gt=0, le=100_000, description="cutting feed, mm/min")
    plunge_feed: FiniteFloat | None = Field(None, gt=0, le=100_000,
                                            description="ramp and plunge feed, mm/min")
    ramp_angle_deg: FiniteFloat | None = Field(None, gt=0, lt=90,
                                               description="steepest ramp entry, degrees")


class ToolOut(BaseModel):
    id: str
    kind: ToolKind
    diameter: float
    flute_length: float


class ToolLibrary(BaseModel):
    tools: list[ToolOut]


class ProblemField(BaseModel):
    field: str = Field(
        description="What the client got wrong. A body field is its path inside the body "
        "(grid.z[1], tools[0].diameter, tolerance); a parameter or header is its name "
        "(task_id, grid_encoding, Authorization, Content-Length); body is the body as a whole")
    reason: str


class ProblemDetails(BaseModel):
    """RFC 9457 problem document returned for every error."""

    type: str = "about:blank"
    title: str
    status: int
    detail: str
    instance: str | None = None
    errors: list[ProblemField] | None = Field(
        None, description="each field at fault and why; on every 400, 401, 403, 413 and 422")
