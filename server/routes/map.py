"""`/map`: the whole map as map.json (recording format, with `radio`) or CSV."""

from __future__ import annotations

import asyncio
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Query, Request
from fastapi.responses import PlainTextResponse
from pydantic import BaseModel

from server.auth import Admin, Viewer
from server.crud.landmarks import decode_text, parse_map_csv, parse_map_text
from server.deps import ServicesDep
from server.errors import ConflictError
from server.models import LandmarkCreate, MapDocument

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
) -> ImportResult:
    """Replace the whole map (one transaction, audited): JSON body, or CSV with
    `Content-Type: text/csv` (UTF-8, a byte-order mark allowed). A map without landmarks is
    refused (409) unless `?allow_empty=true`."""
    raw = await request.body()
    ctype = request.headers.get("content-type", "application/json").split(";")[0].strip()
    items: list[LandmarkCreate]
    if ctype == "text/csv":
        text = decode_text(raw, source="map (CSV body)")
        items = await asyncio.to_thread(parse_map_csv, text, source="map (CSV body)")
    else:
        text = decode_text(raw, source="map")
        items = await asyncio.to_thread(parse_map_text, text, source="map")
    if not items and not allow_empty:
        raise ConflictError(
            "map: the new map has no landmarks; it would empty the site: send "
            "?allow_empty=true to do that"
        )
    count = await asyncio.to_thread(services.map.replace_all, items, actor=who.actor)
    return ImportResult(landmarks=count)
