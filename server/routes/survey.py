"""`/commissioning/survey`: locate every landmark by driving a robot under the ceiling.

Reading the status needs a viewer key; starting, stopping and accepting (accepting writes
landmark positions into the map) an admin key, as map edits do. The survey runs on the
server (`server.survey_service.LiveSurvey`); docs/survey.md, docs/api.md.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter
from pydantic import BaseModel, Field

from server.auth import Admin, Viewer
from server.deps import ServicesDep
from server.models import MAX_LANDMARK_ID
from server.survey_service import SurveyStatus

router = APIRouter(prefix="/commissioning/survey", tags=["commissioning"])


class SurveyStart(BaseModel):
    """Which robot drives the survey."""

    robot: str = Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.-]+$")


class SurveyAccept(BaseModel):
    """Which proposals to write into the map (absent: every one not flagged)."""

    landmarks: list[Annotated[int, Field(ge=0, le=MAX_LANDMARK_ID)]] | None = Field(
        default=None, max_length=100_000, description="landmark IDs of the survey's result"
    )


class ProposalPublic(BaseModel):
    """One landmark as the survey placed it."""

    landmark_id: int
    x: float = Field(description="metres, world frame")
    y: float = Field(description="metres, world frame")
    z: float = Field(description="LED height above the floor, metres")
    sigma_m: float = Field(
        description="1-sigma uncertainty (largest semi-axis), metres; 0 for anchors"
    )
    moved_m: float = Field(description="distance from the map's position, metres")
    views: int = Field(description="independent views of it during the drive")
    rms_px: float = Field(description="reprojection residual RMS, pixels")
    anchor: bool = Field(description="a locked landmark, held at its position")
    flags: list[str] = Field(description="what looks wrong, in words (empty: nothing)")


class SurveyStatusPublic(BaseModel):
    """Where the survey is."""

    state: str = Field(description="idle, driving, solving, done or failed")
    robot: str | None = None
    recording: str | None = Field(default=None, description="the drive's recording folder")
    started_s: float | None = Field(default=None, description="seconds since the drive began")
    blinks: int = Field(description="dark windows requested so far")
    message: str
    proposals: list[ProposalPublic]
    accepted: list[int] = Field(description="landmarks whose proposal was written into the map")
    unseen: list[int] = Field(description="landmarks of the map the drive never identified")


def _public(st: SurveyStatus) -> SurveyStatusPublic:
    return SurveyStatusPublic(
        state=st.state, robot=st.robot, recording=st.recording, started_s=st.started_s,
        blinks=st.blinks, message=st.message,
        proposals=[
            ProposalPublic(
                landmark_id=p.landmark_id, x=p.x, y=p.y, z=p.z, sigma_m=p.sigma_m,
                moved_m=p.moved_m, views=p.views, rms_px=p.rms_px, anchor=p.anchor,
                flags=list(p.flags),
            )
            for p in st.proposals
        ],
        accepted=list(st.accepted), unseen=list(st.unseen),
    )  # fmt: skip


@router.get("")
def get_survey(services: ServicesDep, _: Viewer) -> SurveyStatusPublic:
    """The survey's state and, once solved, its proposals."""
    return _public(services.survey.status())


@router.post("/start")
def start_survey(body: SurveyStart, services: ServicesDep, who: Admin) -> SurveyStatusPublic:
    """Record `robot` while the landmarks blink one at a time against the lit ceiling.

    409 while a survey drives or solves, or with fewer than two locked landmarks (the
    anchors); 503 without a radio; 404 for an unknown robot.
    """
    return _public(services.survey.start(body.robot, actor=who.actor))


@router.post("/stop")
def stop_survey(services: ServicesDep, who: Admin) -> SurveyStatusPublic:
    """End the drive and solve (the state goes solving, then done or failed). 409 when no
    survey drives."""
    return _public(services.survey.stop(actor=who.actor))


@router.post("/accept")
def accept_survey(body: SurveyAccept, services: ServicesDep, who: Admin) -> SurveyStatusPublic:
    """Write proposals into the map (audited, undoable). 409 without a result; 422 naming
    landmarks the survey did not place."""
    return _public(services.survey.accept(body.landmarks, actor=who.actor))
