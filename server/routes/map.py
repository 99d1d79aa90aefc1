"""`/map`: the whole map as map.json (recording format, with `radio`) or CSV."""

from __future__ import annotations

import asyncio
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Query, Request
from fastapi.responses import PlainTextResponse
from pydantic import BaseModel

from server.auth import Admin, Viewer
from server.deps import ServicesDep
from store.landmarks import decode_text, parse_map_csv, parse_map_text
from store.models import LandmarkCreate, MapDocument

router = APIRouter(prefix="/map", tags=["map"])


class ImportResult(BaseModel):
    landmarks: int


@router.get(
    "",
    response_model=MapDocument,
    responses={200: {"content": {"text/csv": {"schema": {"type": "string"}}}}},
)
def export_map(
    services: ServicesDep, _: Viewer, format: Literal["json", "csv"] = Query("json")
) -> Any:
    """The map as map.json (`?format=csv` for CSV: `id,x,y,z,radio,locked,note`)."""
    if format == "csv":
        return PlainTextResponse(services.map.export_csv(), media_type="text/csv")
    return services.map.export_json()


@router.put(
    "",
    openapi_extra={
        "requestBody": {
            "content": {
                # a reference, not the model's own schema: its `$defs` breaks ReDoc
                "application/json": {"schema": {"$ref": "#/components/schemas/MapDocument"}},
                "text/csv": {"schema": {"type": "string"}},
            },
            "required": True,
        }
    },
)
async def import_map(
    request: Request,
    services: ServicesDep,
    who: Admin,
    allow_empty: Annotated[
        bool, Query(description="accept a map without landmarks (empties the site)")
    ] = False,
    confirm: Annotated[bool, Query(description="the same as allow_empty")] = False,
) -> ImportResult:
    """Replace the whole map (one transaction, audited, one step of your undo): JSON body,
    or CSV with `Content-Type: text/csv` (UTF-8, a byte-order mark allowed). A map without
    landmarks is refused (409) unless `?allow_empty=true` (or `confirm=true`)."""
    raw = await request.body()
    ctype = request.headers.get("content-type", "application/json").split(";")[0].strip()
    items: list[LandmarkCreate]
    if ctype == "text/csv":
        text = decode_text(raw, source="map (CSV body)")
        items = await asyncio.to_thread(parse_map_csv, text, source="map (CSV body)")
    else:
        text = decode_text(raw, source="map")
        items = await asyncio.to_thread(parse_map_text, text, source="map")
    count = await asyncio.to_thread(
        services.map.replace_all, items, actor=who.actor, confirm=allow_empty or confirm
    )
    return ImportResult(landmarks=count)


@router.delete("")
async def clear_map(
    services: ServicesDep,
    who: Admin,
    confirm: bool = Query(False, description="required: the site is left without landmarks"),
) -> ImportResult:
    """Remove every landmark (one step of your undo); 409 without `confirm=true`."""
    count = await asyncio.to_thread(services.map.replace_all, [], actor=who.actor, confirm=confirm)
    return ImportResult(landmarks=count)
