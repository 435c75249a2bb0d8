"""A grid-taking request in any of its forms: JSON, an ``.npy`` body, a multipart
upload, or ``grid_task`` naming a stored z-map.

JSON stays FastAPI's: validated against the request model, documented by it.
An ``application/x-npy`` body or a ``multipart/form-data`` upload is turned into
the same JSON request without the heights (the other fields come as query
parameters or form fields), which FastAPI then validates as usual; the heights,
decoded from the ``.npy`` once, wait in the request's state. So every form gets
the same validation and the same problem documents, and the heights of a large
grid never pass through JSON or base64.
"""

from __future__ import annotations

import typing
from collections.abc import Callable, Coroutine
from typing import Any

import anyio
import numpy as np
import orjson
from fastapi import Request, Response
from fastapi.routing import APIRoute
from pydantic import BaseModel
from starlette.datastructures import UploadFile

from service.grids import decode_grid, decode_npy, grid_encoding, stored_grid, zmap_from_heights
from service.problems import Problem
from service.schemas.common import Grid
from service.settings import Settings
from service.store import TaskStore
from zwcore import ZMap
from zwcore.errors import InvalidInputError

NPY = "application/x-npy"
MULTIPART = "multipart/form-data"
GEOMETRY = ("x0", "y0", "dx", "dy")
_UPLOAD = "grid_upload"


def _media_type(request: Request) -> str:
    return request.headers.get("content-type", "").split(";")[0].strip().lower()


def _field_value(model: type[BaseModel], name: str, text: str) -> Any:
    """A query parameter or form field as the JSON value it stands for: numbers,
    ``true``/``false`` and JSON arrays/objects parsed, strings kept (a field the model
    types as a string is never parsed, so an id of digits stays an id)."""
    field = model.model_fields.get(name)
    if field is not None and _is_text(field.annotation):
        return text
    try:
        return orjson.loads(text)
    except orjson.JSONDecodeError:
        return text


def _is_text(annotation: Any) -> bool:
    if annotation is str:
        return True
    args = typing.get_args(annotation)
    if typing.get_origin(annotation) is typing.Literal:
        return all(isinstance(a, str) for a in args)
    return bool(args) and all(_is_text(a) or a is type(None) for a in args)


async def _fields_and_heights(request: Request, model: type[BaseModel]
                              ) -> tuple[dict[str, str], bytes | None, str]:
    """Text fields (query, then form) and the ``.npy`` bytes with the name of their part."""
    fields = dict(request.query_params)
    if _media_type(request) == NPY:
        return fields, await request.body(), "body"
    data: bytes | None = None
    try:
        form = await request.form(max_files=8, max_fields=64)
    except Exception as exc:  # python-multipart's errors are not one family
        raise InvalidInputError("body", f"unreadable multipart/form-data ({exc})") from None
    try:
        for key, value in form.multi_items():
            if key in fields or (key == "grid" and data is not None):
                raise InvalidInputError(key, "given twice")
            if key == "grid":
                if not isinstance(value, UploadFile):
                    raise InvalidInputError("grid", "must be a file part holding an .npy array")
                data = await value.read()
            elif isinstance(value, UploadFile):  # a field sent as a file, e.g. tools.json
                raw = await value.read()
                try:
                    fields[key] = raw.decode("utf-8")
                except UnicodeDecodeError:
                    raise InvalidInputError(key, "is not UTF-8 text") from None
            else:
                fields[key] = value
    finally:
        await form.close()
    if data is None and "grid_task" not in fields:
        raise InvalidInputError("grid", "missing: send the heights as a file part named grid "
                                "(.npy), or grid_task")
    return fields, data, "grid"


async def _as_json_request(request: Request, model: type[BaseModel]) -> Request:
    """The ``.npy`` or multipart request as its JSON equivalent without the heights."""
    settings: Settings = request.app.state.settings
    fields, data, part = await _fields_and_heights(request, model)
    body: dict[str, Any] = {k: _field_value(model, k, v) for k, v in fields.items()
                            if k not in GEOMETRY}
    geometry = {k: _field_value(Grid, k, fields[k]) for k in GEOMETRY if k in fields}
    state = request.scope.setdefault("state", {})
    if data is not None:
        z = await anyio.to_thread.run_sync(decode_npy, data, settings.max_grid_cells, part)
        body["grid"] = geometry
        state[_UPLOAD] = (z, part)
    elif geometry:
        raise InvalidInputError(next(iter(geometry)), "goes with an uploaded grid, not grid_task")
    raw = orjson.dumps(body)
    headers = [(k, v) for k, v in request.scope["headers"]
               if k not in (b"content-type", b"content-length")]
    headers += [(b"content-type", b"application/json"), (b"content-length", str(len(raw)).encode())]
    scope = {**request.scope, "headers": headers, "state": state}

    async def receive() -> dict[str, Any]:
        return {"type": "http.request", "body": raw, "more_body": False}

    return Request(scope, receive)


