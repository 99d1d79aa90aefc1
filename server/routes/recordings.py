"""`/recordings`: the robots' recordings listed, downloaded as a zip, deleted.

Starting and stopping stay with the robot (`POST /robots/{name}/recording/start|stop`,
which name the recording they made). Listing is the viewer role's, downloading the
operator's (a recording holds the site's camera images), deleting the admin's with
`confirm=true`.
"""

from __future__ import annotations

from datetime import datetime
from pathlib import Path
from typing import Annotated

from fastapi import APIRouter, BackgroundTasks, Query, status
from fastapi import Path as PathParam
from fastapi.responses import FileResponse
from pydantic import BaseModel, Field

from server.auth import Admin, Operator, Viewer
from server.deps import ServicesDep
from store.errors import ConflictError
from store.recording_catalog import RecordingInfo

router = APIRouter(prefix="/recordings", tags=["recordings"])
RecordingName = Annotated[
    str,
    PathParam(
        min_length=1,
        max_length=128,
        pattern=r"^[A-Za-z0-9_.-]+$",
        description="the recording's name, as listed",
    ),
]


class RecordingPublic(BaseModel):
    """One recording (EuRoC-style folder, docs/recording.md)."""

    name: str = Field(description="the recording's ID (its folder's name)")
    robot: str
    started: datetime = Field(description="when it began, UTC")
    trigger: str = Field(
        description="why it was made: 'manual' (API or viewer), 'survey' (a live survey's "
        "drive), 'black_box_<trigger>' (a robot's black box saved on 'lost', 'kidnap', "
        "'quality' or 'operator', docs/quality.md); other kinds may be added"
    )
    live: bool = Field(description="a robot is still writing it (no download or delete yet)")
    size_bytes: int
    frames: int = Field(description="camera frames in it")


def _public(r: RecordingInfo) -> RecordingPublic:
    return RecordingPublic(
        name=r.name,
        robot=r.robot,
        started=r.started,
        trigger=r.trigger,
        live=r.live,
        size_bytes=r.size_bytes,
        frames=r.frames,
    )


@router.get("")
def list_recordings(
    services: ServicesDep,
    _: Viewer,
    robot: str | None = Query(None, max_length=64, description="only this robot's"),
    trigger: str | None = Query(None, max_length=32, description="only those made so"),
    limit: int = Query(100, ge=1, le=1000),
    offset: int = Query(0, ge=0, description="skip this many (newest first)"),
) -> list[RecordingPublic]:
    """The recordings, newest first."""
    found = services.recordings.catalog.list(robot)
    if trigger is not None:
        found = [r for r in found if r.trigger == trigger]
    return [_public(r) for r in found[offset : offset + limit]]


@router.get("/{name}")
def get_recording(name: RecordingName, services: ServicesDep, _: Viewer) -> RecordingPublic:
    """One recording; 404 naming the ones there are."""
    return _public(services.recordings.catalog.get(name))


@router.get(
    "/{name}/download",
    response_class=FileResponse,
    responses={200: {"content": {"application/zip": {}}, "description": "the folder, zipped"}},
)
def download_recording(
    name: RecordingName, services: ServicesDep, background: BackgroundTasks, _: Operator
) -> FileResponse:
    """The recording's folder as a zip (409 while it is being written)."""
    tmp = services.recordings.catalog.zip_file(name)
    background.add_task(Path.unlink, tmp, missing_ok=True)
    return FileResponse(tmp, media_type="application/zip", filename=f"{name}.zip")


@router.delete("/{name}", status_code=status.HTTP_204_NO_CONTENT)
def delete_recording(
    name: RecordingName,
    services: ServicesDep,
    _: Admin,
    confirm: bool = Query(False, description="required: the files are gone for good"),
) -> None:
    """Delete a recording for good (409 without `confirm=true`, or while being written)."""
    catalog = services.recordings.catalog
    info = catalog.get(name)
    if not confirm:
        raise ConflictError(
            f"deleting recording {name} ({info.size_bytes / 1e6:.1f} MB) cannot be undone: "
            "repeat with confirm=true"
        )
    catalog.delete(name)
