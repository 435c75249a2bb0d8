"""The result of ``GET /v1/tasks/{task_id}``: whichever operation stored it; and the
state of an asynchronous task."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, Field

from service.schemas.arcs import ArcsResult
from service.schemas.cadfiles import DxfArcsResult, GcodeArcsResult
from service.schemas.common import ProblemDetails
from service.schemas.mrr import MrrResult
from service.schemas.plans import ContourPlanResult, ScanlinePlanResult
from service.schemas.simulate import SimulateResult
from service.schemas.zmaps import ZMapResult

# `operation` tells the results apart, so generated clients get a tagged union.
TaskResult = Annotated[
    MrrResult | ScanlinePlanResult | ContourPlanResult | ArcsResult | ZMapResult
    | SimulateResult | GcodeArcsResult | DxfArcsResult,
    Field(discriminator="operation"),
]


class TaskStatus(BaseModel):
    """Where an asynchronous task stands (``Prefer: respond-async``)."""

    task_id: str = Field(description="SHA-256 of the canonical request: the result's id")
    operation: str = Field(description="the operation that computes it")
    status: Literal["pending", "running", "done", "failed"] = Field(
        description="pending: waiting for a worker or memory; running: computing; done: the "
        "result is at /v1/tasks/{task_id}; failed: see error")
    progress: float = Field(ge=0, le=1, description="fraction done, by phase: 0 pending, "
                            "0.1 computing, 0.9 storing, 1 done")
    created: float = Field(description="when the task was accepted, Unix seconds")
    updated: float = Field(description="when its state last changed, Unix seconds")
    error: ProblemDetails | None = Field(None, description="why it failed")