class GridRoute(APIRoute):
    """A route whose JSON body may also come as ``application/x-npy`` or multipart."""

    def get_route_handler(self) -> Callable[[Request], Coroutine[Any, Any, Response]]:
        handler = super().get_route_handler()
        annotation = self.body_field.field_info.annotation if self.body_field else None
        model = (annotation if isinstance(annotation, type) and issubclass(annotation, BaseModel)
                 else None)

        async def route(request: Request) -> Response:
            media = _media_type(request)
            if model is not None and media in (NPY, MULTIPART):
                request = await _as_json_request(request, model)
            elif media and media != "application/json" and not media.endswith("+json"):
                raise Problem(415, "Unsupported media type",
                              f"{media} is not taken here: send application/json, {NPY} "
                              f"(an .npy body) or {MULTIPART}", kind="unsupported-media-type",
                              errors=[{"field": "content-type", "reason": f"{media} unsupported"}])
            return await handler(request)

        return route


async def request_zmap(request: Request, grid: Grid | None, grid_task: str | None,
                       settings: Settings, store: TaskStore) -> tuple[ZMap, str]:
    """The request's z-map and the encoding its returned grids take.

    Exactly one of: the grid (JSON or uploaded ``.npy``) or ``grid_task``, the id of
    a ``POST /v1/zmaps`` task still in the store (422 naming ``grid_task`` otherwise).
    """
    if (grid is None) == (grid_task is None):
        raise InvalidInputError("grid", "give exactly one of grid (JSON or .npy) or grid_task")
    if grid_task is not None:
        return await anyio.to_thread.run_sync(_stored_zmap, store, grid_task), "float64"
    assert grid is not None
    upload = getattr(request.state, _UPLOAD, None)
    if upload is not None:
        z, part = upload
        zmap = await anyio.to_thread.run_sync(zmap_from_heights, z, grid, part)
        # float32 heights are hashed without a check and come back as float32 base64
        return zmap, "float32" if z.dtype == np.float32 else "float64"
    return (await anyio.to_thread.run_sync(decode_grid, grid, settings.max_grid_cells),
            grid_encoding(grid))


def _stored_zmap(store: TaskStore, task_id: str) -> ZMap:
    body = store.get(task_id)
    if body is None:
        raise InvalidInputError("grid_task", f"no stored task {task_id} (unknown, or evicted "
                                "from the cache: upload the STL or grid again)")
    result = orjson.loads(body)
    if result.get("operation") != "zmap":
        raise InvalidInputError("grid_task", f"task {task_id} is a {result.get('operation')} "
                                "task, not a z-map (POST /v1/zmaps)")
    z, geo = stored_grid(result["grid"])
    return ZMap(z, geo["x0"], geo["y0"], geo["dx"], geo["dy"])


def binary_grid_openapi(model: type[BaseModel]) -> dict[str, Any]:
    """``openapi_extra`` of a :class:`GridRoute`: the ``.npy`` and multipart forms, their
    query parameters and form fields, beside the JSON body FastAPI documents."""
    fields = {name: f for name, f in model.model_fields.items() if name not in ("grid",)}
    geometry = {name: Grid.model_fields[name] for name in GEOMETRY}

    def describe(name: str, f: Any) -> str:
        head = (f.description or "").strip()
        return (f"{head} (as in the JSON body; numbers, true/false and JSON arrays "
                f"as their JSON text)" if name not in GEOMETRY else head)

    params = [{"name": name, "in": "query", "required": False,
               "description": "With an .npy or multipart body only: " + describe(name, f),
               "schema": {"type": "string"}}
              for name, f in {**geometry, **fields}.items()]
    form = {name: {"type": "string", "description": describe(name, f)}
            for name, f in {**geometry, **fields}.items()}
    form["grid"] = {"type": "string", "format": "binary",
                    "description": "the heights as .npy (numpy.save): shape (ny, nx), float32, "
                    "float64 or integer; never a pickle"}
    return {
        "parameters": params,
        "requestBody": {"content": {
            NPY: {"schema": {"type": "string", "format": "binary",
                             "description": "the heights as .npy; x0, y0, dx, dy and the "
                             "other fields as query parameters"}},
            MULTIPART: {"schema": {"type": "object", "properties": form}},
        }},
    }
