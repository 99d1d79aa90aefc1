"""`/map`: the whole map as map.json (recording format, with `radio`) or CSV."""

from __future__ import annotations

import asyncio
import json
from typing import Any, Literal

from fastapi import APIRouter, Query, Request
from fastapi.responses import PlainTextResponse
from pydantic import BaseModel

from server.auth import Admin, Viewer
from server.crud.landmarks import parse_map_csv, parse_map_json
from server.deps import ServicesDep
from server.models import LandmarkCreate, MapDocument

router = APIRouter(prefix="/map", tags=["map"])


class ImportResult(BaseModel):
    landmarks: int


@router.get("", response_model=MapDocument)
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
    confirm: bool = Query(False, description="required when the new map has no landmarks"),
) -> ImportResult:
    """Replace the whole map (one transaction, audited, one step of your undo): JSON body,
    or CSV with `Content-Type: text/csv`. A map without landmarks needs `confirm=true`
    (409 otherwise)."""
    raw = await request.body()
    ctype = request.headers.get("content-type", "application/json").split(";")[0].strip()
    text = raw.decode("utf-8", errors="strict") if raw else ""
    items: list[LandmarkCreate]
    if ctype == "text/csv":
        items = parse_map_csv(text, source="map (CSV body)")
    else:
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise ValueError(f"map: body is not JSON: {exc}") from None
        items = parse_map_json(data, source="map")
    count = await asyncio.to_thread(
        services.map.replace_all, items, actor=who.actor, confirm=confirm
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
