"""The result of ``GET /v1/tasks/{task_id}``: whichever operation stored it."""

from __future__ import annotations

from typing import Annotated

from pydantic import Field

from service.schemas.arcs import ArcsResult
from service.schemas.mrr import MrrResult
from service.schemas.plans import ContourPlanResult, ScanlinePlanResult
from service.schemas.zmaps import ZMapResult

# `operation` tells the results apart, so generated clients get a tagged union.
TaskResult = Annotated[
    MrrResult | ScanlinePlanResult | ContourPlanResult | ArcsResult | ZMapResult,
    Field(discriminator="operation"),
]
