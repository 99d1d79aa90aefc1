"""`/zones` (polygons on the floor, with enter/exit/dwell events) and `/history` (where the
robots went: poses kept about once a second, by time range; a coverage heatmap)."""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Annotated

from fastapi import APIRouter, Path, Query, status
from pydantic import BaseModel, BeforeValidator, Field

from live.zones_history import grid_from_cells
from server.auth import Admin, Viewer
from server.deps import ServicesDep
from store.models import PoseRecord, ZoneRecord

router = APIRouter(tags=["zones and history"])
ZoneId = Annotated[int, Path(ge=1, le=2**31, description="zone id")]


def _iso_time(value: object) -> object:
    """A time given as ISO 8601 text; a bare number (which pydantic would read as seconds
    since 1970) is refused, as the schema's `date-time` format says."""
    if isinstance(value, str):
        try:
            float(value)
        except ValueError:
            return value
        raise ValueError(f"{value!r} is no ISO 8601 time (e.g. 2026-12-07T16:00:00Z)")
    return value


Since = Annotated[
    datetime | None,
    BeforeValidator(_iso_time),
    Query(description="from (ISO 8601; UTC when no offset)"),
]
Until = Annotated[
    datetime | None, BeforeValidator(_iso_time), Query(description="until, excluded (ISO 8601)")
]


class ZoneCreate(BaseModel):
    """A zone: a polygon on the floor, world frame (x, y metres), at least 3 points."""

    name: str = Field(min_length=1, max_length=64)
    polygon: list[tuple[float, float]] = Field(min_length=3, max_length=1000)
    floor: str = Field(default="", max_length=64, description="the site's floor ('' for one)")
    dwell_s: float | None = Field(
        default=None,
        gt=0,
        le=86_400,
        description="a zone_dwell event when a robot stays longer than this, seconds",
    )


class ZoneUpdate(BaseModel):
    """The fields to change; those left out keep their value (`dwell_s: null` drops the
    dwell limit)."""

    name: str | None = Field(default=None, min_length=1, max_length=64)
    polygon: list[tuple[float, float]] | None = Field(default=None, min_length=3, max_length=1000)
    floor: str | None = Field(default=None, max_length=64)
    dwell_s: float | None = Field(default=None, gt=0, le=86_400)


class ZonePublic(ZoneCreate):
    id: int
    created_at: datetime


class PosePoint(BaseModel):
    """A kept pose."""

    robot: str
    t: datetime = Field(description="wall clock, UTC")
    t_ns: int = Field(description="the site clock, nanoseconds (as the live poses)")
    x: float = Field(description="metres")
    y: float = Field(description="metres")
    theta: float = Field(description="radians, REP-103")
    sigma_m: float | None = Field(description="1-sigma position error, metres")
    mode: str
    floor: str = Field(description="the floor whose map frame x, y are in")


class Coverage(BaseModel):
    """Kept poses counted per cell: `counts[row][col]` is the cell whose corner is at
    (x0 + col * cell_m, y0 + row * cell_m)."""

    x0: float
    y0: float
    cell_m: float
    poses: int
    counts: list[list[int]]


def _zone(z: ZoneRecord) -> ZonePublic:
    assert z.id is not None  # stored
    return ZonePublic(
        id=z.id,
        name=z.name,
        polygon=[(p[0], p[1]) for p in z.polygon],
        floor=z.floor,
        dwell_s=z.dwell_s,
        created_at=z.created_at,
    )


def _utc(t: datetime | None) -> datetime | None:
    """A time given without an offset is UTC."""
    if t is None or t.tzinfo is not None:
        return t
    return t.replace(tzinfo=UTC)


@router.get("/zones")
def list_zones(services: ServicesDep, _: Viewer) -> list[ZonePublic]:
    return [_zone(z) for z in services.zones.list()]


@router.post("/zones", status_code=status.HTTP_201_CREATED)
def create_zone(body: ZoneCreate, services: ServicesDep, _: Admin) -> ZonePublic:
    """A new zone (409 when the name is taken; 422 naming a bad polygon; 404 naming an
    unknown floor)."""
    if body.floor:
        services.floors.check(body.floor, what="zone")
    z = services.zones.create(body.name, body.polygon, floor=body.floor, dwell_s=body.dwell_s)
    return _zone(z)


