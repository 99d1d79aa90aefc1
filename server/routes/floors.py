"""`/floors`: the site's floors, each floor's versioned map, restore of an old version."""

from __future__ import annotations

import asyncio
from datetime import datetime
from typing import Annotated

from fastapi import APIRouter, Path, Query, Request, Response, status
from pydantic import BaseModel, Field

from server.auth import Admin, Viewer
from server.deps import ServicesDep
from store.landmarks import decode_text, parse_map_text
from store.map_versions import FloorMap
from store.models import (
    FLOOR_ID,
    Floor,
    FloorCreate,
    FloorPublic,
    FloorUpdate,
    LandmarkPublic,
)

router = APIRouter(prefix="/floors", tags=["floors"])
FloorId = Annotated[str, Path(pattern=FLOOR_ID, description="floor ID")]


class FloorMapPublic(BaseModel):
    """One floor's map at one version (VDA 5050: `mapId` = `floor`, `mapVersion` = `version`)."""

    floor: str
    version: int = Field(description="the map's version on this floor (1 is the first)")
    hash: str = Field(description="sha256 of the map's content, hex")
    t: datetime = Field(description="when this version was made (UTC)")
    actor: str = Field(description="who made it ('' for the first version)")
    action: str = Field(description="how: create, update, delete, import, restore, ...")
    current: bool = Field(description="this is the floor's map now")
    landmarks: list[LandmarkPublic] = Field(default=[], description="each carries `floor`")


class RestoreBody(BaseModel):
    version: int = Field(ge=1, description="the version whose content becomes the map again")


class FloorImportResult(BaseModel):
    landmarks: int
    version: int
    hash: str


def _public(services: ServicesDep, row: Floor) -> FloorPublic:
    version, digest = services.map_versions.current(row.id)
    return FloorPublic(
        id=row.id,
        name=row.name,
        level=row.level,
        height=row.height,
        version=version,
        hash=digest,
        landmarks=len(services.map.on_floor(row.id)),
    )


def _map(services: ServicesDep, fm: FloorMap) -> FloorMapPublic:
    return FloorMapPublic(
        floor=fm.floor,
        version=fm.version,
        hash=fm.hash,
        t=fm.t,
        actor=fm.actor,
        action=fm.action,
        current=fm.version == services.map_versions.version(fm.floor),
        landmarks=[LandmarkPublic.model_validate(r) for r in fm.landmarks],
    )


@router.get("")
def list_floors(services: ServicesDep, _: Viewer) -> list[FloorPublic]:
    """Every floor, lowest level first: `id`, `name`, `level`, `height`, its map's `version`
    and `hash`, its landmark count."""
    return [_public(services, f) for f in services.floors.list()]


@router.post("", status_code=status.HTTP_201_CREATED)
def create_floor(body: FloorCreate, services: ServicesDep, _: Admin) -> FloorPublic:
    """Add a floor (409 when its ID is taken)."""
    row = services.floors.create(body)
    services.map_versions.sync()
    return _public(services, row)


@router.get("/{floor_id}")
def get_floor(floor_id: FloorId, services: ServicesDep, _: Viewer) -> FloorPublic:
    return _public(services, services.floors.get(floor_id))


@router.patch("/{floor_id}")
def update_floor(
    floor_id: FloorId, body: FloorUpdate, services: ServicesDep, _: Admin
) -> FloorPublic:
    """Change its name, level or height (fields left out keep their value)."""
    return _public(services, services.floors.update(floor_id, body))


@router.delete("/{floor_id}", status_code=status.HTTP_204_NO_CONTENT)
def delete_floor(floor_id: FloorId, services: ServicesDep, _: Admin) -> Response:
    """Remove an empty floor (409 while landmarks hang on it, or for the last floor); its
    map versions go with it."""
    services.floors.delete(floor_id)
    services.map_versions.sync()
    return Response(status_code=status.HTTP_204_NO_CONTENT)


@router.get("/{floor_id}/map")
def get_floor_map(
    floor_id: FloorId,
    services: ServicesDep,
    _: Viewer,
    version: Annotated[int | None, Query(ge=1, description="an old version (default: now)")] = None,
) -> FloorMapPublic:
    """The floor's landmarks with the map's `version` and `hash` (`?version=N`: as they were
    at version N; 404 naming an unknown version)."""
    return _map(services, services.map_versions.get(floor_id, version))


@router.get("/{floor_id}/map/versions")
def list_versions(
    floor_id: FloorId,
    services: ServicesDep,
    _: Viewer,
    limit: Annotated[int, Query(ge=1, le=1000)] = 100,
) -> list[FloorMapPublic]:
    """The floor's map versions, newest first (without their landmarks)."""
    return [_map(services, fm) for fm in services.map_versions.history(floor_id, limit)]


@router.put(
    "/{floor_id}/map",
    openapi_extra={
        "requestBody": {
            "content": {
                "application/json": {"schema": {"$ref": "#/components/schemas/MapDocument"}}
            },
            "required": True,
        }
    },
)
async def import_floor_map(
    floor_id: FloorId,
    request: Request,
    services: ServicesDep,
    who: Admin,
    confirm: Annotated[bool, Query(description="accept a map without landmarks")] = False,
) -> FloorImportResult:
    """Replace this floor's landmarks (map.json body; a landmark naming no floor goes on
    this one, one naming another is 409); the other floors keep theirs. One transaction,
    one step of your undo. An empty map is 409 without `confirm=true`."""
    text = decode_text(await request.body(), source=f"map of floor {floor_id!r}")
    items = await asyncio.to_thread(parse_map_text, text, source=f"map of floor {floor_id!r}")
    count = await asyncio.to_thread(
        services.map_versions.replace_floor, floor_id, items, actor=who.actor, confirm=confirm
    )
    version, digest = services.map_versions.current(floor_id)
    return FloorImportResult(landmarks=count, version=version, hash=digest)


@router.post("/{floor_id}/map/restore")
def restore_floor_map(
    floor_id: FloorId,
    body: RestoreBody,
    services: ServicesDep,
    who: Admin,
    confirm: Annotated[bool, Query(description="required: the floor's map is replaced")] = False,
) -> FloorMapPublic:
    """Make an old version's content the floor's map again: audited (`restore`, one step
    of your undo), recorded as a new version, which is returned. 409 without
    `confirm=true`, when that version is the current content, or when one of its landmark
    IDs or radios is used on another floor now; 404 for an unknown version."""
    fm = services.map_versions.restore(floor_id, body.version, actor=who.actor, confirm=confirm)
    return _map(services, fm)
