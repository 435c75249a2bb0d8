"""The result of ``GET /v1/tasks/{task_id}``: whichever operation stored it."""

from __future__ import annotations

from typing import Annotated

from pydantic import Field

from service.schemas.mrr import MrrResult

# Each operation adds its result model here as it lands; `operation` tells them apart.
TaskResult = Annotated[MrrResult, Field(discriminator=None)]