@router.get("/zones/{zone_id}")
def get_zone(zone_id: ZoneId, services: ServicesDep, _: Viewer) -> ZonePublic:
    return _zone(services.zones.get(zone_id))


@router.patch("/zones/{zone_id}")
def update_zone(zone_id: ZoneId, body: ZoneUpdate, services: ServicesDep, _: Admin) -> ZonePublic:
    """Rename, reshape, move to a floor or change the dwell limit (409 when the name is
    taken; 422 naming a bad polygon)."""
    fields = body.model_fields_set
    if body.floor:
        services.floors.check(body.floor, what="zone")
    z = services.zones.update(
        zone_id,
        name=body.name,
        polygon=body.polygon,
        floor=body.floor,
        dwell_s=body.dwell_s,
        clear_dwell="dwell_s" in fields and body.dwell_s is None,
    )
    return _zone(z)


@router.delete("/zones/{zone_id}", status_code=status.HTTP_204_NO_CONTENT)
def delete_zone(zone_id: ZoneId, services: ServicesDep, _: Admin) -> None:
    services.zones.delete(zone_id)


def _range(
    since: datetime | None, until: datetime | None
) -> tuple[datetime | None, datetime | None]:
    since, until = _utc(since), _utc(until)
    if since is not None and until is not None and until <= since:
        raise ValueError(f"history: until ({until}) must be after since ({since})")
    return since, until


def _poses(
    services: ServicesDep,
    robot: str | None,
    since: datetime | None,
    until: datetime | None,
    limit: int,
    floor: str | None,
) -> list[PoseRecord]:
    since, until = _range(since, until)
    return services.pose_history.query(
        robot=robot, since=since, until=until, limit=limit, floor=floor
    )


FloorFilter = Annotated[
    str | None, Query(max_length=32, description="only poses on this floor (floor ID)")
]


@router.get("/history/poses")
def pose_history(
    services: ServicesDep,
    _: Viewer,
    since: Since = None,
    until: Until = None,
    robot: str | None = Query(None, max_length=64),
    limit: int = Query(10_000, ge=1, le=100_000),
    max_points: int | None = Query(
        None,
        ge=2,
        le=100_000,
        description="at most this many, spread evenly over the whole range (every k-th kept "
        "pose; `limit` then does not apply): a week of history in a few thousand points",
    ),
    floor: FloorFilter = None,
) -> list[PosePoint]:
    """Kept poses oldest first (about one a second a robot while it has a pose)."""
    if max_points is not None:
        since, until = _range(since, until)
        poses = services.pose_history.thinned(
            robot=robot, since=since, until=until, max_points=max_points, floor=floor
        )[0]
    else:
        poses = _poses(services, robot, since, until, limit, floor)
    return [
        PosePoint(
            robot=p.robot,
            t=p.t.replace(tzinfo=UTC),
            t_ns=p.t_ns,
            x=p.x,
            y=p.y,
            theta=p.theta,
            sigma_m=p.sigma_m,
            mode=p.mode,
            floor=p.floor,
        )
        for p in poses
    ]


@router.get("/history/coverage")
def history_coverage(
    services: ServicesDep,
    _: Viewer,
    since: Since = None,
    until: Until = None,
    robot: str | None = Query(None, max_length=64),
    cell_m: float = Query(0.5, ge=0.05, le=10.0, description="cell size, metres"),
    floor: FloorFilter = None,
) -> Coverage:
    """Where the robots went: every kept pose of the range counted per floor cell (a
    heatmap; counted in the database, however long the range)."""
    since, until = _range(since, until)
    cells, n = services.pose_history.cell_counts(
        cell_m, robot=robot, since=since, until=until, floor=floor
    )
    (x0, y0), counts = grid_from_cells(cells, cell_m)
    return Coverage(x0=x0, y0=y0, cell_m=cell_m, poses=n, counts=counts.tolist())
