"""`/map/floorplan`: a floor's plan image (PNG/JPEG) shown under its map, placed by two points
(`?floor=`: which floor; default: the default floor)."""

from __future__ import annotations

import asyncio
from typing import Annotated

from fastapi import APIRouter, Query, Request, Response, status
from pydantic import BaseModel, Field

from server.auth import Admin, Viewer
from server.deps import ServicesDep
from store.errors import NotFoundError
from store.floorplan import FloorPlanInfo, FloorPlanStore, Placement

router = APIRouter(prefix="/map/floorplan", tags=["map"])
XY = tuple[float, float]


class PlacementBody(BaseModel):
    """Two points known in the image and on the floor."""

    a_px: XY = Field(description="first point in the image: (column, row), pixels")
    a_m: XY = Field(description="the same point on the floor: world (x, y), metres")
    b_px: XY = Field(description="second point in the image: (column, row), pixels")
    b_m: XY = Field(description="the same point on the floor: world (x, y), metres")

    def placement(self) -> Placement:
        return Placement(self.a_px, self.a_m, self.b_px, self.b_m)


class FloorPlanPublic(BaseModel):
    width_px: int
    height_px: int
    media_type: str
    placement: PlacementBody
    metres_per_px: float = Field(description="scale, metres per pixel")
    rotation_rad: float = Field(description="the image's rotation about z, radians (REP-103)")
    center_m: XY = Field(description="the image centre on the floor: world (x, y), metres")
    width_m: float = Field(description="the image's width on the floor, metres")
    height_m: float = Field(description="the image's height on the floor, metres")


def _public(info: FloorPlanInfo) -> FloorPlanPublic:
    p = info.placement
    return FloorPlanPublic(
        width_px=info.width_px,
        height_px=info.height_px,
        media_type=info.media_type,
        placement=PlacementBody(a_px=p.a_px, a_m=p.a_m, b_px=p.b_px, b_m=p.b_m),
        metres_per_px=info.metres_per_px,
        rotation_rad=info.rotation_rad,
        center_m=info.center_m,
        width_m=info.width_m,
        height_m=info.height_m,
    )


FloorQuery = Annotated[
    str | None,
    Query(max_length=32, description="the floor's plan (floor ID; default: the default floor)"),
]


def _store(services: ServicesDep, floor: str | None) -> FloorPlanStore:
    store: FloorPlanStore = services.floorplans.of(floor)
    return store


@router.get("", response_class=Response, responses={200: {"content": {"image/png": {}}}})
def get_floorplan_image(services: ServicesDep, _: Viewer, floor: FloorQuery = None) -> Response:
    """The floor plan image as uploaded (404 when there is none)."""
    found = _store(services, floor).image()
    if found is None:
        raise NotFoundError("there is no floor plan")
    return Response(found[0], media_type=found[1])


@router.get("/placement")
def get_floorplan_placement(
    services: ServicesDep, _: Viewer, floor: FloorQuery = None
) -> FloorPlanPublic:
    """Where the floor plan lies on the floor (404 when there is none)."""
    info = _store(services, floor).info()
    if info is None:
        raise NotFoundError("there is no floor plan")
    return _public(info)


def image_type_of(data: bytes) -> str:
    """ "image/png" or "image/jpeg" from a file's first bytes (else what was sent, refused
    by the store naming the types it takes)."""
    if data.startswith(b"\x89PNG\r\n\x1a\n"):
        return "image/png"
    if data.startswith(b"\xff\xd8\xff"):
        return "image/jpeg"
    return "application/octet-stream"


@router.put(
    "",
    openapi_extra={
        "requestBody": {
            "content": {
                # octet-stream first: what client generators turn into a file argument (the
                # image type is then read from the file's first bytes)
                "application/octet-stream": {"schema": {"type": "string", "format": "binary"}},
                "image/png": {"schema": {"type": "string", "format": "binary"}},
                "image/jpeg": {"schema": {"type": "string", "format": "binary"}},
            },
            "required": True,
        }
    },
)
async def put_floorplan(
    request: Request,
    services: ServicesDep,
    _: Admin,
    a_px: Annotated[list[float], Query(description="first image point: column, row (px)")],
    a_m: Annotated[list[float], Query(description="its floor position: x, y (metres)")],
    b_px: Annotated[list[float], Query(description="second image point: column, row (px)")],
    b_m: Annotated[list[float], Query(description="its floor position: x, y (metres)")],
    floor: FloorQuery = None,
) -> FloorPlanPublic:
    """Upload the floor plan (the body is the PNG or JPEG file, `Content-Type` image/png,
    image/jpeg, or application/octet-stream: then told apart by the file's first bytes),
    placed by two points: e.g. `?a_px=0&a_px=0&a_m=0&a_m=10&...`."""
    for name, v in (("a_px", a_px), ("a_m", a_m), ("b_px", b_px), ("b_m", b_m)):
        if len(v) != 2:
            raise ValueError(f"floor plan placement: {name} needs two numbers, got {len(v)}")
    placement = Placement(
        (a_px[0], a_px[1]), (a_m[0], a_m[1]), (b_px[0], b_px[1]), (b_m[0], b_m[1])
    )
    media_type = request.headers.get("content-type", "").split(";")[0].strip()
    body = await request.body()
    if media_type == "application/octet-stream":
        media_type = image_type_of(body)
    info = await asyncio.to_thread(_store(services, floor).put, body, media_type, placement)
    return _public(info)


@router.patch("/placement")
def place_floorplan(
    body: PlacementBody, services: ServicesDep, _: Admin, floor: FloorQuery = None
) -> FloorPlanPublic:
    """Move the stored floor plan by two new points (404 when there is none)."""
    return _public(_store(services, floor).place(body.placement()))


@router.delete("", status_code=status.HTTP_204_NO_CONTENT)
def delete_floorplan(services: ServicesDep, _: Admin, floor: FloorQuery = None) -> Response:
    """Remove the floor plan (404 when there is none)."""
    if not _store(services, floor).delete():
        raise NotFoundError("there is no floor plan")
    return Response(status_code=status.HTTP_204_NO_CONTENT)
