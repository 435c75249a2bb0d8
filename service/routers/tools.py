"""``GET /v1/tools``: the default tool library."""

from __future__ import annotations

from fastapi import APIRouter

from service.routers import responses
from service.schemas.common import ToolLibrary, ToolOut
from zwcore import DEFAULT_LIBRARY

router = APIRouter(prefix="/v1", tags=["tools"])


@router.get("/tools", response_model=ToolLibrary, operation_id="list_tools",
            summary="The default tool library", responses=responses())
async def list_tools() -> ToolLibrary:
    """Ball end mills Ø1-Ø20 and flat end mills Ø3-Ø20 with catalogue flute lengths."""
    return ToolLibrary(tools=[ToolOut(id=t.id, kind=t.kind, diameter=t.diameter,
                                      flute_length=t.flute_length) for t in DEFAULT_LIBRARY])
