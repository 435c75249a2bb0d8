"""The viewer page: ``GET /viewer`` (and ``/`` redirects to it), with its script and style.

Plain HTML and JavaScript shipped in ``service/static``: no build step, nothing
fetched from elsewhere, so it works offline on a shop network. Not part of the
API document.
"""

from __future__ import annotations

from pathlib import Path

from fastapi import APIRouter
from fastapi.responses import FileResponse, RedirectResponse

from service.problems import Problem

STATIC = Path(__file__).resolve().parents[1] / "static"
#: The files served under /static, with their media types (nothing else is).
FILES = {"viewer.js": "text/javascript", "viewer.css": "text/css"}
_NO_STORE = {"Cache-Control": "no-cache"}

router = APIRouter(include_in_schema=False)


@router.get("/")
async def root() -> RedirectResponse:
    return RedirectResponse("/viewer", status_code=307)


@router.get("/viewer")
async def viewer() -> FileResponse:
    return FileResponse(STATIC / "viewer.html", media_type="text/html", headers=_NO_STORE)


@router.get("/static/{name}")
async def static(name: str) -> FileResponse:
    if name not in FILES:
        raise Problem(404, "Not found", f"no static file {name!r}", kind="not-found")
    return FileResponse(STATIC / name, media_type=FILES[name], headers=_NO_STORE)
