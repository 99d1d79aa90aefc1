"""`/commissioning/survey`: locate every landmark by driving a robot under the ceiling.

Reading the status needs a viewer key; starting, stopping and accepting (accepting writes
landmark positions into the map) an admin key, as map edits do. The survey runs on the
server (`live.survey.service.LiveSurvey`); docs/survey.md, docs/api.md.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter
from pydantic import BaseModel, ConfigDict, Field

from live.survey.service import SurveyStatus
from server.auth import Admin, Viewer
from server.deps import ServicesDep
from store.models import MAX_LANDMARK_ID

router = APIRouter(prefix="/commissioning/survey", tags=["commissioning"])


class SurveyStart(BaseModel):
    """Which robot drives the survey."""

    model_config = ConfigDict(extra="forbid")

    robot: str = Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.-]+$")


class SurveyAccept(BaseModel):
    """Which proposals to write into the map (absent: every one not flagged). Unknown keys
    are refused: a misspelt `landmarks` must not accept every proposal."""

    model_config = ConfigDict(extra="forbid")

    landmarks: list[Annotated[int, Field(ge=0, le=MAX_LANDMARK_ID)]] | None = Field(
        default=None, max_length=100_000, description="landmark IDs of the survey's result"
    )
    include_flagged: bool = Field(
        default=False, description="accept named landmarks the survey flagged, too"
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
    state: str = Field(description="anchor, converging, converged or flagged")
    ellipse_major_m: float = Field(description="horizontal 1-sigma ellipse: major semi-axis, m")
    ellipse_minor_m: float = Field(description="... minor semi-axis, m")
    ellipse_angle_rad: float = Field(description="... direction of the major axis, rad from +x")


class SurveyStatusPublic(BaseModel):
    """Where the survey is."""

    state: str = Field(
        description=(
            "idle, driving, solving, done, failed or interrupted (the server restarted "
            "during the drive: the live estimate is kept; start goes on from it)"
        )
    )
    robot: str | None = None
    recording: str | None = Field(default=None, description="the drive's recording folder")
    started_s: float | None = Field(default=None, description="seconds since the drive began")
    blinks: int = Field(description="dark windows requested so far")
    message: str
    proposals: list[ProposalPublic]
    accepted: list[int] = Field(description="landmarks whose proposal was written into the map")
    unseen: list[int] = Field(description="landmarks of the map the estimate cannot place (yet)")
    drive_s: float = Field(description="robot time the estimate covers, seconds")
    estimates: int = Field(description="live estimates made during the drive")
    converged_sigma_m: float = Field(
        description="a landmark at or under this 1-sigma uncertainty counts as converged, m"
    )
    route: list[tuple[float, float]] = Field(
        description="suggested waypoints (x, y) metres over what is still uncertain, in order"
    )
    no_radio: list[int] = Field(
        default_factory=list,
        description="landmarks left out: the radio cannot switch them (no radio address), "
        "so they cannot blink and nothing names them",
    )


def _public(st: SurveyStatus) -> SurveyStatusPublic:
    return SurveyStatusPublic(
        state=st.state,
        robot=st.robot,
        recording=st.recording,
        started_s=st.started_s,
        blinks=st.blinks,
        message=st.message,
        proposals=[
            ProposalPublic(
                landmark_id=p.landmark_id,
                x=p.x,
                y=p.y,
                z=p.z,
                sigma_m=p.sigma_m,
                moved_m=p.moved_m,
                views=p.views,
                rms_px=p.rms_px,
                anchor=p.anchor,
                flags=list(p.flags),
                state=p.state,
                ellipse_major_m=p.ellipse[0],
                ellipse_minor_m=p.ellipse[1],
                ellipse_angle_rad=p.ellipse[2],
            )
            for p in st.proposals
        ],
        accepted=list(st.accepted),
        unseen=list(st.unseen),
        drive_s=st.drive_s,
        estimates=st.estimates,
        route=list(st.route),
        converged_sigma_m=st.converged_sigma_m,
        no_radio=list(st.no_radio),
    )


@router.get("")
def get_survey(services: ServicesDep, _: Viewer) -> SurveyStatusPublic:
    """The survey's state; while driving the live estimate (every landmark's position,
    1-sigma ellipse and state) and the suggested route; once solved, the proposals."""
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


@router.post("/cancel")
def cancel_survey(services: ServicesDep, who: Admin) -> SurveyStatusPublic:
    """Drop the survey: blinking and recording stop, nothing is solved or written (the
    recording folder stays)."""
    return _public(services.survey.cancel(actor=who.actor))


@router.post("/accept")
def accept_survey(body: SurveyAccept, services: ServicesDep, who: Admin) -> SurveyStatusPublic:
    """Write proposals into the map, each landmark as its own audited, undoable edit: the
    final result, or while driving the latest live estimate (landmark by landmark as they
    converge). Absent `landmarks`: every unflagged one. 409 without an estimate or while
    solving; 422 naming landmarks not placed, anchors, locked, given twice, or flagged
    (without `include_flagged`): then nothing is written."""
    return _public(
        services.survey.accept(
            body.landmarks, actor=who.actor, include_flagged=body.include_flagged
        )
    )
